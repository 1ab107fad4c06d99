"""The motion check: can every robot make every move the orchestrator will command?

One judge: the moves are planned and run by the IK service's own C++ motion generators, through
``hrc-ik --check-moves`` (a MotionCheckRequest on stdin, a MotionCheckReply on stdout; see
services/ik_cpp/README.md). `planned_moves` lists the moves in the order the orchestrator sends them
(services/orchestrator/hrc_orchestrator/robots.py): per part, transport robots home/intermediate
-> pick -> intermediate -> place -> intermediate; screwing robots the same with the feeder as the
pick; home at the end. Under the retreat policies, each move is also checked interrupted at its
start and at its end: to the retreat pose (with that move's yaw).

What the runtime does after an interruption needs no judging of its own (docs/task-semantics.md,
"Interruptions"): the IK service brings the arm back to the point where it left its task move and
follows the rest of the very plan judged here; a retreat that is not feasible where the arm stops
is made from where the task move began, which is judged here. `interrupted_moves` lists the checks
that show it, every task move interrupted at its start, middle and end by what each policy does
(tests/test_interruptions.py).
"""

from __future__ import annotations

import logging
import os
import subprocess
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from hrc.scenario.conventions import APPROACH_HEIGHT_M, grasp_point
from hrc.scenario.enums import RobotRole, SafetyPolicy
from hrc.scenario.errors import Problem
from hrc.scenario.models import Scenario
from hrc.wire import pb

log = logging.getLogger(__name__)

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class PlannedMove:
    """One move of one robot: the command, and what it means in the task."""

    robot: str
    part: str  # the part handled ("" for home moves)
    origin: str  # where the arm comes from, e.g. "intermediate"
    dest: str  # where it goes, e.g. "place"
    key: str  # the scenario key of the destination, e.g. "parts.RA1.target"
    command: pb.RobotCommand
    start: str = ""  # MoveCheck.start: "" after the previous move, "home", or a move label
    interrupt: pb.Interruption | None = None  # MoveCheck.interrupt: None for an undisturbed move

    @property
    def label(self) -> str:
        part = f" {self.part}" if self.part else ""
        return f"{self.robot}{part}: {self.origin} -> {self.dest}"


def _v(xyz: Sequence[float]) -> Vec3:
    return (float(xyz[0]), float(xyz[1]), float(xyz[2]))


def _command(
    robot: str, target: Vec3, yaw_deg: float, approach: float = 0.0, depart: float = 0.0
) -> pb.RobotCommand:
    return pb.RobotCommand(
        robot=robot,
        kind=pb.RobotCommand.KIND_MOVE,
        target=pb.Vec3(x=target[0], y=target[1], z=target[2]),
        yaw_deg=yaw_deg,
        approach_height=approach,
        depart_height=depart,
    )


def task_moves(scenario: Scenario, rid: str) -> list[PlannedMove]:
    """The moves robot `rid` makes in an undisturbed trial, in order, from home to home."""
    robot = scenario.robots[rid]
    a = APPROACH_HEIGHT_M
    moves: list[PlannedMove] = []
    here = "home"
    for pid in scenario.sequence_of(rid):
        part = next(p for p in scenario.parts if p.id == pid)
        if robot.role == RobotRole.SCREWING:
            feeder = _v(robot.feeder or (0.0, 0.0, 0.0))
            pick, pick_yaw, pick_name = grasp_point(feeder, part.size), 0.0, "feeder"
            pick_key = f"robots.{rid}.feeder"
        else:
            assert part.start is not None  # checked by the loader
            pick, pick_yaw, pick_name = (
                grasp_point(_v(part.start.xyz), part.size),
                part.start.yaw,
                "pick",
            )
            pick_key = f"parts.{pid}.start"
        place = grasp_point(_v(part.target.xyz), part.size)
        yaw = part.target.yaw
        inter = _v(robot.intermediate)
        moves += [
            PlannedMove(rid, pid, here, pick_name, pick_key, _command(rid, pick, pick_yaw, a)),
            PlannedMove(
                rid,
                pid,
                pick_name,
                "intermediate",
                f"robots.{rid}.intermediate",
                _command(rid, inter, yaw, 0.0, a),
            ),
            PlannedMove(
                rid,
                pid,
                "intermediate",
                "place",
                f"parts.{pid}.target",
                _command(rid, place, yaw, a),
            ),
            PlannedMove(
                rid,
                pid,
                "place",
                "intermediate",
                f"robots.{rid}.intermediate",
                _command(rid, inter, yaw, 0.0, a),
            ),
        ]
        here = "intermediate"
    moves.append(
        PlannedMove(rid, "", here, "home", f"robots.{rid}.home", _command(rid, _v(robot.home), 0.0))
    )
    return moves


def planned_moves(scenario: Scenario) -> list[PlannedMove]:
    """Every move every robot can be commanded: the task moves, then (under the retreat policies)
    each one interrupted at its start and at its end: to the retreat pose and back to its target."""
    out: list[PlannedMove] = []
    retreats = scenario.conditions.safety_policy in (
        SafetyPolicy.RETREAT,
        SafetyPolicy.RETREAT_BUTTON,
    )
    for rid in sorted(scenario.robots):
        task = task_moves(scenario, rid)
        out += task
        if not retreats:
            continue
        retreat = _v(scenario.robots[rid].retreat)
        for i, move in enumerate(task):
            starts = [
                ("home" if i == 0 else task[i - 1].label, move.origin),
                (move.label, move.dest),
            ]
            for start, where in starts:
                out.append(
                    PlannedMove(
                        rid,
                        move.part,
                        where,
                        "retreat",
                        f"robots.{rid}.retreat",
                        _command(rid, retreat, move.command.yaw_deg),
                        start,
                    )
                )
    return out


