"""`hrc session` without a browser: its page link, its console commands, a declined consent,
one session per participant, bad input. The page is played by a plain WebSocket client on the
session's real endpoint (the browser tests in test_session.py do the whole session)."""

from __future__ import annotations

import json
import subprocess
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

import pytest
from websockets.exceptions import InvalidStatus
from websockets.sync.client import ClientConnection, connect

from .conftest import HRC, ROOT
from .session_page import Session, write_study

pytestmark = pytest.mark.slow

LIVE = """[live]
participants = ["L01", "L02"]
consent = "consent.md"
instructions = "instructions.md"
"""


@pytest.fixture
def sessions() -> Iterator[list[Session]]:
    started: list[Session] = []
    yield started
    for s in started:
        s.stop()


def page_link(s: Session) -> tuple[str, str]:
    """(the session's WebSocket URL, the participant's key) from the printed link."""
    url = s.url()
    assert url
    parts = urlsplit(url)
    key = parse_qs(parts.query)["driver"][0]
    return f"ws://{parts.netloc}/session?driver={key}", key


def screen(ws: ClientConnection, kind: str) -> dict[str, Any]:
    while True:
        msg = json.loads(ws.recv(timeout=60))
        if msg.get("type") == "screen" and msg["kind"] == kind:
            return msg


def test_only_the_participants_page_takes_part_and_declining_consent_ends_it(
    sessions: list[Session], tmp_path: Path
) -> None:
    study = write_study(tmp_path / "study", LIVE, simulated=0)
    out = tmp_path / "out"
    s = Session(study, "L01", out)
    sessions.append(s)
    ws_url, key = page_link(s)
    base = ws_url.replace("ws://", "http://").split("/session")[0]
    with urllib.request.urlopen(base + "/", timeout=10) as r:  # the participant's page
        assert r.status == 200 and b"<canvas" in r.read()
    with pytest.raises(InvalidStatus) as refused:  # another page (a wrong key) is refused
        connect(ws_url.replace(key, "not-the-key"), open_timeout=10)
    assert refused.value.response.status_code == 403

    with connect(ws_url, open_timeout=10) as ws:
        consent = screen(ws, "consent")
        assert "working with robots" in consent["text"]
        ws.send(json.dumps({"type": "consent", "accepted": False, "screen": consent["id"]}))
        screen(ws, "ended")
    assert s.wait(60) == 0, s.console()
    assert "L01 declined consent" in s.console()
    state = json.loads((out / "sessions" / "L01" / "session.json").read_text())
    assert state["status"] == "declined" and state["consent"]["accepted"] is False

    again = subprocess.run(s.argv, capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert again.returncode == 2
    assert "L01 declined consent" in again.stderr and "does not run again" in again.stderr


def test_ctrl_c_ends_a_session_started_with_sigint_ignored(
    sessions: list[Session], tmp_path: Path
) -> None:
    """A script's background job, nohup or a CI runner starts a program with SIGINT ignored, and
    Python leaves it so: the experimenter's Ctrl-C was lost and `hrc session` went on waiting
    for the page (issue 41). It takes SIGINT as Ctrl-C whatever it inherited."""
    study = write_study(tmp_path / "study", LIVE, simulated=0)
    s = Session(study, "L01", tmp_path / "out", sigint_ignored=True)
    sessions.append(s)
    assert s.interrupt() == 130, s.console()
    s.said("session interrupted; resume with the same command", 10)


def test_one_session_per_participant_paused_and_ended_by_the_experimenter_then_resumed(
    sessions: list[Session], tmp_path: Path
) -> None:
    study = write_study(tmp_path / "study", LIVE, simulated=0)
    out = tmp_path / "out"
    s = Session(study, "L02", out)
    sessions.append(s)
    twice = subprocess.run(s.argv, capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert twice.returncode == 2 and "L02's session is already running" in twice.stderr

    ws_url, _ = page_link(s)
    with connect(ws_url, open_timeout=10) as ws:
        consent = screen(ws, "consent")
        ws.send(json.dumps({"type": "consent", "accepted": True, "screen": consent["id"]}))
        text = screen(ws, "text")  # the instructions
        s.command("p")  # paused: the page says so; again: the same screen comes back
        assert "paused" in screen(ws, "paused")["text"]
        s.command("p")
        assert screen(ws, "text")["id"] == text["id"]
        s.command("e")
        assert s.wait(60) == 0, s.console()
    assert "resume with the same command" in s.console()

    s2 = Session(study, "L02", out)  # the same command: consent is not asked again
    sessions.append(s2)
    ws_url, _ = page_link(s2)
    with connect(ws_url, open_timeout=10) as ws:
        first = json.loads(ws.recv(timeout=60))
        assert first["kind"] == "text" and first["title"] == "Instructions", first
    state = json.loads((out / "sessions" / "L02" / "session.json").read_text())
    assert state["consent"]["accepted"] is True
    assert [e["what"] for e in state["log"]][:3] == [
        "session created",
        "consent accepted",
        "session resumed",
    ]


def test_a_bad_study_or_participant_is_named_and_nothing_runs(tmp_path: Path) -> None:
    study = write_study(tmp_path / "study", LIVE.replace('"L02"]', '"L02"]\norder = "zigzag"'))
    out = tmp_path / "out"
    bad = subprocess.run(
        [HRC, "session", str(study), "--participant", "L01", "--out", str(out)],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert bad.returncode == 2
    assert "live.order: one of williams, latin, random, fixed (got 'zigzag')" in bad.stderr
    assert not out.exists()
    good = write_study(tmp_path / "study2", LIVE, simulated=0)
    who = subprocess.run(
        [HRC, "session", str(good), "--participant", "L09", "--out", str(out)],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert who.returncode == 2 and "not a live participant of the study (L01, L02" in who.stderr
    assert not out.exists()
