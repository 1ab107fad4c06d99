"""Kinematic robots: URDF bodies whose joints are set from `RobotState`, never driven by motors."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import pybullet as p

from hrc.geometry import IDENTITY, Pose, Quat, compose, relative, vec3, yaw_quat_deg
from hrc.scenario.models import DEFAULT_BASE_LINK, DEFAULT_TIP_LINK
from hrc.validate import all_finite

from hrc_physics.closest import Box

BASE = -1  # pybullet's link index of a body's base
# m added to the bound on how far the colliders moved (KinematicRobot.bounds): covers the
# AABBs' floating-point rounding many times over.
ROUNDING_M = 1e-4


@dataclass(frozen=True)
class Chain:
    """The scenario's chain: base_link (placed at the robot's base pose), tip_link, and the
    TCP in the tip link's frame."""

    base_link: str = DEFAULT_BASE_LINK
    tip_link: str = DEFAULT_TIP_LINK
    tcp: Pose = Pose((0.0, 0.0, 0.0), IDENTITY)


class RobotModelError(Exception):
    """The URDF cannot serve (not loadable, no tool link)."""


class KinematicRobot:
    """One arm at its base pose. It takes no part in the dynamics (collision mask 0): its links
    are posed each tick and only the contact queries look at their collision shapes."""

    def __init__(
        self,
        client: int,
        robot_id: str,
        urdf: Path,
        base_xyz: Sequence[float],
        base_yaw_deg: float,
        near_margin: float,
        chain: Chain | None = None,
    ) -> None:
        chain = chain or Chain()
        self.tcp = chain.tcp
        self.id = robot_id
        self.near_margin = near_margin
        self._c = client
        try:
            self.body = p.loadURDF(
                str(urdf),
                basePosition=list(base_xyz),
                baseOrientation=yaw_quat_deg(base_yaw_deg),
                useFixedBase=True,
                physicsClientId=client,
            )
        except p.error as exc:
            raise RobotModelError(f"robot {robot_id}: pybullet cannot load {urdf}: {exc}") from exc
        base_name = p.getBodyInfo(self.body, physicsClientId=client)[0].decode()
        self.link_names: dict[int, str] = {BASE: base_name}
        self.joint_index: dict[str, int] = {}
        self.movable: list[int] = []
        self.tool = BASE
        for j in range(p.getNumJoints(self.body, physicsClientId=client)):
            info = p.getJointInfo(self.body, j, physicsClientId=client)
            name, link = info[1].decode(), info[12].decode()
            self.link_names[j] = link
            if link == chain.tip_link:
                self.tool = j
            if info[2] != p.JOINT_FIXED:
                self.joint_index[name] = j
                self.movable.append(j)
        if self.tool == BASE and base_name != chain.tip_link:
            raise RobotModelError(f"robot {robot_id}: {urdf} has no link named {chain.tip_link!r}")
        self._place_base(chain.base_link, base_xyz, base_yaw_deg, urdf)
        for link in self.link_names:
            p.setCollisionFilterGroupMask(self.body, link, 0, 0, physicsClientId=client)
        # Asleep for good: the solver never integrates the arm (no sagging between our resets,
        # no cost); resetting its joints still moves its colliders for the contact queries.
        p.changeDynamics(
            self.body,
            BASE,
            activationState=p.ACTIVATION_STATE_ENABLE_SLEEPING,
            physicsClientId=client,
        )
        p.changeDynamics(
            self.body, BASE, activationState=p.ACTIVATION_STATE_SLEEP, physicsClientId=client
        )
        # Links with collision shapes (the tool frame has none).
        self._links = [
            link
            for link in self.link_names
            if p.getCollisionShapeData(self.body, link, physicsClientId=client)
        ]
        self.joint_names = [n for n, _ in sorted(self.joint_index.items(), key=lambda kv: kv[1])]
        self.positions: list[float] = [0.0] * len(self.movable)
        self._applied: list[float] | None = None
        # The links' AABB until they move (a joint reset here, or a world step: the first step
        # after a reset still nudges the links): contacts and span planning ask for it per tick.
        self._aabb: Box | None = None
        self._boxes: list[tuple[int, Box]] | None = None
        # The last measured AABB and how far any collider may have moved since (m): what the
        # contact checks need to skip an arm that cannot have come near (see ``bounds``). The
        # per-joint levers (m per rad, 1 for a sliding joint) come with ``bound_motion``.
        self._loose: Box | None = None
        self._drift = 0.0
        self._levers: list[float] | None = None
        self._order_cache: dict[tuple[str, ...], list[int] | str] = {}

    def _indices(self, names: Sequence[str]) -> list[int] | str:
        key = tuple(names)
        hit = self._order_cache.get(key)
        if hit is None:
            unknown = [n for n in names if n not in self.joint_index]
            if unknown:
                hit = f"robot {self.id} has no joint named {', '.join(unknown)}"
            else:
                order = [self.movable.index(self.joint_index[n]) for n in names]
                hit = order
            self._order_cache[key] = hit
        return hit

    def set_state(self, names: Sequence[str], positions: Sequence[float]) -> str | None:
        """Records joint positions (by name; no names: in URDF order). Returns a problem or None."""
        if not all_finite(positions):
            return f"robot {self.id}: joint positions contain NaN or infinity"
        if names:
            if len(names) != len(positions):
                return f"robot {self.id}: {len(names)} joint names but {len(positions)} positions"
            order = self._indices(names)
            if isinstance(order, str):
                return order
            new = list(self.positions)
            for i, v in zip(order, positions, strict=True):
                new[i] = float(v)
        else:
            if len(positions) != len(self.movable):
                return (
                    f"robot {self.id}: {len(positions)} joint positions for "
                    f"{len(self.movable)} joints"
                )
            new = [float(v) for v in positions]
        self.positions = new
        return None

    def bound_motion(self, reaches: dict[str, tuple[float, bool]]) -> None:
        """Lets the arm bound how far its colliders move from how far its joints do
        (``reaches``: joint -> (m per rad, sliding), hrc_physics.exchange.joint_reaches)."""
        by_index = {j: name for name, j in self.joint_index.items()}
        self._levers = [
            1.0 if reaches[by_index[j]][1] else reaches[by_index[j]][0] for j in self.movable
        ]

    def apply(self) -> bool:
        """Puts the links where the recorded joint positions say (zero velocities); True if
        they moved."""
        if self.positions == self._applied:
            return False  # the arm stands still: nothing to move
        if self._levers is None or self._applied is None:
            self._loose = None  # no bound: the next measurement starts one
        else:
            self._drift += sum(
                lever * abs(a - b)
                for lever, a, b in zip(self._levers, self.positions, self._applied, strict=True)
            )
        p.resetJointStatesMultiDof(
            self.body, self.movable, [[v] for v in self.positions], physicsClientId=self._c
        )
        self._applied = list(self.positions)
        self._aabb = None
        self._boxes = None
        return True

    def stepped(self) -> None:
        """The world stepped: the links may have moved (see ``_boxes``)."""
        self._aabb = None
        self._boxes = None

    def link_boxes(self) -> list[tuple[int, Box]]:
        """(link, world AABB) of each link with a collider (the closest-point queries' bounds)."""
        if self._boxes is None:
            self._boxes = [
                (link, cast(Box, p.getAABB(self.body, link, physicsClientId=self._c)))
                for link in self._links
            ]
        return self._boxes

    def aabb(self) -> Box:
        """World AABB of all link colliders (cheap prefilter for the distance queries)."""
        if self._aabb is not None:
            return self._aabb
        boxes = [b for _, b in self.link_boxes()]
        lo = tuple(map(min, zip(*(b[0] for b in boxes), strict=True)))
        hi = tuple(map(max, zip(*(b[1] for b in boxes), strict=True)))
        self._aabb = self._loose = (vec3(lo), vec3(hi))
        self._drift = 0.0
        return self._aabb

    def bounds(self) -> tuple[Box, float] | None:
        """(box, d): every collider lies within ``box`` grown by ``d`` m on each side, without
        a query if the links moved since it was measured (each joint's travel times its lever:
        a rigid point turned by a rad at r m from the axis moves at most a * r; plus
        ``ROUNDING_M``); None when the arm has no such bound yet. The AABB of a collider is
        that of its local box's corners, rigid points, so it moves no farther than they do."""
        if self._aabb is not None:
            return self._aabb, 0.0
        if self._loose is None:
            return None
        return self._loose, self._drift + ROUNDING_M

    def _place_base(
        self, base_link: str, base_xyz: Sequence[float], base_yaw_deg: float, urdf: Path
    ) -> None:
        """Moves the body so that `base_link` (not necessarily the URDF's root: a robot may
        stand on a pedestal link) is at the base pose."""
        index = next((i for i, n in self.link_names.items() if n == base_link), None)
        if index is None:
            raise RobotModelError(f"robot {self.id}: {urdf} has no link named {base_link!r}")
        if index == BASE:
            return
        c = self._c
        X_WR = Pose(*map(tuple, p.getBasePositionAndOrientation(self.body, physicsClientId=c)))
        s = p.getLinkState(self.body, index, computeForwardKinematics=True, physicsClientId=c)
        X_RB = relative(X_WR, Pose(vec3(s[4]), cast(Quat, tuple(s[5]))))
        X_WB = Pose(vec3(base_xyz), yaw_quat_deg(base_yaw_deg))
        X_BR = relative(X_RB, Pose((0.0, 0.0, 0.0), IDENTITY))  # the inverse of X_RB
        X_WR_new = compose(X_WB, X_BR)
        p.resetBasePositionAndOrientation(
            self.body, list(X_WR_new.position), list(X_WR_new.orientation), physicsClientId=c
        )

    def tool_pose(self) -> Pose:
        """The TCP in the world: the tip link's frame composed with the scenario's tcp."""
        if self.tool == BASE:
            pos, quat = p.getBasePositionAndOrientation(self.body, physicsClientId=self._c)
            return compose(Pose(vec3(pos), cast(Quat, tuple(quat))), self.tcp)
        s = p.getLinkState(
            self.body, self.tool, computeForwardKinematics=True, physicsClientId=self._c
        )
        return compose(Pose(vec3(s[4]), cast(Quat, tuple(s[5]))), self.tcp)

    def link_name(self, index: int) -> str:
        return self.link_names.get(index, str(index))
