"""Event-aligned exchanges keep the timing of one-tick exchanges (docs/ARCHITECTURE.md,
"Exchange step"), with the five real services.

The thesis trial with two provoked collisions (the golden `thesis-collisions`: a cautious
participant who holds back for robots, reaches into one twice, and is hit) runs twice: with the
default exchanges (up to `max_exchange_ticks` ticks, ended at every event a participant
declares, started at every look it declares, and at every gap the speed bounds could close) and
with `max_exchange_ticks = 1`. Every event happens at the same tick and the metrics and the log
are the same, but for the participant's idle time: a hand crossing the workspace's edge inside
an exchange is seen at its end (documented there).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from hrc.bus.clock import exchange_counts

from .goldens import GOLDEN_TRIALS, THESIS, normalised, run_trial

pytestmark = [pytest.mark.e2e, pytest.mark.slow]


def _scenario(tmp: Path, max_ticks: int | None) -> Path:
    text = THESIS.read_text()
    assert "caution = 0.5" in text and "seed = 1\n" in text
    for old, new in GOLDEN_TRIALS["thesis-collisions"]:
        text = text.replace(old, new)
    if max_ticks is not None:
        text = text.replace("seed = 1\n", f"seed = 1\nmax_exchange_ticks = {max_ticks}\n", 1)
    # in the test's folder: its relative paths (robots/arm5.urdf) resolve against the project
    # root there. (A copy beside thesis.toml was seen by another pytest process collecting
    # scenarios/*.toml, and gone when that test ran.)
    path = tmp / f"thesis-collisions-{max_ticks}.toml"
    path.write_text(text)
    return path


def _flat(obj: Any, prefix: str = "") -> dict[str, Any]:
    if isinstance(obj, dict):
        return {k: v for key, val in obj.items() for k, v in _flat(val, f"{prefix}.{key}").items()}
    if isinstance(obj, list):
        return {k: v for i, val in enumerate(obj) for k, v in _flat(val, f"{prefix}[{i}]").items()}
    return {prefix: obj}


def _trial(tmp: Path, max_ticks: int | None) -> tuple[dict[str, Any], int, int]:
    scenario = _scenario(tmp, max_ticks)
    out = tmp / f"span{max_ticks}"
    proc = run_trial(scenario, out, "--no-view")  # the events are compared, not views
    assert proc.returncode == 0, proc.stderr[-3000:]
    counts = exchange_counts((out / "services" / "physics.log").read_text())
    assert counts, "physics logs its exchanges at the end"
    return normalised(out), *counts


IDLE = ("HUMAN_IDLE_BEGIN", "HUMAN_IDLE_END", "HUMAN_FINISHED")  # they say the idle time


def _without_idle(events: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The events but those of the idle time, and the metrics they carry without it."""
    out = []
    for e in events:
        if e.get("kind") in IDLE:
            continue
        if e.get("type") == "metrics":
            e = {**e, "human": {k: v for k, v in e["human"].items() if k != "idle_s"}}
        out.append(e)
    return out


def test_event_aligned_exchanges_give_the_events_of_one_tick_exchanges(tmp_path: Path) -> None:
    aligned, ticks, exchanges = _trial(tmp_path, None)
    single, ticks_1, exchanges_1 = _trial(tmp_path, 1)
    assert ticks == ticks_1 == exchanges_1
    assert exchanges < ticks / 5, f"{exchanges} exchanges for {ticks} ticks: hardly any saved"
    got, want = (_without_idle(out["events.jsonl"]) for out in (aligned, single))
    collisions = [e for e in want if e.get("kind") == "COLLISION"]
    assert len(collisions) >= 2, "the trial is to show the participant hit (and cautious after)"
    for i, (a, b) in enumerate(zip(got, want, strict=False)):
        assert a == b, f"event {i + 1}: {json.dumps(a)} != {json.dumps(b)} (one-tick exchanges)"
    assert len(got) == len(want)
    m_got, m_want = _flat(aligned["metrics.json"]), _flat(single["metrics.json"])
    differ = sorted(k for k in m_got.keys() | m_want.keys() if m_got.get(k) != m_want.get(k))
    assert differ in ([], [".human.idle_s"]), f"metrics differ: {differ}"
    log_got, log_want = (
        [line for line in out["log.txt"] if "idle" not in line.lower()] for out in (aligned, single)
    )
    assert log_got == log_want