# Where the interruption checks interrupt a move: at its start, middle and just before its end.
INTERRUPT_FRACTIONS = (0.0, 0.5, 0.97)
INTERRUPT_WAIT_S = 0.5  # how long the arm stands still before the move is commanded again


def interruptions(
    policy: SafetyPolicy, robot: str, retreat: Vec3, yaw_deg: float
) -> dict[str, pb.RobotCommand]:
    """What a policy can do to a moving arm, by name: a hold (stop_colliding, and a near collision
    under every policy), a detour to the retreat pose (the retreat policies), a speed scale of 0
    (ssm)."""
    out = {"hold": pb.RobotCommand(robot=robot, kind=pb.RobotCommand.KIND_HOLD)}
    if policy in (SafetyPolicy.RETREAT, SafetyPolicy.RETREAT_BUTTON):
        detour = _command(robot, retreat, yaw_deg)
        detour.detour = True
        out["retreat"] = detour
    if policy == SafetyPolicy.SSM:
        out["speed 0"] = pb.RobotCommand(
            robot=robot, kind=pb.RobotCommand.KIND_SPEED_SCALE, speed_scale=0.0
        )
    return out


def interrupted_moves(scenario: Scenario, durations_s: dict[str, float]) -> list[PlannedMove]:
    """Every task move of every robot interrupted at each of INTERRUPT_FRACTIONS of its undisturbed
    duration (`durations_s`, by move label) by each of what the scenario's policy can do, then
    commanded again. Each starts where the move before it ended undisturbed (its label)."""
    out: list[PlannedMove] = []
    policy = scenario.conditions.safety_policy
    for rid in sorted(scenario.robots):
        task = task_moves(scenario, rid)
        retreat = _v(scenario.robots[rid].retreat)
        for i, move in enumerate(task):
            start = "home" if i == 0 else task[i - 1].label
            kinds = interruptions(policy, rid, retreat, move.command.yaw_deg)
            for fraction in INTERRUPT_FRACTIONS:
                for name, command in kinds.items():
                    out.append(
                        PlannedMove(
                            rid,
                            move.part,
                            move.origin,
                            f"{move.dest} ({name} at {fraction:.0%})",
                            move.key,
                            move.command,
                            start,
                            pb.Interruption(
                                at_s=fraction * durations_s[move.label],
                                command=command,
                                wait_s=INTERRUPT_WAIT_S,
                            ),
                        )
                    )
    return out


class MotionCheckError(Exception):
    """The check could not run (hrc-ik missing or failing); the message says why."""


def run_check(
    scenario_pb: pb.Scenario, moves: Sequence[PlannedMove], binary: Path | None = None
) -> list[pb.MoveCheckResult]:
    """Plans and runs `moves` with ``hrc-ik --check-moves``; one result per move, in order.

    A robot's moves depend on each other (each starts where an earlier one of the same robot
    ended), the robots' do not: each robot's moves go to a process of their own, run at the
    same time (the check is on the path of ``hrc run`` before any service starts)."""
    if binary is None:
        from hrc.paths import ik_binary

        binary = ik_binary()
    if not binary.exists():
        raise MotionCheckError(f"{binary} is missing: build services/ik_cpp (scripts/setup.sh)")
    by_robot: dict[str, list[int]] = {}
    for i, m in enumerate(moves):
        by_robot.setdefault(m.command.robot, []).append(i)
    if len(by_robot) > 1 and _cores() > 1:
        groups = list(by_robot.values())
    else:
        groups = [list(range(len(moves)))]

    def check(group: list[int]) -> subprocess.CompletedProcess[bytes]:
        request = pb.MotionCheckRequest(scenario=scenario_pb)
        for i in group:
            m = moves[i]
            check = request.moves.add(label=m.label, command=m.command, start=m.start)
            if m.interrupt is not None:
                check.interrupt.CopyFrom(m.interrupt)
        return subprocess.run(
            [str(binary), "--check-moves"],
            input=request.SerializeToString(),
            capture_output=True,
            check=False,
            timeout=600,
        )

    with ThreadPoolExecutor(max_workers=len(groups)) as pool:
        procs = list(pool.map(check, groups))
    results: list[pb.MoveCheckResult] = [pb.MoveCheckResult()] * len(moves)
    for group, proc in zip(groups, procs, strict=True):
        if proc.returncode != 0:
            raise MotionCheckError(
                proc.stderr.decode(errors="replace").strip()
                or f"hrc-ik --check-moves exited with {proc.returncode}"
            )
        reply = pb.MotionCheckReply.FromString(proc.stdout)
        if len(reply.results) != len(group):
            raise MotionCheckError(
                f"hrc-ik --check-moves answered {len(reply.results)} of {len(group)} moves"
            )
        for i, r in zip(group, reply.results, strict=True):
            results[i] = r
    return results


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def check_motion(scenario: Scenario, binary: Path | None = None) -> list[Problem]:
    """One problem per infeasible move: robot, part, from -> to, target, where and why."""
    from hrc.scenario.convert import to_proto

    moves = planned_moves(scenario)
    try:
        results = run_check(to_proto(scenario), moves, binary)
    except MotionCheckError as exc:
        return [Problem("robots", f"motion check failed: {exc}")]
    problems: list[Problem] = []
    for move, result in zip(moves, results, strict=True):
        if result.feasible:
            continue
        t = move.command.target
        where = f"[{t.x:.3f}, {t.y:.3f}, {t.z:.3f}] yaw {move.command.yaw_deg:g}"
        problems.append(
            Problem(
                move.key, f"robot {move.label} (target {where}) is not feasible: {result.detail}"
            )
        )
    log.debug("motion check: %d moves, %d infeasible", len(moves), len(problems))
    return problems
