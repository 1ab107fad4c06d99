"""Speed and separation monitoring with every real service (docs/safety-ssm.md): a replayed
hand that approaches r1's path at 1 m/s on a straight line makes r1 stop before contact, and r1
resumes by itself once the hand has left; the thesis trial with ssm and provoked collisions
finishes, with protective stops and resumes in its events."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from hrc.bus.clock import exchange_counts
from hrc.paths import ik_binary, project_root
from hrc.trial import TrialOptions, run_trial

from .conftest import strip_fields

ROOT = project_root()
pytestmark = [
    pytest.mark.e2e,
    pytest.mark.slow,
    pytest.mark.skipif(not ik_binary().exists(), reason=f"{ik_binary()} is not built"),
]

# One transport arm, one part, nobody else: the task starts at once (empty human sequence) and
# r1 heads from home (0.35, 0.30, 0.35) for its pick, 5 cm above (0.66, 0.30, 0.06).
SCENARIO = """
[scenario]
name = "ssm-approach"
tick_hz = 240
seed = 1
stall_timeout_s = 30

[participant]
name = "P00"
input = "replay"
replay_file = "approach.jsonl"

[conditions]
safety_policy = "ssm"

[robots.r1]
role = "transport"
urdf = "robots/arm5.urdf"
base = { xyz = [0.45, 0.55, 0.0], yaw = 180 }
max_tcp_speed = 0.5
home = [0.35, 0.30, 0.35]
intermediate = [0.20, 0.25, 0.25]
retreat = [0.45, 0.45, 0.40]

[[parts]]
id = "RA1"
owner = "r1"
size = [0.04, 0.04, 0.06]
start = { xyz = [0.66, 0.30, 0.03], yaw = 0 }
target = { xyz = [0.04, 0.16, 0.03], yaw = 0 }

[sequence]
human = []
r1 = ["RA1"]

[workspace]
envelope = [{ min = [-0.35, -0.25, -0.05], max = [0.35, 0.25, 0.50] }]
"""

# A second transport arm, r1's mirror on the left, whose separation sensor scans every 0.05 s
# (12 ticks at 240 Hz) while r1's scans every 0.03 s (7 ticks): the two monitors' scans make no
# grid. The hand never comes nearer to r2 than 0.6 m, so r2 only slows down.
SECOND_ROBOT = """
[robots.r2]
role = "transport"
urdf = "robots/arm5.urdf"
base = { xyz = [-0.45, 0.55, 0.0], yaw = 180 }
max_tcp_speed = 0.5
home = [-0.35, 0.30, 0.35]
intermediate = [-0.20, 0.25, 0.25]
retreat = [-0.45, 0.45, 0.40]

[robots.r2.ssm]
scan_period_s = 0.05

