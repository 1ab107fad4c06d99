"""The exchange step: how many ticks the next exchange may cover (docs/ARCHITECTURE.md,
"Exchange step").

Inside an exchange of n ticks every participant computes from the inputs it held at its start, so
a contact that began inside it would be acted on only at its end. What the participants know in
advance they declare (TickAck.next_event_tick; hrc.bus.clock.DeclaredEvents caps the span); what
nobody can announce is kept out of long exchanges here, from the gaps and speed bounds:

- a hand-robot contact must be acted on within one thesis frame, so an exchange of n > 1 ticks is
  allowed only where no hand can touch an arm before it ends: the gap between each active hand
  and each arm is larger than what the two can close in n ticks at their speed bounds,
  gap > n * dt * (hand_speed_bound + arm_speed_bound);
- a robot-robot near-collision (the inflated volumes touch: gap <= the sum of the margins) must
  begin and end where it would with one-tick exchanges: |gap - margins| > n * dt * (bound_a +
  bound_b).

A contact can then only begin in an exchange of one tick or at an exchange boundary, exactly as
without exchanges. The gap and the bounds are simulated quantities, so the step sizes are the
same on every run.

Speed bounds: an arm's from its URDF joint velocity limits (every point of it moves at most
sum_j |qdot_j| * r_j, r_j the farthest any collider beyond joint j can be from it), each joint's
term scaled by what the arm's motion source declares for the coming ticks
(RobotState.joint_speed_fraction_bounds: joint j no faster than f_j of its limit until a new
command reaches the arm; all 0 at rest): sum_j f_j * v_j * r_j. Where the source also declares
how fast each joint's child link moves and turns (RobotState.link_linear_speed_bounds,
link_angular_speed_bounds: what its planned poses do), each collider's bound is that of the
nearest such link above it, v + w * r (r from that link's frame origin to the collider's
farthest point), plus the terms of the joints between (a gripper's fingers); the arm's is the
largest over its colliders, if lower than the sum (a sum of every joint at its own peak, 3-5
times the arm's real speed). An arm commanded in the exchange just ended, or without a
declaration, counts with its full bound. The hand's is what its source declares
(HumanState.hand_speed_bound), else :data:`HAND_SPEED_BOUND`.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import pybullet as p

from hrc.scenario.models import DEFAULT_MAX_EXCHANGE_TICKS

from hrc_physics.closest import Box, box_gap, nearest
from hrc_physics.hands import Hand
from hrc_physics.robots import KinematicRobot

# m/s: the scenario's upper limit of ``peak_hand_speed`` (hrc.scenario.models), assumed for a
# hand source that declares no bound of its own (HumanState.hand_speed_bound = 0: live VR).
HAND_SPEED_BOUND = 5.0


def _aabb_radius(origin: tuple[float, ...], box: tuple[tuple[float, ...], ...]) -> float:
    """The largest distance from ``origin`` to a corner of the box (covers the collider)."""
    lo, hi = box
    return math.sqrt(
        sum(max(abs(lo[i] - origin[i]), abs(hi[i] - origin[i])) ** 2 for i in range(3))
    )


@dataclass(frozen=True)
class _ArmAtStart:
    """What the speed bounds read of an arm, in its pose at start: each joint's pybullet info,
    each link's parent, each link frame's origin (-1: the base), each collider's AABB."""

    info: list[tuple[Any, ...]]
    parent: dict[int, int]
    origin: dict[int, tuple[float, ...]]
    boxes: dict[int, tuple[Any, ...]]  # link -> AABB, links with a collider

    @classmethod
    def of(cls, robot: KinematicRobot) -> _ArmAtStart:
        c, body = robot._c, robot.body
        n = p.getNumJoints(body, physicsClientId=c)
        info = [p.getJointInfo(body, j, physicsClientId=c) for j in range(n)]
        origin: dict[int, tuple[float, ...]] = {
            -1: tuple(p.getBasePositionAndOrientation(body, c)[0])
        }
        for j in range(n):
            origin[j] = tuple(p.getLinkState(body, j, physicsClientId=c)[4])
        boxes = {
            link: p.getAABB(body, link, physicsClientId=c)
            for link in range(n)
            if p.getCollisionShapeData(body, link, physicsClientId=c)
        }
        return cls(info, {j: info[j][16] for j in range(n)}, origin, boxes)

    def v_max(self, j: int) -> float:
        """Joint j's URDF velocity limit (rad/s, m/s when prismatic); 2 pi where none."""
        v = self.info[j][11]
        return float(v) if v > 0 else 2 * math.pi


