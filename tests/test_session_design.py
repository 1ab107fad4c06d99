"""A 2x2 mixed design run by `hrc session` for a roster of four people: robot speed between
subjects, anticipation within. Each person's page is played by a WebSocket client on the
session's real endpoint, and each trial by a Python participant on the trial's real bridge
(H1 taken and placed): the sessions, the table and the report show the design as dealt."""

from __future__ import annotations

import json
import re
import subprocess
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pandas as pd
import pytest
from websockets.sync.client import connect

from .conftest import HRC, ROOT
from .session_page import Session, page_link, place_by_socket, screen, write_study

pytestmark = [pytest.mark.slow, pytest.mark.e2e]

SPEED = "robots.*.max_tcp_speed"
ANTICIPATION = "conditions.anticipation"
ROSTER = ["L01", "L02", "L03", "L04"]
LIVE = f"""[live]
participants = {json.dumps(ROSTER)}
consent = "consent.md"
instructions = "instructions.md"
between = ["{SPEED}"]
"""


@pytest.fixture
def sessions() -> Iterator[list[Session]]:
    started: list[Session] = []
    yield started
    for s in started:
        s.stop()


def one_person(study: Path, pid: str, out: Path, sessions: list[Session]) -> list[str]:
    """`hrc session` for `pid`, its screens answered and its trials played; returns the titles
    of the screens in the order shown. L01 stops in its first trial with H1 in the hand until
    the console says so."""
    s = Session(study, pid, out)
    sessions.append(s)
    ws_url, key = page_link(s)
    seen: list[str] = []
    stuck = (
        (lambda: s.said(r"\[task +[\d.]+ s\] waiting for the participant: H1", 90))
        if (pid == "L01")
        else None
    )
    with connect(ws_url, open_timeout=10) as ws:
        while True:
            sc = screen(ws)
            seen.append(f"{sc['kind']}:{sc.get('title', '')}")
            if sc["kind"] == "consent":
                ws.send(json.dumps({"type": "consent", "accepted": True, "screen": sc["id"]}))
            elif sc["kind"] == "text":
                ws.send(json.dumps({"type": "continue", "screen": sc["id"]}))
            elif sc["kind"] == "ready":
                ws.send(json.dumps({"type": "start", "screen": sc["id"]}))
            elif sc["kind"] == "trial":
                place_by_socket(sc["port"], key, holding=stuck)
                stuck = None
            elif sc["kind"] == "done":
                break
            else:
                assert sc["kind"] == "starting", (pid, sc)
    assert s.wait(60) == 0, s.console()
    return seen


@pytest.mark.timeout(900)
def test_a_mixed_design_for_four_people_is_balanced_in_the_table_and_report(
    sessions: list[Session], tmp_path: Path
) -> None:
    study = write_study(
        tmp_path / "study",
        LIVE,
        simulated=0,
        factors=f'"{ANTICIPATION}" = [true, false]\n"{SPEED}" = [0.5, 0.7]',
    )
    out = tmp_path / "out"
    # two people at a time, as two rooms of a lab would (each session on its own ports)
    with ThreadPoolExecutor(2) as pool:
        done = pool.map(lambda p: one_person(study, p, out, sessions), ROSTER)
        shown = dict(zip(ROSTER, done, strict=True))
    for pid, screens in shown.items():
        assert sum(s.startswith("trial:") for s in screens) == 2, (pid, screens)
    # the experimenter saw the stuck participant on the session's console within 15 s of the
    # last thing that happened in the task (H1 grabbed, RA1 placed by r1)
    l01 = next(s for s in sessions if "L01" in s.argv)
    told = [
        (float(m.group(1)), m.group(2))
        for ln in l01.lines
        if (m := re.search(r"\[task +([\d.]+) s\] (.*)", ln))
    ]
    at = next(t for t, what in told if what.startswith("waiting for the participant: H1"))
    before = max(t for t, what in told if t < at)
    assert at - before <= 15, l01.console()

    table = pd.read_csv(out / "trials.csv")
    live = table[table["participant_kind"] == "live"]
    assert sorted(live["participant"].unique()) == ROSTER, live
    assert (live["outcome"] == "ok").all() and live["task.finished"].all(), live
    speed = {p: sorted(g[SPEED].unique()) for p, g in live.groupby("participant")}
    # between: one speed each, dealt over the roster in turn (L01, L03 | L02, L04)
    assert speed == {"L01": [0.5], "L02": [0.7], "L03": [0.5], "L04": [0.7]}, speed
    for p, g in live.groupby("participant"):  # within: both anticipation levels each
        assert sorted(g[ANTICIPATION]) == [False, True], (p, g)
    # the two of a group in opposite orders (counterbalanced within the group)
    first = {
        p: bool(g.sort_values("order_position")[ANTICIPATION].iloc[0])
        for p, g in live.groupby("participant")
    }
    assert first["L01"] != first["L03"] and first["L02"] != first["L04"], first
    meta = json.loads((out / "study.json").read_text())
    assert meta["between"] == [SPEED], meta

    rep = subprocess.run(
        [HRC, "report", str(out)], capture_output=True, text=True, timeout=300, cwd=ROOT
    )
    assert rep.returncode == 0, rep.stderr[-3000:]
    report = (out / "report.html").read_text()
    assert f"<td>{SPEED}</td><td>0.5, 0.7</td><td>between (one level each)</td>" in report
    assert f"<td>{ANTICIPATION}</td><td>True, False</td><td>within (every level)</td>" in report
