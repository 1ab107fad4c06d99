"""A live participant's session on disk: `<study out>/sessions/<participant>/session.json`.

Rewritten atomically after every change (a consent, an answer, a trial's end), so a crash of
anything loses at most the step in progress and the same `hrc session` command resumes from it.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

FORMAT = "hrc-session"
VERSION = 1
DONE = ("ok", "stalled", "skipped")  # a trial in one of these is not run again


def now_iso() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())


@dataclass
class Attempt:
    started: str
    outcome: str = ""  # ok | stalled | failed | skipped
    reason: str = ""
    exit_code: int | None = None
    wall_s: float = 0.0


@dataclass
class TrialState:
    id: str
    index: int
    practice: bool
    order_position: int
    condition: dict[str, Any]
    condition_index: int
    seed: int
    input_hash: str
    repetition: int = 1
    status: str = "pending"  # pending | ok | stalled | failed | skipped
    reason: str = ""
    attempts: list[Attempt] = field(default_factory=list)
    answers: dict[str, dict[str, Any]] = field(default_factory=dict)
    scores: dict[str, dict[str, Any]] = field(default_factory=dict)
    # the experimenter's notes and flags (`n TEXT`, `f [TEXT]`): {"at", "text"[, "flag": true]}
    notes: list[dict[str, Any]] = field(default_factory=list)

    @property
    def done(self) -> bool:
        return self.status in DONE

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> TrialState:
        d = dict(d)
        d["attempts"] = [Attempt(**a) for a in d.get("attempts", [])]
        return cls(**{k: d[k] for k in cls.__dataclass_fields__ if k in d})


@dataclass
class SessionState:
    study: str
    participant: str
    created: str
    order: list[int]
    trials: list[TrialState]
    consent: dict[str, Any] | None = None  # {"accepted": bool, "at": iso}
    seen: list[str] = field(
        default_factory=list
    )  # texts shown: "instructions", "instruction:<trial>"
    end_answers: dict[str, dict[str, Any]] = field(default_factory=dict)
    end_scores: dict[str, dict[str, Any]] = field(default_factory=dict)
    start_answers: dict[str, dict[str, Any]] = field(default_factory=dict)  # before_session
    start_scores: dict[str, dict[str, Any]] = field(default_factory=dict)
    # a questionnaire's answers as they are given, before it is sent whole
    # ("<trial id or end>:<questionnaire>" -> answers): a closed tab or a crash keeps them
    drafts: dict[str, dict[str, Any]] = field(default_factory=dict)
    # running (an `hrc session` serves it now) | done | ended (by the experimenter's `e`) |
    # stopped (the process stopped: Ctrl-C, a signal, an error, or it could not start) | declined
    status: str = "running"
    log: list[dict[str, Any]] = field(default_factory=list)
    # the participant's link key: the same link for the whole session, across restarts (the
    # file is private: hrc.privacy); "" in files written before it was kept
    key: str = ""
    # the experimenter's notes before any trial was run (as TrialState.notes)
    notes: list[dict[str, Any]] = field(default_factory=list)

    def trial(self, tid: str) -> TrialState:
        return next(t for t in self.trials if t.id == tid)

    def note(self, what: str, **extra: Any) -> None:
        self.log.append({"at": now_iso(), "what": what, **extra})

    def to_dict(self) -> dict[str, Any]:
        return {"format": FORMAT, "version": VERSION, **asdict(self)}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> SessionState:
        if d.get("format") != FORMAT or d.get("version") != VERSION:
            raise ValueError(f"not an {FORMAT} v{VERSION} file")
        d = {k: v for k, v in d.items() if k in cls.__dataclass_fields__}
        d["trials"] = [TrialState.from_dict(t) for t in d["trials"]]
        return cls(**d)


def session_dir(out: Path, participant: str) -> Path:
    return out / "sessions" / participant


def load(path: Path) -> SessionState | None:
    """The saved session, None if there is none; ValueError names a file that cannot be read."""
    if not path.exists():
        return None
    try:
        return SessionState.from_dict(json.loads(path.read_text(encoding="utf-8")))
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(
            f"{path}: cannot be read as a session ({exc}); nothing was changed"
        ) from exc


def save(state: SessionState, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(state.to_dict(), indent=1), encoding="utf-8")
    os.replace(tmp, path)


def all_sessions(out: Path) -> list[SessionState]:
    """Every readable session of a study folder (an unreadable one is skipped: the table is
    rebuilt from what can be read, the file stays for a person to look at)."""
    found: list[SessionState] = []
    for path in sorted((out / "sessions").glob("*/session.json")):
        try:
            s = load(path)
        except ValueError:
            continue
        if s is not None:
            found.append(s)
    return found