def joint_reaches(robot: KinematicRobot) -> dict[str, tuple[float, bool]]:
    """Per movable joint j: (r_j in m, prismatic). Turning joint j by d rad moves no point of the
    colliders beyond it by more than d * r_j; sliding it by d m moves them by d.

    Each link's reach from joint j is bounded by the chain of joint offsets from j to the link
    plus the link's own radius (link frame to its collider's AABB corners), so it holds in any
    pose.
    """
    arm = _ArmAtStart.of(robot)
    info, parent, origin = arm.info, arm.parent, arm.origin
    n = len(info)
    movable = [j for j in range(n) if info[j][2] != p.JOINT_FIXED]
    radius = {
        link: _aabb_radius(origin[link], arm.boxes[link]) if link in arm.boxes else 0.0
        for link in range(n)
    }
    offset = {j: math.dist(origin[j], origin[parent[j]]) for j in range(n)}
    out: dict[str, tuple[float, bool]] = {}
    for j in movable:
        reach = 0.0
        for link in range(n):
            # path length from joint j down to link (link must lie below j)
            length, at = 0.0, link
            while at != j and at != -1:
                length += offset[at]
                at = parent[at]
            if at == j:
                reach = max(reach, length + radius[link])
        out[info[j][1].decode()] = (reach, info[j][2] == p.JOINT_PRISMATIC)
    return out


def arm_speed_terms(robot: KinematicRobot) -> dict[str, float]:
    """Per movable joint j, v_j * r_j in m/s: the speed it alone can give any point of the arm's
    colliders (the arm's bound is their sum, at most sum_j |qdot_j| * r_j, r_j from
    :func:`joint_reaches`); v_j for a prismatic joint. A joint without a velocity limit counts
    as 2 pi rad/s.
    """
    arm = _ArmAtStart.of(robot)
    v_max = {arm.info[j][1].decode(): arm.v_max(j) for j in range(len(arm.info))}
    # a sliding joint (a gripper's finger) moves every point below it at its own speed
    return {
        name: v_max[name] if prismatic else v_max[name] * reach
        for name, (reach, prismatic) in joint_reaches(robot).items()
    }


@dataclass(frozen=True)
class Lever:
    """A movable joint above a collider: any point of the collider lies within ``reach_m`` of
    the joint's child-link frame origin (which lies on the joint's axis), in any pose."""

    joint: str
    v_max: float  # rad/s (m/s when prismatic): its URDF limit, 2 pi rad/s where none
    prismatic: bool
    reach_m: float

    def term(self) -> float:
        """m/s: the most the joint alone moves a point of the collider, at its limit."""
        return self.v_max if self.prismatic else self.v_max * self.reach_m


def arm_levers(robot: KinematicRobot) -> list[tuple[Lever, ...]]:
    """Per link with a collider: its movable joints, nearest first (see :class:`Lever`). The
    nearest one's reach is the collider's farthest AABB corner from its frame (the two move as
    one); a farther one's is the path of link offsets down to it plus that radius, each sliding
    joint on the way adding its travel."""
    arm = _ArmAtStart.of(robot)
    info, parent, origin = arm.info, arm.parent, arm.origin
    out: list[tuple[Lever, ...]] = []
    for link, box in arm.boxes.items():
        radius = _aabb_radius(origin[link], box)
        levers: list[Lever] = []
        path, at = 0.0, link
        while at != -1:
            kind = info[at][2]
            if kind != p.JOINT_FIXED:
                prismatic = kind == p.JOINT_PRISMATIC
                reach = _aabb_radius(origin[at], box) if not levers else path + radius
                levers.append(Lever(info[at][1].decode(), arm.v_max(at), prismatic, reach))
            path += math.dist(origin[at], origin[parent[at]])
            if kind == p.JOINT_PRISMATIC:
                path += abs(info[at][9] - info[at][8])  # its travel: the offset varies by it
            at = parent[at]
        out.append(tuple(levers))
    return out


