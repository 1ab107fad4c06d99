"""Can each robot reach every point the scenario sends it to, with the tool pointing down?

`reach_items` lists the points: every robot pose (home, intermediate, retreat, feeder) and, for
each part a robot owns, its pick (start) and place (target) positions plus the approach point
APPROACH_HEIGHT_M above each (picks and places approach and leave vertically).

`PybulletReachChecker` answers by the arm's own kinematics: it loads the robot's URDF at its
base pose in a private pybullet DIRECT client, solves inverse kinematics for the tool link at the
point with the tool's z axis along world -z, from a few seeded starts and several tool yaws,
and accepts a solution whose forward kinematics put the tool within REACH_TOLERANCE_M of the
point and within AXIS_TOLERANCE_DEG of pointing down. Any object with the same `check` method
(e.g. one that asks the IK service's `robot/reach` queryable) can replace it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

from hrc.scenario.conventions import APPROACH_HEIGHT_M

if TYPE_CHECKING:
    from hrc.scenario.models import Part, Robot

REACH_TOLERANCE_M = 0.005  # reached within 5 mm (docs/task-semantics.md#robot-motion)
AXIS_TOLERANCE_DEG = 2.0  # "pointing down" within this angle
TOOL_LINK = "tool"


@dataclass(frozen=True)
class ReachItem:
    key: str  # the scenario key the point comes from, e.g. "parts.RA1.target"
    robot: str
    position: tuple[float, float, float]
    yaw_deg: float | None  # preferred tool yaw (part yaw); None: any
    note: str = ""  # e.g. "approach point 0.05 m above"


@dataclass(frozen=True)
class ReachResult:
    item: ReachItem
    reachable: bool
    position_error_m: float
    detail: str = ""


class ReachChecker(Protocol):
    def check(self, robot: Robot, urdf: Path, items: Sequence[ReachItem]) -> list[ReachResult]:
        """One result per item, in order. `robot` gives the base pose."""
        ...


def reach_items(robot: Robot, parts: Sequence[Part]) -> list[ReachItem]:
    """The points robot must reach: its poses, then each of its parts' picks and places."""
    rid = robot.id
    items: list[ReachItem] = []
    poses = [("home", robot.home), ("intermediate", robot.intermediate), ("retreat", robot.retreat)]
    for name, pos in poses:
        items.append(ReachItem(f"robots.{rid}.{name}", rid, _vec(pos), None))
    if robot.feeder is not None:
        items.extend(_with_approach(f"robots.{rid}.feeder", rid, robot.feeder, None))
    for part in parts:
        if part.owner != rid:
            continue
        if part.start is not None:
            items.extend(_with_approach(f"parts.{part.id}.start", rid, part.start.xyz,
                                        part.start.yaw))
        items.extend(_with_approach(f"parts.{part.id}.target", rid, part.target.xyz,
                                    part.target.yaw))
    return items


def _vec(v: Sequence[float]) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def _with_approach(key: str, rid: str, pos: Sequence[float], yaw: float | None) -> list[ReachItem]:
    x, y, z = _vec(pos)
    return [
        ReachItem(key, rid, (x, y, z), yaw),
        ReachItem(key, rid, (x, y, z + APPROACH_HEIGHT_M), yaw,
                  f"approach point {APPROACH_HEIGHT_M:g} m above"),
    ]


# ---------------------------------------------------------------- pybullet checker


class ArmModelError(Exception):
    """The URDF cannot serve for the check (not loadable, no tool link, no joints)."""


@dataclass
class _Arm:
    body: int
    tool: int
    joints: list[int]  # movable joint indices, in pybullet's DOF order
    lower: list[float]
    upper: list[float]


