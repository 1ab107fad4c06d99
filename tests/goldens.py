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
import subprocess
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
GOLDEN_ROOT = Path(__file__).resolve().parent / "golden"
THESIS = ROOT / "scenarios" / "thesis.toml"
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


def strip_wall(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: strip_wall(v) for k, v in obj.items() if k not in WALL}
    if isinstance(obj, list):
        return [strip_wall(v) for v in obj]
    return obj


def run_trial(hrc: str, scenario: Path, out: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([hrc, "run", str(scenario), "--out", str(out), "--max-ticks", "60000"],
                          capture_output=True, text=True, timeout=900)


def normalised(folder: Path) -> dict[str, Any]:
    """A trial folder's three outputs with the wall-clock parts removed."""
    events = [json.loads(line) for line in (folder / "events.jsonl").read_text().splitlines()]
    log_lines = (folder / "log.txt").read_text().splitlines()[1:]  # line 0: the date
    metrics = json.loads((folder / "metrics.json").read_text())
    if any("numbers" in r for r in events):  # written before the typed contract (hrc.v2)
        events = [_v2_record(r, metrics) for r in events]
    return {"events.jsonl": [strip_wall(r) for r in events], "log.txt": log_lines,
            "metrics.json": strip_wall(metrics)}


# ---------------------------------------------------------------- the hrc.v2 renames
# events.jsonl of hrc.v1 carried an event's figures in "value" and "numbers" (an untyped map);
# hrc.v2 carries them in a typed "payload" named after the kind. Its metrics records now have
# every field of metrics.json (task.started/finished, run.ok/end_reason/deadline_misses) and
# `run: null` before the run has ended (v1 wrote zeros there).

_NUMBER_IN_VALUE = {"COLLISION_END", "RETREAT_REACHED", "NEAR_COLLISION_END"}
_VALUE_IS_TASK_TIME = {"ROBOT_FINISHED", "HUMAN_FINISHED", "TASK_FINISHED"}


def _v1_payload(kind: str, value: float, numbers: dict[str, float]) -> dict[str, Any]:
    n = dict(numbers)
    payload = _take(kind, value, n)
    assert not n, f"{kind}: {n} not in the payload"
    return payload


def _take(kind: str, value: float, n: dict[str, float]) -> dict[str, Any]:
    if kind == "PART_RELEASED":
        assert value == n["distance_m"]
        return {"distance_m": n.pop("distance_m"), "angle_deg": n.pop("angle_deg")}
    if kind == "ROBOT_WAIT_OVER":
        return {"waited_s": value}
    if kind == "ROBOT_FINISHED":
        return {k: n.pop(k) for k in ("max_tcp_speed_mps", "avg_tcp_speed_mps", "idle_s")}
    if kind == "HUMAN_FINISHED":
        return {"idle_s": n.pop("idle_s")}
    if kind == "TASK_FINISHED":
        return {k: int(n.pop(k)) for k in ("human_robot_collisions", "near_collisions")}
    if kind == "COLLISION":
        assert value == n["collision"]
        return {"number": int(n.pop("collision"))}
    if kind in _NUMBER_IN_VALUE:
        return {"number": int(value)}
    if kind == "CONTINUED":
        assert value == n["delay_s"]
        return {"number": int(n.pop("collision")), "delay_s": n.pop("delay_s")}
    if kind == "NEAR_COLLISION":
        assert value == n["near_collision"]
        number = int(n.pop("near_collision"))
        (a, d_a), (b, d_b) = sorted(n.items())
        n.clear()
        return {"number": number, "robot_a": a.removeprefix("distance_").removesuffix("_m"),
                "distance_a_m": d_a, "robot_b": b.removeprefix("distance_").removesuffix("_m"),
                "distance_b_m": d_b}
    assert value == 0.0, kind
    return {}


def _v2_record(rec: dict[str, Any], metrics: dict[str, Any]) -> dict[str, Any]:
    rec = dict(rec)
    if rec["type"] == "event":
        value, numbers = rec.pop("value"), rec.pop("numbers")
        payload = _v1_payload(rec["kind"], value, numbers)
        if rec["kind"] in _VALUE_IS_TASK_TIME:
            assert value == rec["task_time"]
        rec["payload"] = payload
    elif rec["type"] == "metrics":
        rec["task"] = {"started": metrics["task"]["started"],
                       "finished": metrics["task"]["finished"], **rec["task"]}
        if rec["run"] == {"mode": "", "ticks": 0, "wall_s": 0.0, "realtime_factor": 0.0}:
            rec["run"] = None
        else:
            rec["run"] = {**rec["run"], "ok": metrics["run"]["ok"],
                          "end_reason": metrics["run"]["end_reason"],
                          "deadline_misses": metrics["run"]["deadline_misses"]}
    return rec