[[parts]]
id = "RA2"
owner = "r2"
size = [0.04, 0.04, 0.06]
start = { xyz = [-0.66, 0.30, 0.03], yaw = 0 }
target = { xyz = [-0.04, 0.16, 0.03], yaw = 0 }
"""

HAND_SPEED = 1.0  # m/s
# A point of r1's first move (home -> above the pick, 60 % of the way): the hand comes along +y
# from 0.6 m in front of it, stays on r1's path until LEAVE_S, then goes back the same way.
ON_PATH = (0.536, 0.30, 0.206)
START = (ON_PATH[0], ON_PATH[1] - 0.6, ON_PATH[2])
LEAVE_S = 3.0
FAR = {"position": [-0.3, -0.7, 0.1], "orientation": [0.0, 0.0, 0.0, 1.0]}


def _pose(xyz: tuple[float, float, float]) -> dict[str, Any]:
    return {"position": list(xyz), "orientation": [0.0, 0.0, 0.0, 1.0]}


def write_replay(path: Path) -> None:
    travel = 0.6 / HAND_SPEED
    keys = [(0.0, START), (travel, ON_PATH), (LEAVE_S, ON_PATH), (LEAVE_S + travel, START)]
    head = {"position": [0.0, -0.9, 0.6], "orientation": [0.0, 0.0, 0.0, 1.0]}
    lines = [json.dumps({"format": "hrc-human-input", "version": 1})]
    for t, xyz in keys:  # played with linear interpolation: a straight line at 1 m/s
        sample = {"t": t, "head": head, "left": FAR, "right": _pose(xyz)}
        lines.append(json.dumps({**sample, "left_grip": 0.0, "right_grip": 0.0}))
    path.write_text("\n".join(lines) + "\n")


def events(trial_dir: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (trial_dir / "events.jsonl").read_text().splitlines()]


def approach_trial(
    folder: Path, max_exchange_ticks: int | None = None, second_robot: bool = False
) -> Path:
    """Runs the approach scenario with the 1 m/s replay in `folder` (with ``second_robot``,
    SECOND_ROBOT too); the trial folder."""
    folder.mkdir(parents=True, exist_ok=True)
    scenario = folder / "ssm-approach.toml"
    text = SCENARIO
    if second_robot:
        text = text.replace('\n[[parts]]\nid = "RA1"', SECOND_ROBOT + '\n[[parts]]\nid = "RA1"', 1)
        text = text.replace('r1 = ["RA1"]', 'r1 = ["RA1"]\nr2 = ["RA2"]')
        assert "RA2" in text and 'r2 = ["RA2"]' in text
    if max_exchange_ticks is not None:
        text = text.replace("seed = 1\n", f"seed = 1\nmax_exchange_ticks = {max_exchange_ticks}\n")
        assert "max_exchange_ticks" in text
    scenario.write_text(text)
    (folder / "robots").symlink_to(ROOT / "robots")
    write_replay(folder / "approach.jsonl")
    out = folder / "trial"
    result = run_trial(
        TrialOptions(scenario=scenario, out=out, max_ticks=240 * 60, view=False), out
    )
    assert result.ok, result.message
    return out


def test_a_hand_approaching_at_1_mps_stops_r1_before_contact_and_r1_resumes(
    tmp_path: Path,
) -> None:
    out = approach_trial(tmp_path)
    evs = events(out)
    kinds = [e.get("kind") for e in evs if "kind" in e]
    assert "COLLISION" not in kinds, "the hand touched r1"
    stops = [e for e in evs if e.get("kind") == "PROTECTIVE_STOP"]
    resumes = [e for e in evs if e.get("kind") == "PROTECTIVE_RESUME"]
    assert stops and stops[0]["robot"] == "r1"
    assert stops[0]["task_time"] < 0.6 / HAND_SPEED + 0.5  # while the hand comes or waits
    assert resumes and resumes[-1]["task_time"] > LEAVE_S  # only once the hand goes away
    assert "TASK_FINISHED" in kinds  # it went on and finished by itself
    metrics = json.loads((out / "metrics.json").read_text())
    ssm = metrics["robots"]["r1"]["ssm"]
    assert ssm["protective_stop_count"] == len(stops) >= 1
    assert ssm["min_separation_m"] > 0.05  # stopped with room to spare
    assert ssm["protective_stop_s"] > 1.0 and ssm["reduced_speed_s"] > 0.0


def test_thesis_with_ssm_and_provoked_collisions_finishes(tmp_path: Path) -> None:
    text = (ROOT / "scenarios" / "thesis.toml").read_text()
    assert 'safety_policy = "retreat"' in text and "provoke_collisions = false" in text
    text = text.replace('safety_policy = "retreat"', 'safety_policy = "ssm"')
    text = text.replace("provoke_collisions = false", "provoke_collisions = [3.0, 12.0]")
    scenario = tmp_path / "thesis-ssm.toml"
    scenario.write_text(text)
    (tmp_path / "robots").symlink_to(ROOT / "robots")  # the file's robots/arm5.urdf
    out = tmp_path / "trial"
    result = run_trial(
        TrialOptions(scenario=scenario, out=out, max_ticks=240 * 400, view=False), out
    )
    assert result.ok, result.message
    assert result.run_end is not None and result.run_end.reason.startswith("stopped")
    evs = [e for e in events(out) if "kind" in e]
    kinds = [e["kind"] for e in evs]
    assert "TASK_FINISHED" in kinds and kinds.count("PART_PLACED") == 18
    assert "RETREAT_REACHED" not in kinds  # no retreat under ssm
    stops = [e for e in evs if e["kind"] == "PROTECTIVE_STOP"]
    resumes = [e for e in evs if e["kind"] == "PROTECTIVE_RESUME"]
    assert stops and resumes
    for robot in ("r1", "r2"):  # every stop is followed by its resume, in order
        mine = [
            e["payload"]["number"]
            for e in evs
            if e.get("robot") == robot and e["kind"] in ("PROTECTIVE_STOP", "PROTECTIVE_RESUME")
        ]
        assert mine == [n for n in range(1, len(mine) // 2 + 1) for _ in (0, 1)], robot
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["conditions"]["safety_policy"] == "ssm"
    for robot in ("r1", "r2"):
        ssm = metrics["robots"][robot]["ssm"]
        assert ssm["protective_stop_count"] == sum(1 for e in stops if e["robot"] == robot)
    # Provoked touches are still human-robot collisions, and each one ends with a resume.
    col = metrics["collisions"]
    assert col["human_robot_count"] == kinds.count("COLLISION") >= 1
    assert all(c["delay_s"] is not None and c["delay_s"] > 0 for c in col["human_robot"])
    log_txt = (out / "log.txt").read_text()
    assert "PROTECTIVE STOP 1" in log_txt and "resumes after protective stop 1" in log_txt


def test_ssm_trials_are_deterministic_and_decide_as_with_one_tick_exchanges(
    tmp_path: Path,
) -> None:
    """Twice the same events and metrics; and those of one-tick exchanges (docs/safety-ssm.md,
    step 2: the monitor decides at its scans, which start exchanges, and what it decides
    reaches the arm at the next scan). A monitor deciding at every tick from the separation of
    the exchange's first tick stopped r1 a tick early here."""
    wall = {"wall_time", "wall_s", "realtime_factor"}
    runs = []
    for name, span in (("a", None), ("b", None), ("one-tick", 1)):
        out = approach_trial(tmp_path / name, span)
        metrics = json.loads((out / "metrics.json").read_text())
        runs.append(strip_fields([events(out), metrics], wall))
        counts = exchange_counts((out / "services" / "physics.log").read_text())
        assert counts, "physics logs its exchanges at the end"
        ticks, n = counts
        assert n == ticks if span == 1 else n < ticks / 2, (name, ticks, n)
    assert runs[0] == runs[1]
    got, want = runs[0][0], runs[2][0]
    for i, (a, b) in enumerate(zip(got, want, strict=False)):
        assert a == b, f"event {i + 1}: {json.dumps(a)} != {json.dumps(b)} (one-tick exchanges)"
    assert len(got) == len(want)
    assert runs[0][1] == runs[2][1], "the metrics differ from those of one-tick exchanges"