def link_speed_bound(
    levers: list[tuple[Lever, ...]],
    links: dict[str, tuple[float, float]],
    fractions: dict[str, float],
) -> float:
    """m/s no collider exceeds: per collider, the nearest joint whose child link's speeds are
    declared (``links``: joint -> (m/s, rad/s)) gives v + w * reach, the joints below it their
    terms scaled by their declared fractions (1 where none)."""
    bound = 0.0
    for chain in levers:
        extra = 0.0
        for lever in chain:
            speeds = links.get(lever.joint)
            if speeds is not None:
                extra += speeds[0] + speeds[1] * lever.reach_m
                break
            extra += fractions.get(lever.joint, 1.0) * lever.term()
        bound = max(bound, extra)
    return bound


@dataclass
class SpanPlanner:
    """Chooses each exchange's span from the world's gaps: hand-arm and arm-arm (their inflated
    volumes)."""

    dt: float
    arm_terms: dict[str, dict[str, float]]  # robot id -> joint -> m/s (arm_speed_terms)
    max_span: int = DEFAULT_MAX_EXCHANGE_TICKS
    hand_bound: float = HAND_SPEED_BOUND
    # robot pairs whose inflated volumes touch at a gap <= the margin (near-collisions)
    arm_pairs: list[tuple[str, str, float]] = field(default_factory=list)
    # robot id -> its colliders' levers (arm_levers), for declared link speeds
    arm_levers: dict[str, list[tuple[Lever, ...]]] = field(default_factory=dict)
    # the continue button's body and world AABB where a press is acted on (retreat_button):
    # a press may then begin only where an exchange ends, as a hand-arm contact; only while
    # ``button_armed`` (from a hand-arm contact to the next press: the button may be wanted)
    button: tuple[int, Box] | None = None
    button_armed: bool = False

    def __post_init__(self) -> None:
        self.histogram: Counter[int] = Counter()  # exchanges planned, by span
        # robot id -> m/s: the full bound from the URDF
        self.arm_bounds: dict[str, float] = {
            rid: sum(t.values()) for rid, t in self.arm_terms.items()
        }
        # robot id -> its latest declaration (joints, fractions, window ticks, link m/s, link
        # rad/s); read only when a span is planned, once per exchange, though a moving arm's
        # states come every tick
        self._declared: dict[
            str, tuple[Sequence[str], Sequence[float], int, Sequence[float], Sequence[float]]
        ] = {}
        self._commanded: set[str] = set()  # arms commanded since the last span was planned

    def declare(
        self,
        robot: str,
        joints: Sequence[str],
        fractions: Sequence[float],
        window: int = 0,
        link_linear: Sequence[float] = (),
        link_angular: Sequence[float] = (),
    ) -> None:
        """The robot's latest state declares these joint speed fractions for the next
        ``window`` ticks (0: all; empty fractions: nothing declared); a joint it does not name
        counts in full. ``link_linear`` and ``link_angular``: its first joints' child links'
        speeds on the same ticks (m/s, rad/s), if declared."""
        if robot not in self.arm_terms:
            return
        if not fractions:
            self._declared.pop(robot, None)
            return
        self._declared[robot] = (joints, fractions, window, link_linear, link_angular)

    def commanded(self, robot: str) -> None:
        """A command for ``robot`` was sent: its source applies it at the next exchange's first
        tick, so its declaration does not hold there."""
        self._commanded.add(robot)

    def bound(self, robot: str) -> tuple[float, int]:
        """m/s no point of the arm exceeds during the next exchange, if it is at most so many
        ticks long (0: any)."""
        declared = self._declared.get(robot)
        if declared is None or robot in self._commanded:
            return self.arm_bounds[robot], 0
        joints, fractions, window, linear, angular = declared
        given = dict(zip(joints, fractions, strict=True))
        terms = self.arm_terms[robot]
        bound = sum(term * given.get(j, 1.0) for j, term in terms.items())
        levers = self.arm_levers.get(robot)
        if linear and levers:
            links = {j: (v, w) for j, v, w in zip(joints, linear, angular, strict=False)}
            bound = min(bound, link_speed_bound(levers, links, given))
        return bound, window

    def span(
        self,
        client: int,
        hands: list[Hand],
        robots: dict[str, KinematicRobot],
        limit: int | None = None,
    ) -> int:
        """The span of the next exchange: at most ``limit`` (the declared events' cap, default
        ``max_span``) and what the gaps allow."""
        n = min(self.max_span, self.max_span if limit is None else limit)
        if n > 1:
            bounds: dict[str, float] = {}
            for rid in robots:
                bounds[rid], window = self.bound(rid)
                if window:
                    n = min(n, window)
            n = self._hands(client, hands, robots, bounds, n)
            n = self._arms(client, robots, bounds, n)
            n = self._button(client, hands, n)
        self._commanded.clear()
        n = max(1, n)
        self.histogram[n] += 1
        return n

    def _hands(
        self,
        client: int,
        hands: list[Hand],
        robots: dict[str, KinematicRobot],
        bounds: dict[str, float],
        n: int,
    ) -> int:
        for hand in hands:
            if n <= 1:
                return 1
            if not hand.active:
                continue
            hand_box = p.getAABB(hand.body, -1, physicsClientId=client)
            for rid, robot in robots.items():
                per_tick = self.dt * (self.hand_bound + bounds[rid])
                need = n * per_tick  # the gap a span of n needs
                if _apart((hand_box, 0.0), robot.bounds(), need):
                    continue  # the boxes are farther apart than that: so are the bodies
                if box_gap(hand_box, robot.aabb()) > need:
                    continue
                pt = nearest(
                    client, hand.body, [(-1, hand_box)], robot.body, robot.link_boxes(), need
                )
                if pt is None:
                    continue  # farther apart than need
                n = _fit(n, pt[8], per_tick)
                if n == 1:
                    return 1
        return n

    def _button(self, client: int, hands: list[Hand], n: int) -> int:
        """Hand-button gaps: the button stands still, so only the hand closes them. Only a
        press (a contact's begin) is acted on, so a hand already on the button sets no bound:
        its press has begun (were it to leave and press again within the exchange, that second
        press would be seen at the exchange's end; the scripted participant never does)."""
        if self.button is None or not self.button_armed:
            return n
        body, box = self.button
        per_tick = self.dt * self.hand_bound
        for hand in hands:
            if n <= 1:
                return 1
            if not hand.active:
                continue
            hand_box = p.getAABB(hand.body, -1, physicsClientId=client)
            need = n * per_tick
            if box_gap(hand_box, box) > need:
                continue
            pt = nearest(client, hand.body, [(-1, hand_box)], body, [(-1, box)], need)
            if pt is not None and pt[8] > 0.0:
                n = _fit(n, pt[8], per_tick)
        return n

    def _arms(
        self,
        client: int,
        robots: dict[str, KinematicRobot],
        bounds: dict[str, float],
        n: int,
    ) -> int:
        """Two arms' inflated volumes touch at a gap <= margin: a near-collision can only begin
        (or end) where the gap can cross the margin within the exchange."""
        for ra, rb, margin in self.arm_pairs:
            if n <= 1:
                return 1
            per_tick = self.dt * (bounds[ra] + bounds[rb])
            need = n * per_tick
            a, b = robots[ra], robots[rb]
            if _apart(a.bounds(), b.bounds(), margin + need):
                continue
            if box_gap(a.aabb(), b.aabb()) > margin + need:
                continue
            pt = nearest(client, a.body, a.link_boxes(), b.body, b.link_boxes(), margin + need)
            if pt is None:
                continue  # farther apart than margin + need
            n = _fit(n, abs(pt[8] - margin), per_tick)
        return n


def _apart(a: tuple[Box, float] | None, b: tuple[Box, float] | None, gap: float) -> bool:
    """Are two boxes, each known as (box, d: grown by up to d m on each side;
    KinematicRobot.bounds), surely more than ``gap`` apart? Never where a bound is unknown."""
    if a is None or b is None:
        return False
    return box_gap(_grown(a), _grown(b)) > gap


def _grown(known: tuple[Box, float]) -> Box:
    (lo, hi), d = known
    return (lo[0] - d, lo[1] - d, lo[2] - d), (hi[0] + d, hi[1] + d, hi[2] + d)


def _fit(n: int, gap: float, per_tick: float) -> int:
    """The largest span <= n with span * per_tick < gap (at least 1)."""
    if per_tick <= 0 or n * per_tick < gap:
        return n
    return max(1, min(n, math.ceil(gap / per_tick) - 1))
