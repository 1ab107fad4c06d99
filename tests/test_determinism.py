"""Same scenario + seed => identical events and metrics, whatever the machine's load
(docs/ARCHITECTURE.md, "Modes"); and whether the logger keeps the 3D recording or not
(`hrc run --no-view`: the second run, which thus costs no trial of its own)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

import pytest

from .conftest import HRC, ROOT, strip_fields
from .goldens import normalised

pytestmark = [pytest.mark.e2e, pytest.mark.slow]

WALL = {"wall_time", "wall_s", "realtime_factor", "end_reason"}


def _strip(obj: Any) -> Any:
    return strip_fields(obj, WALL)


def _run(out: Path, ik_bin: Path, *options: str) -> tuple[list[dict], dict]:
    proc = subprocess.run(
        [
            HRC,
            "run",
            str(ROOT / "scenarios" / "thesis.toml"),
            "--out",
            str(out),
            "--seed",
            "7",
            "--max-ticks",
            "60000",
            *options,
        ],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr
    events = [json.loads(line) for line in (out / "events.jsonl").read_text().splitlines()]
    return _strip(events), _strip(json.loads((out / "metrics.json").read_text()))


def test_two_runs_of_the_thesis_trial_are_identical(tmp_path: Path, ik_bin: Path) -> None:
    e1, m1 = _run(tmp_path / "a", ik_bin)
    e2, m2 = _run(tmp_path / "b", ik_bin, "--no-view")
    assert (tmp_path / "a" / "recording.rrd").stat().st_size > 100_000
    assert not (tmp_path / "b" / "recording.rrd").exists()
    assert m1["task"]["completion_s"] is not None, "the task did not finish"
    assert m1["seed"] == 7
    assert len(e1) == len(e2)
    for i, (a, b) in enumerate(zip(e1, e2, strict=True)):
        assert a == b, f"event {i} differs"
    assert m1 == m2
    # log.txt in full but for the dated start line
    assert normalised(tmp_path / "a")["log.txt"] == normalised(tmp_path / "b")["log.txt"]
    # Without the view the logger takes no world state from the bus (a robot's state every tick
    # it moves: most of the session's messages), only what its files hold.
    seen = {
        run: json.loads((tmp_path / run / "logger_stats.json").read_text())["messages"]
        for run in ("a", "b")
    }
    ticks = m1["run"]["ticks"]
    assert seen["a"] > ticks and seen["b"] < ticks / 4, (seen, ticks)
