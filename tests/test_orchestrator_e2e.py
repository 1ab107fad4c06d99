"""End to end: `hrc run` with all five services on the thesis scenario (docs/metrics.md, and
each safety policy's behaviour with a scripted participant told to provoke collisions).

The task events are read from the orchestrator's service log, where it writes one parseable line
per published event (``event <KIND> | <text>``) and per robot command
(``command <robot> #<id> <MOVE|HOLD> (x, y, z)``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import pytest

from hrc.paths import ik_binary

from . import goldens
from .goldens import THESIS, Finished

ROOT = Path(__file__).resolve().parents[1]
HRC = ROOT / ".venv" / "bin" / "hrc"
TICK_CAP = 240 * 100  # 100 s of sim time: a stalled policy ends the run instead of hanging

pytestmark = [
    pytest.mark.e2e,
    pytest.mark.slow,
    pytest.mark.skipif(
        not ik_binary().exists(),
        reason=f"the IK service binary {ik_binary()} is missing (build it with scripts/setup.sh)",
    ),
]

EVENT_RE = re.compile(r" event ([A-Z_]+) \| (.*)$")
COMMAND_RE = re.compile(r" command (\S+) #(\d+) (MOVE|HOLD) \(([-\d.e]+), ([-\d.e]+), ([-\d.e]+)\)")
TIME_RE = re.compile(r"^([-\d.]+) sec : ")

SPEC_FIELDS = [
    "scenario",
    "participant",
    "conditions",
    "seed",
    "task.completion_s",
    "human.completion_s",
    "human.idle_s",
    "collisions.human_robot",
    "collisions.human_robot_count",
    "collisions.total_delay_s",
    "collisions.near",
    "collisions.near_count",
    "run.mode",
    "run.ticks",
    "run.wall_s",
    "run.realtime_factor",
]
ROBOT_FIELDS = ["completion_s", "idle_s", "avg_tcp_speed_mps", "max_tcp_speed_mps"]


@dataclass
class Line:
    index: int
    kind: str  # an event kind (COLLISION, ...) or "command"
    text: str
    robot: str = ""
    target: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def t(self) -> float:
        m = TIME_RE.match(self.text)
        return float(m.group(1)) if m else -1.0


def run_trial(scenario: Path, out: Path, ticks: int = TICK_CAP) -> tuple[dict, list[Line]]:
    # (the task's events and metrics are read, not the 3D recording: a tenth of the CPU less)
    return read_trial(goldens.run_trial(scenario, out, "--no-view", max_ticks=ticks))


def read_trial(trial: Finished) -> tuple[dict, list[Line]]:
    """The trial's metrics and the events and commands of its orchestrator's log."""
    orch_log = trial.folder / "services" / "orchestrator.log"
    log_text = orch_log.read_text(errors="replace") if orch_log.exists() else ""
    assert trial.returncode == 0, (
        f"hrc run failed ({trial.returncode}):\n{trial.stdout}\n"
        f"{trial.stderr}\n--- orchestrator log tail:\n{log_text[-3000:]}"
    )
    return trial.metrics, parse_log(log_text)


def parse_log(text: str) -> list[Line]:
    lines: list[Line] = []
    for i, raw in enumerate(text.splitlines()):
        if m := EVENT_RE.search(raw):
            words = m.group(2)
            robot = ""
            for name in ("r1", "r2"):
                if f" {name} " in f" {words} " or f"between {name}" in words:
                    robot = name
            lines.append(Line(i, m.group(1), words, robot))
        elif m := COMMAND_RE.search(raw):
            lines.append(
                Line(
                    i,
                    m.group(3),
                    raw,
                    m.group(1),
                    (float(m.group(4)), float(m.group(5)), float(m.group(6))),
                )
            )
    return lines


def dig(d: dict, path: str):
    for key in path.split("."):
        assert key in d, f"metrics.json has no {path!r}"
        d = d[key]
    return d


def policy_scenario(tmp: Path, policy: str) -> Path:
    text = THESIS.read_text()
    assert 'safety_policy = "retreat"' in text and "provoke_collisions = false" in text
    text = text.replace('safety_policy = "retreat"', f'safety_policy = "{policy}"')
    text = text.replace("provoke_collisions = false", "provoke_collisions = [3.0, 12.0]")
    path = tmp / f"thesis-{policy}.toml"
    path.write_text(text)
    return path


def first(lines: list[Line], kind: str, after: int = -1) -> Line | None:
    return next((ln for ln in lines if ln.kind == kind and ln.index > after), None)


def test_thesis_run_writes_every_spec_metric(thesis_trial: Finished) -> None:
    data, lines = read_trial(thesis_trial)
    for path in SPEC_FIELDS:
        dig(data, path)
    assert data["scenario"] == "thesis-board" and data["participant"] == "P01"
    cond = data["conditions"]
    assert cond["anticipation"] is True and cond["safety_policy"] == "retreat"
    assert cond["robots"] == {"r1": {"max_tcp_speed": 0.5}, "r2": {"max_tcp_speed": 0.5}}
    assert cond["ssm"] is None
    assert data["task"]["completion_s"] is not None, "the task did not finish"
    assert data["run"]["mode"] == "lockstep" and data["run"]["ticks"] > 0
    assert set(data["robots"]) == {"r1", "r2"}
    for rid, r in data["robots"].items():
        for name in ROBOT_FIELDS:
            assert isinstance(r[name], (int, float)), f"robots.{rid}.{name} = {r[name]!r}"
        assert 0 < r["avg_tcp_speed_mps"] <= r["max_tcp_speed_mps"] <= 0.5 * 1.05
    assert len(data["parts"]) == 18
    for pid, p in data["parts"].items():
        assert p["grabbed_s"] is not None and p["placed_s"] is not None, pid
        assert p["grabbed_s"] <= p["placed_s"]
    col = data["collisions"]
    assert col["human_robot_count"] == len(col["human_robot"])
    assert col["near_count"] == len(col["near"])
    kinds = [ln.kind for ln in lines if ln.kind not in ("MOVE", "HOLD")]
    # TASK FINISHED at the last placement (the robots then go home: their phases follow)
    assert kinds[0] == "TASK_STARTED" and kinds.count("TASK_FINISHED") == 1
    assert kinds.count("PART_PLACED") == 18
    last_placed = max(i for i, k in enumerate(kinds) if k == "PART_PLACED")
    assert kinds.index("TASK_FINISHED") > last_placed
    assert set(kinds[kinds.index("TASK_FINISHED") + 1 :]) <= {"ROBOT_PHASE"}


def retreat_pose(policy_file: Path, robot: str) -> tuple[float, float, float]:
    from hrc import scenario as sc

    return tuple(sc.load(policy_file, motion_check=False).robots[robot].retreat)  # type: ignore


def test_policy_retreat_both_retreat_then_resume(tmp_path: Path) -> None:
    scen = policy_scenario(tmp_path, "retreat")
    data, lines = run_trial(scen, tmp_path / "trial")
    col = first(lines, "COLLISION")
    assert col is not None, "the scripted participant caused no collision"
    reached = [ln for ln in lines if ln.kind == "RETREAT_REACHED" and ln.index > col.index]
    cont = first(lines, "CONTINUED", col.index)
    assert cont is not None
    assert {ln.robot for ln in reached if ln.index < cont.index} == {"r1", "r2"}
    for rid in ("r1", "r2"):
        moves = [
            ln
            for ln in lines
            if ln.kind == "MOVE" and ln.robot == rid and col.index < ln.index < cont.index
        ]
        assert any(ln.target == pytest.approx(retreat_pose(scen, rid)) for ln in moves)
        resumed = [
            ln for ln in lines if ln.kind == "MOVE" and ln.robot == rid and ln.index > cont.index
        ]
        assert resumed, f"{rid} never moved after the collision"
    assert data["collisions"]["human_robot_count"] >= 1
    assert data["collisions"]["human_robot"][0]["delay_s"] > 0
    assert data["collisions"]["total_delay_s"] > 0


def test_policy_retreat_button_no_resume_before_the_button(tmp_path: Path) -> None:
    scen = policy_scenario(tmp_path, "retreat_button")
    _data, lines = run_trial(scen, tmp_path / "trial")
    col = first(lines, "COLLISION")
    assert col is not None, "the scripted participant caused no collision"
    reached = [ln for ln in lines if ln.kind == "RETREAT_REACHED" and ln.index > col.index]
    assert {ln.robot for ln in reached} >= {"r1", "r2"}
    for c in [ln for ln in lines if ln.kind == "COLLISION"]:
        cont = first(lines, "CONTINUED", c.index)
        if cont is None:
            continue  # never pressed: never resumed (the run ended on the tick cap)
        pressed = first(lines, "BUTTON_PRESSED", c.index)
        assert pressed is not None and pressed.index < cont.index, (
            "robots resumed without the continue button"
        )
        last_arrival = max(ln.index for ln in reached if ln.index < cont.index)
        assert last_arrival < cont.index
    # the scripted participant presses the button, so the robots do resume
    assert first(lines, "BUTTON_PRESSED", col.index) is not None
    assert first(lines, "CONTINUED", col.index) is not None


def test_policy_stop_colliding_the_other_robot_carries_on(tmp_path: Path) -> None:
    scen = policy_scenario(tmp_path, "stop_colliding")
    data, lines = run_trial(scen, tmp_path / "trial")
    col = first(lines, "COLLISION")
    assert col is not None, "the scripted participant caused no collision"
    assert [ln for ln in lines if ln.kind == "RETREAT_REACHED"] == []
    touched = col.robot
    other = "r2" if touched == "r1" else "r1"
    halted = first(lines, "ROBOT_HALTED", col.index - 1)
    assert halted is not None and halted.robot == touched
    cont = first(lines, "CONTINUED", col.index)
    end = cont.index if cont is not None else 10**9
    holds = [ln for ln in lines if ln.kind == "HOLD" and col.index < ln.index < end]
    assert any(ln.robot == touched for ln in holds)
    near_halts = [
        ln
        for ln in lines
        if ln.kind == "NEAR_COLLISION"
        and col.index < ln.index < end
        and f"{other} halts" in ln.text
    ]
    if not near_halts:
        assert not any(ln.robot == other for ln in holds), f"{other} was stopped as well"
    assert not any(
        ln.kind == "MOVE"
        and ln.robot == other
        and ln.target == pytest.approx(retreat_pose(scen, other))
        for ln in lines
        if col.index < ln.index < end
    )
    assert data["collisions"]["human_robot_count"] >= 1