class PybulletReachChecker:
    """Reach check by the arm's kinematics in pybullet (DIRECT mode, no window).

    Use as a context manager, or call close(); one pybullet client serves every robot checked.
    Deterministic: the restarts use a fixed seed.
    """

    def __init__(self, tool_link: str = TOOL_LINK, restarts: int = 4, seed: int = 7) -> None:
        self.tool_link = tool_link
        self.restarts = restarts
        self.seed = seed
        self._client: int | None = None
        self._arms: dict[tuple[str, tuple[float, ...]], _Arm] = {}

    def __enter__(self) -> PybulletReachChecker:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()

    def close(self) -> None:
        if self._client is not None:
            import pybullet as p

            p.disconnect(physicsClientId=self._client)
            self._client = None
            self._arms.clear()

    def _pb(self):  # noqa: ANN202 - the pybullet module
        import pybullet as p

        if self._client is None:
            self._client = p.connect(p.DIRECT)
        return p

    def _arm(self, robot: Robot, urdf: Path) -> _Arm:
        p = self._pb()
        cid = self._client
        base = (*robot.base.xyz, robot.base.yaw)
        cache_key = (str(urdf), tuple(float(v) for v in base))
        if cache_key in self._arms:
            return self._arms[cache_key]
        orn = p.getQuaternionFromEuler([0.0, 0.0, math.radians(robot.base.yaw)])
        try:
            body = p.loadURDF(str(urdf), basePosition=list(robot.base.xyz), baseOrientation=orn,
                              useFixedBase=True, physicsClientId=cid)
        except p.error as exc:
            raise ArmModelError(f"pybullet cannot load {urdf}: {exc}") from exc
        tool = -1
        joints: list[int] = []
        lower: list[float] = []
        upper: list[float] = []
        for j in range(p.getNumJoints(body, physicsClientId=cid)):
            info = p.getJointInfo(body, j, physicsClientId=cid)
            if info[12].decode() == self.tool_link:
                tool = j
            if info[2] != p.JOINT_FIXED:
                joints.append(j)
                lo, hi = float(info[8]), float(info[9])
                if hi < lo or (lo == 0.0 and hi == 0.0):  # continuous joint: no limits
                    lo, hi = -2 * math.pi, 2 * math.pi
                lower.append(lo)
                upper.append(hi)
        if tool < 0:
            raise ArmModelError(f"{urdf} has no link named {self.tool_link!r}")
        if not joints:
            raise ArmModelError(f"{urdf} has no movable joints")
        arm = _Arm(body, tool, joints, lower, upper)
        self._arms[cache_key] = arm
        return arm

    def check(self, robot: Robot, urdf: Path, items: Sequence[ReachItem]) -> list[ReachResult]:
        try:
            arm = self._arm(robot, urdf)
        except ArmModelError as exc:
            return [ReachResult(item, False, math.inf, str(exc)) for item in items]
        return [self._check_one(robot, arm, item) for item in items]

    def _check_one(self, robot: Robot, arm: _Arm, item: ReachItem) -> ReachResult:
        import random

        rng = random.Random(f"{self.seed}:{item.robot}:{item.position}")
        natural = math.degrees(math.atan2(item.position[1] - robot.base.xyz[1],
                                          item.position[0] - robot.base.xyz[0]))
        yaws = [item.yaw_deg] if item.yaw_deg is not None else []
        yaws += [natural, natural + 90.0, natural - 90.0, natural + 180.0]
        mid = [0.5 * (lo + hi) if hi - lo < 2 * math.pi else 0.0
               for lo, hi in zip(arm.lower, arm.upper)]
        seeds = [mid] + [[rng.uniform(lo, hi) for lo, hi in zip(arm.lower, arm.upper)]
                         for _ in range(self.restarts - 1)]
        best_err, best_axis = math.inf, 180.0
        for yaw in yaws:
            for seed in seeds:
                err, axis = self._solve(arm, item.position, yaw, seed)
                if err < best_err or (err == best_err and axis < best_axis):
                    best_err, best_axis = err, axis
                if err <= REACH_TOLERANCE_M and axis <= AXIS_TOLERANCE_DEG:
                    return ReachResult(item, True, err)
        if best_err <= REACH_TOLERANCE_M:
            detail = (f"reachable only with the tool tilted {best_axis:.0f} deg from pointing "
                      "down")
        else:
            detail = f"closest tool position is {best_err * 1000:.0f} mm away"
        return ReachResult(item, False, best_err, detail)

    def _solve(self, arm: _Arm, target: tuple[float, float, float], yaw_deg: float,
               seed: list[float]) -> tuple[float, float]:
        p = self._pb()
        cid = self._client
        # Tool z along world -z: roll pi about x, then the yaw about world z.
        orn = p.getQuaternionFromEuler([math.pi, 0.0, math.radians(yaw_deg)])
        ranges = [hi - lo for lo, hi in zip(arm.lower, arm.upper)]
        best = (math.inf, 180.0)
        # pybullet's null-space IK (with joint limits) trades accuracy for staying near the rest
        # pose, so the plain solver goes first and the limited one is the fallback; solutions are
        # wrapped into and clamped to the limits before the forward-kinematics check either way.
        for limited in (False, True):
            q = list(seed)
            for _ in range(10):
                for j, v in zip(arm.joints, q):
                    p.resetJointState(arm.body, j, v, physicsClientId=cid)
                extra = (dict(lowerLimits=arm.lower, upperLimits=arm.upper, jointRanges=ranges,
                              restPoses=seed) if limited else {})
                sol = p.calculateInverseKinematics(
                    arm.body, arm.tool, list(target), orn, maxNumIterations=100,
                    residualThreshold=1e-7, physicsClientId=cid, **extra)
                q = [_into_limits(v, lo, hi) for v, lo, hi in zip(sol, arm.lower, arm.upper)]
                err, axis = self._fk_error(arm, q, target)
                if (err, axis) < best:
                    best = (err, axis)
                if err <= REACH_TOLERANCE_M * 0.2 and axis <= AXIS_TOLERANCE_DEG * 0.5:
                    return best
        return best

    def _fk_error(self, arm: _Arm, q: list[float], target: tuple[float, float, float]
                  ) -> tuple[float, float]:
        p = self._pb()
        cid = self._client
        for j, v in zip(arm.joints, q):
            p.resetJointState(arm.body, j, v, physicsClientId=cid)
        state = p.getLinkState(arm.body, arm.tool, computeForwardKinematics=True,
                               physicsClientId=cid)
        pos, quat = state[4], state[5]  # the link's URDF frame, not its centre of mass
        err = math.dist(pos, target)
        m = p.getMatrixFromQuaternion(quat)
        z_world = m[8]  # z component of the tool's z axis
        axis = math.degrees(math.acos(max(-1.0, min(1.0, -z_world))))
        return err, axis


def _into_limits(angle: float, lo: float, hi: float) -> float:
    """The same joint angle shifted by whole turns into [lo, hi] when possible, else clamped."""
    for shifted in (angle, angle - 2 * math.pi, angle + 2 * math.pi):
        if lo <= shifted <= hi:
            return shifted
    return min(max(angle, lo), hi)
