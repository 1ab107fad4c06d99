"""The golden trials and the outputs they must give.

Each golden trial is `scenarios/thesis.toml` with a few keys changed (`GOLDEN_TRIALS`); its
events.jsonl, log.txt and metrics.json are committed under `tests/golden/<name>/`. The golden
test runs each trial and compares; `scripts/update-golden.sh` rewrites them after a deliberate
change of behaviour or of an output's shape (the commit says which).

Only what legitimately differs between two runs of one trial is ignored: wall-clock times
(`wall_time`, `wall_s`, `realtime_factor`), the run's end reason (it names the wall time spent)
and the date line at the top of log.txt.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .warm_cli import hrc

ROOT = Path(__file__).resolve().parents[1]
GOLDEN_ROOT = Path(__file__).resolve().parent / "golden"
THESIS = ROOT / "scenarios" / "thesis.toml"
MINIMAL = ROOT / "scenarios" / "minimal.toml"  # the two-part board
WALL = {"wall_time", "wall_s", "realtime_factor", "end_reason"}
FILES = ("events.jsonl", "log.txt", "metrics.json")

# name -> (text in thesis.toml, replacement) pairs; the default trial, and one with collisions
GOLDEN_TRIALS: dict[str, list[tuple[str, str]]] = {
    "thesis": [],
    "thesis-collisions": [("provoke_collisions = false", "provoke_collisions = [3.0, 12.0]")],
}


def scenario_file(name: str, tmp: Path) -> Path:
    """The golden trial's scenario (written next to thesis.toml so relative paths resolve)."""
    text = THESIS.read_text()
    for old, new in GOLDEN_TRIALS[name]:
        assert old in text, f"{old!r} is no longer in scenarios/thesis.toml"
        text = text.replace(old, new)
    if not GOLDEN_TRIALS[name]:
        return THESIS
    path = tmp / f"golden-{name}.toml"
    path.write_text(text)
    return path


def with_robot_speed(scenario: Path, folder: Path, mps: float) -> Path:
    """``scenario`` (two robots at 0.5 m/s) with both robots at ``mps``, written into
    ``folder`` (its relative paths resolve from the project as from the scenario's folder)."""
    text = scenario.read_text()
    assert text.count("max_tcp_speed = 0.5") == 2, f"{scenario.name}: two robots at 0.5 m/s?"
    path = folder / f"{scenario.stem}-{mps:g}-mps.toml"
    path.write_text(text.replace("max_tcp_speed = 0.5", f"max_tcp_speed = {mps}"))
    return path


def strip_wall(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: strip_wall(v) for k, v in obj.items() if k not in WALL}
    if isinstance(obj, list):
        return [strip_wall(v) for v in obj]
    return obj


@dataclass
class Finished:
    """A trial `hrc run` has run: its folder, exit code and output, and its files as read."""

    folder: Path
    returncode: int
    stdout: str
    stderr: str

    @property
    def metrics(self) -> dict[str, Any]:
        return dict(json.loads((self.folder / "metrics.json").read_text()))

    @property
    def events(self) -> list[dict[str, Any]]:
        lines = (self.folder / "events.jsonl").read_text().splitlines()
        return [json.loads(line) for line in lines]

    @property
    def log_lines(self) -> list[str]:
        return (self.folder / "log.txt").read_text().splitlines()


def run_trial(
    scenario: Path, out: Path, *extra: str, max_ticks: int = 60000, timeout: float = 900
) -> Finished:
    """`hrc run SCENARIO --out OUT --max-ticks N EXTRA...` to its end (the tests' one way to run a
    whole trial from the command line; the cap only ends a trial that would never finish),
    forked from the test process's warm worker (tests/warm_cli.py)."""
    proc = hrc("run", str(scenario), "--out", str(out), "--max-ticks", str(max_ticks), *extra,
               timeout=timeout)  # fmt: skip
    return Finished(out, proc.returncode, proc.stdout, proc.stderr)


def normalised(folder: Path) -> dict[str, Any]:
    """A trial folder's three outputs with the wall-clock parts removed."""
    events = [
        strip_wall(json.loads(line)) for line in (folder / "events.jsonl").read_text().splitlines()
    ]
    log_lines = [  # all but the start line: its date
        line
        for line in (folder / "log.txt").read_text().splitlines()
        if not line.endswith(" - TASK STARTED.")
    ]
    metrics = strip_wall(json.loads((folder / "metrics.json").read_text()))
    return {"events.jsonl": events, "log.txt": log_lines, "metrics.json": metrics}