def test_robots_whose_sensors_scan_at_other_periods_decide_as_with_one_tick_exchanges(
    tmp_path: Path,
) -> None:
    """r1's sensor scans every 7 ticks, r2's every 12 (SECOND_ROBOT): each monitor decides at
    its own scans, and the events and metrics are those of one-tick exchanges. (When the
    orchestrator declared only the first coming scan, the exchange that began there ran past
    the other robot's next scan, whose monitor then decided from the separation of that
    exchange's first tick: r1 stopped 21 ticks early, 18 of the 25 events at other ticks.)"""
    wall = {"wall_time", "wall_s", "realtime_factor"}
    runs = []
    for name, span in (("default", None), ("one-tick", 1)):
        out = approach_trial(tmp_path / name, span, second_robot=True)
        metrics = json.loads((out / "metrics.json").read_text())
        runs.append(strip_fields([events(out), metrics], wall))
    evs, metrics = runs[0]
    # both monitors decided: r1 stopped for the hand on its path, r2 slowed for it
    assert any(e.get("kind") == "PROTECTIVE_STOP" and e["robot"] == "r1" for e in evs)
    assert metrics["robots"]["r2"]["ssm"]["reduced_speed_s"] > 0
    assert metrics["robots"]["r2"]["ssm"]["protective_stop_count"] == 0
    got, want = runs[0][0], runs[1][0]
    for i, (a, b) in enumerate(zip(got, want, strict=False)):
        assert a == b, f"event {i + 1}: {json.dumps(a)} != {json.dumps(b)} (one-tick exchanges)"
    assert len(got) == len(want)
    assert runs[0][1] == runs[1][1], "the metrics differ from those of one-tick exchanges"
