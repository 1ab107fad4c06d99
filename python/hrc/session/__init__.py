"""Live participants' sessions (`hrc session`, docs/studies.md "Running a study with people"):
`state` (session.json), `web` (the page's server and its /session WebSocket), `run` (the
session's steps, its trials, the experimenter's console)."""
