"""`hrc session` without a browser: its page link, its console commands, a declined consent,
one session per participant, bad input. The page is played by a plain WebSocket client on the
session's real endpoint (the browser tests in test_session.py do the whole session)."""

from __future__ import annotations

import json
import os
import re
import signal
import socket
import subprocess
import urllib.error
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pandas as pd
import pytest
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from .conftest import HRC, ROOT, _children, _cmdline, gone, wait_until
from .session_page import Session, page_link, screen, write_study

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
    # a page whose link dropped asks whether its key still opens the session, to say so
    with urllib.request.urlopen(f"{base}/session?driver={key}", timeout=10) as r:
        assert r.status == 204
    with pytest.raises(urllib.error.HTTPError) as wrong:
        urllib.request.urlopen(f"{base}/session?driver=not-the-key", timeout=10)
    assert wrong.value.code == 403

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
        # the page is told, in words (it was left on its screen)
        assert "experimenter has ended the session for now" in screen(ws, "paused")["text"]
        assert s.wait(60) == 0, s.console()
    assert "resume with the same command" in s.console()
    assert json.loads((out / "sessions" / "L02" / "session.json").read_text())["status"] == "ended"

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


def test_a_session_killed_mid_trial_goes_on_with_the_same_link_and_names_the_cut_attempt(
    sessions: list[Session], tmp_path: Path
) -> None:
    """kill -9 of `hrc session` during a trial, then the same command: the trial the kill cut
    short ends; the participant's link (its key) is the same, so the page that was open redials
    and gets the trial's screen again; the attempt the kill cut short is recorded as failed,
    with why. The same command while the session's port is taken says so, and leaves
    session.json as stopped, not running."""
    study = write_study(tmp_path / "study", LIVE, simulated=0)
    out = tmp_path / "out"
    path = out / "sessions" / "L01" / "session.json"
    s = Session(study, "L01", out)
    sessions.append(s)
    ws_url, key = page_link(s)
    with connect(ws_url, open_timeout=10) as ws:
        consent = screen(ws, "consent")
        ws.send(json.dumps({"type": "consent", "accepted": True, "screen": consent["id"]}))
        text = screen(ws, "text")
        ws.send(json.dumps({"type": "continue", "screen": text["id"]}))
        ready = screen(ws, "ready")
        ws.send(json.dumps({"type": "start", "screen": ready["id"]}))
        screen(ws, "starting")  # the trial runs (nobody drives it)
        running = json.loads(path.read_text())
        assert running["trials"][0]["attempts"][0]["outcome"] == "", running["trials"][0]
        trial = [p for p in _children(s.proc.pid) if " run " in _cmdline(p)]
        assert len(trial) == 1, [_cmdline(p) for p in _children(s.proc.pid)]
        os.kill(s.proc.pid, signal.SIGKILL)
        assert s.wait(30) == -signal.SIGKILL
    # The trial the kill cut short ends too (it waited for a page that redials the next session
    # process, holding the trial port that one needs), its services with it.
    assert wait_until(lambda: gone(trial[0]), 60, 0.2), _cmdline(trial[0])

    with socket.socket() as busy:  # the same command, its port taken: refused, in words
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        taken = [*s.argv[:-4], "--port", str(busy.getsockname()[1]), *s.argv[-2:]]
        refused = subprocess.run(taken, capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert refused.returncode == 2 and "cannot serve the session page" in refused.stderr, refused
    assert json.loads(path.read_text())["status"] == "stopped"

    again = Session(study, "L01", out, port=s.port)
    sessions.append(again)
    assert page_link(again) == (ws_url, key)  # the same link
    with connect(ws_url, open_timeout=10) as ws:  # the page that was open, redialling
        assert screen(ws, "ready")["title"] == ready["title"]
    state = json.loads(path.read_text())
    cut = state["trials"][0]["attempts"][0]
    assert cut["outcome"] == "failed" and "session process ended during this trial" in cut["reason"]
    assert state["status"] == "running" and state["trials"][0]["status"] == "pending"
    assert "the last session process ended without a word (killed or crashed)" in [
        e["what"] for e in state["log"]
    ]


def test_a_skipped_trial_is_not_counted_as_done(sessions: list[Session], tmp_path: Path) -> None:
    """The page's "trials done" and the console's status count what the participant did: a
    trial the experimenter skipped is shown as skipped (it was counted as done)."""
    study = write_study(tmp_path / "study", LIVE, simulated=0)
    s = Session(study, "L01", tmp_path / "out")
    sessions.append(s)
    ws_url, _ = page_link(s)
    with connect(ws_url, open_timeout=10) as ws:
        consent = screen(ws, "consent")
        ws.send(json.dumps({"type": "consent", "accepted": True, "screen": consent["id"]}))
        text = screen(ws, "text")
        ws.send(json.dumps({"type": "continue", "screen": text["id"]}))
        first = screen(ws, "ready")
        assert first["progress"] == {"done": 0, "skipped": 0, "total": 2}, first
        s.command("s")  # skip the next trial
        second = screen(ws, "ready")
        assert second["title"] != first["title"]
        assert second["progress"] == {"done": 0, "skipped": 1, "total": 2}, second
        s.command("?")
        s.said(r"L01: 0/2 trials done \(1 skipped\)", 30)


def test_the_console_shows_what_the_trial_waits_for(
    sessions: list[Session], tmp_path: Path
) -> None:
    """While a trial runs the experimenter sees its state on the session's console (it said only
    `running 7:31, page connected`): the trial's task events as they come and its status line,
    which `?` shows too. Here nobody drives the trial: it waits for the first grab."""
    study = write_study(tmp_path / "study", LIVE, simulated=0)
    out = tmp_path / "out"
    s = Session(study, "L01", out)
    sessions.append(s)
    ws_url, _ = page_link(s)
    with connect(ws_url, open_timeout=10) as ws:
        consent = screen(ws, "consent")
        ws.send(json.dumps({"type": "consent", "accepted": True, "screen": consent["id"]}))
        text = screen(ws, "text")
        ws.send(json.dumps({"type": "continue", "screen": text["id"]}))
        ready = screen(ws, "ready")
        s.command("n came ten minutes late")  # before any trial: a note on the session
        s.said(r"note on the session: came ten minutes late", 30)
        ws.send(json.dumps({"type": "start", "screen": ready["id"]}))
        screen(ws, "trial")  # its bridge serves: the trial runs
        s.command("n the participant sneezed")  # notes and a flag on the trial in progress
        s.command("f")
        s.command("n")  # (an empty note: says how)
        s.said(r"flagged on \S+$", 30)
        s.said(r"n TEXT: type the note after the n", 30)
        # `?` until the trial's console has said its first status line (a loaded machine may
        # take seconds: the experimenter asks again)
        status = re.compile(
            r"L01: 0/2 trials done, page connected; trial: L01: no driver, 0 spectator\(s\) "
            r"\| waiting for the first grab \| task 0.0 s \| placed 0/3"
        )

        def told() -> bool:
            s.command("?")
            return wait_until(lambda: any(status.search(ln) for ln in s.lines), 2, 0.2)

        assert wait_until(told, 60, 0.1), s.console()
        s.command("s")  # skipped: stopped, its end on the console
        s.said(r"trial \S+: skipped", 60)
        s.command("?")
        s.said(r"L01: 0/2 trials done \(1 skipped\), page connected$", 30)
    state = json.loads((out / "sessions" / "L01" / "session.json").read_text())
    assert [n["text"] for n in state["notes"]] == ["came ten minutes late"], state["notes"]
    first = state["trials"][0]
    assert [(n["text"], n.get("flag", False)) for n in first["notes"]] == [
        ("the participant sneezed", False),
        ("", True),
    ], first
    rows = pd.read_csv(out / "trials.csv").set_index("trial")
    assert rows.loc[first["id"], "notes"] == "the participant sneezed", rows
    assert bool(rows.loc[first["id"], "flagged"]) is True


def test_questionnaires_before_the_session_and_before_a_trial(
    sessions: list[Session], tmp_path: Path
) -> None:
    """before_session: after the consent, once (demographics, a baseline SSQ); before_trial:
    before each analysed trial's ready screen. Every answer kept in session.json."""
    live = LIVE + (
        'before_session = ["demographics"]\nbefore_trial = ["ready"]\n'
        '[questionnaires.ready]\npoints = 5\nitems = [{ id = "rested", text = "I feel rested." }]\n'
    )
    study = write_study(tmp_path / "study", live, simulated=0)
    out = tmp_path / "out"
    s = Session(study, "L01", out)
    sessions.append(s)
    ws_url, _ = page_link(s)
    with connect(ws_url, open_timeout=10) as ws:
        consent = screen(ws, "consent")
        ws.send(json.dumps({"type": "consent", "accepted": True, "screen": consent["id"]}))
        about = screen(ws, "questionnaire")
        assert about["questionnaire"]["title"] == "About you", about
        answers = {"handedness": "left", "age": "25-34"}
        ws.send(json.dumps({"type": "answers", "answers": answers, "screen": about["id"]}))
        text = screen(ws, "text")  # then the instructions
        ws.send(json.dumps({"type": "continue", "screen": text["id"]}))
        ready_q = screen(ws, "questionnaire")
        assert ready_q["questionnaire"]["id"] == "ready", ready_q
        ws.send(json.dumps({"type": "answers", "answers": {"rested": 4}, "screen": ready_q["id"]}))
        screen(ws, "ready")
    state = json.loads((out / "sessions" / "L01" / "session.json").read_text())
    assert state["start_answers"] == {"demographics": answers}
    assert state["trials"][0]["answers"] == {"ready": {"rested": 4}}
    assert state["trials"][0]["scores"] == {"ready": {"mean": 4.0}}
