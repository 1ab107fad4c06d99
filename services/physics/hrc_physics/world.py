"""The pybullet world of one scenario (DIRECT mode) and what happens in it each tick.

Tick work (:meth:`World.step`, called with the participants' outputs of tick k):
1. the dynamics advance one fixed step (free parts fall, slide, come to rest);
2. robots and hands are posed from the latest RobotState / HumanState (kinematic);
3. world commands are applied in the order received (attach, release/snap, spawn, grabbable);
4. held parts follow their holder; open hands release, then closed hands grasp (GRIP_CLOSED);
the world is then the world of tick k + 1: :meth:`contact_events` and :meth:`object_states` read
it for `world/contacts` and `world/objects`.

Why one file of over 600 lines: the tick's steps above share one pybullet client and its body
ids; they read best in the order they run.
"""

from __future__ import annotations

import logging
import math
import re
from collections import Counter, deque
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import pybullet as p

from hrc import scenario as sc
from hrc.geometry import (
    Pose,
    Quat,
    Vec3,
    compose,
    distance,
    point_box_distance,
    pose_from_pb,
    pose_to_pb,
    quat_yaw_deg,
    relative,
    rpy_quat_deg,
    vec3,
    yaw_difference_deg,
    yaw_quat_deg,
)
from hrc.scenario.colors import part_color, unit_rgba
from hrc.scenario.conventions import (
    GRASP_DISTANCE_M,
    GRIP_CLOSED,
    HANDS,
    MAX_HELD_GRIP_CHANGES,
)
from hrc.scenario.layout import BUTTON_HEIGHT, BUTTON_RADIUS, FLOOR_Z, StaticBox, furniture
from hrc.scenario.models import DEFAULT_TICK_HZ, ID_PATTERN
from hrc.scenario.urdf import localized_urdf
from hrc.validate import check_pose
from hrc.wire import pb

from hrc_physics import objects as ob
from hrc_physics.closest import Box, nearest
from hrc_physics.contacts import ContactKey, ContactTracker, Touch
from hrc_physics.exchange import joint_reaches
from hrc_physics.hands import Hand, create_hand, pose_hand
from hrc_physics.objects import WorldObject
from hrc_physics.robots import Chain, KinematicRobot
from hrc_physics.separation import SeparationMonitor

log = logging.getLogger(__name__)

GRAVITY = -9.81
BUTTON_ID = "continue_button"
HAND_ROBOT, ROBOT_ROBOT = pb.CONTACT_KIND_HAND_ROBOT, pb.CONTACT_KIND_ROBOT_ROBOT
HAND_ENVELOPE, HAND_BUTTON = pb.CONTACT_KIND_HAND_ENVELOPE, pb.CONTACT_KIND_HAND_BUTTON
_ID_RE = re.compile(ID_PATTERN)


@dataclass
class WorldSettings:
    dt: float = 1.0 / DEFAULT_TICK_HZ
    solver_iterations: int = 50
    grasp_distance: float = GRASP_DISTANCE_M  # hand's grasp point to the object's surface


class CommandRejected(ValueError):
    """A world command that names something that does not exist or carries a bad value."""


class World:
    """The world of one scenario. Use as a context manager (it owns a pybullet client)."""

    def __init__(self, scenario: sc.Scenario, settings: WorldSettings | None = None) -> None:
        self.scenario = scenario
        self.settings = settings or WorldSettings()
        if not self.settings.dt > 0:
            raise ValueError(f"time step must be > 0, got {self.settings.dt}")
        self._human: pb.HumanState | None = None
        self._human_applied: pb.HumanState | None = None
        # States in which a grip crosses GRIP_CLOSED, each applied in a step of its own
        self._human_edges: deque[pb.HumanState] = deque(maxlen=MAX_HELD_GRIP_CHANGES)
        # Contacts involve only hands and arms: while neither moved, they are what they were.
        self._contacts_stale = True
        self.c = p.connect(p.DIRECT)
        try:
            self._build()
        except Exception:
            p.disconnect(physicsClientId=self.c)
            raise
        self.tracker = ContactTracker()
        # ssm only: the participant-robot separations (its own module; nothing for the others)
        self.separation: SeparationMonitor | None = None
        if scenario.conditions.safety_policy == sc.SafetyPolicy.SSM:
            ranges = {rid: scenario.ssm_of(rid).sensing_range_m for rid in self.robots}
            self.separation = SeparationMonitor(self.c, self.robots, self.hands, ranges)
        self.events: list[pb.ObjectEvent] = []
        self.rejected: Counter[str] = Counter()  # by object id (or "?" when none)
        self.steps = 0

    # ------------------------------------------------------------------ lifecycle
    def __enter__(self) -> World:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()

    def close(self) -> None:
        if self.c >= 0:
            p.disconnect(physicsClientId=self.c)
            self.c = -1

    # ------------------------------------------------------------------ building
    def _build(self) -> None:
        c, s = self.c, self.settings
        p.resetSimulation(physicsClientId=c)
        # Fixed step, fixed iterations, deterministic pair order: same inputs => same outputs.
        p.setPhysicsEngineParameter(
            fixedTimeStep=s.dt,
            numSolverIterations=s.solver_iterations,
            numSubSteps=0,
            deterministicOverlappingPairs=1,
            physicsClientId=c,
        )
        p.setGravity(0.0, 0.0, GRAVITY, physicsClientId=c)
        plane = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=c)
        self.floor = p.createMultiBody(0.0, plane, -1, [0.0, 0.0, FLOOR_Z], physicsClientId=c)
        self.furniture: dict[str, int] = {}
        supports = [self.floor]
        for box in furniture(self.scenario):
            self.furniture[box.name] = self._static_box(box)
            if box.collides:
                supports.append(self.furniture[box.name])
        self.button: int | None = None
        ws = self.scenario.workspace
        if ws.continue_button is not None:
            shape = p.createCollisionShape(
                p.GEOM_CYLINDER, radius=BUTTON_RADIUS, height=BUTTON_HEIGHT, physicsClientId=c
            )
            visual = p.createVisualShape(
                p.GEOM_CYLINDER,
                radius=BUTTON_RADIUS,
                length=BUTTON_HEIGHT,
                rgbaColor=[0.9, 0.1, 0.1, 1.0],
                physicsClientId=c,
            )
            self.button = p.createMultiBody(
                0.0, shape, visual, list(ws.continue_button), physicsClientId=c
            )
            p.setCollisionFilterGroupMask(self.button, -1, 0, 0, physicsClientId=c)
            self._button_box = p.getAABB(self.button, -1, physicsClientId=c)
        self.envelope: list[tuple[Vec3, Vec3]] = [(tuple(b.min), tuple(b.max)) for b in ws.envelope]  # type: ignore[misc]

        self.robots: dict[str, KinematicRobot] = {}
        for rid, robot in self.scenario.robots.items():
            urdf = self.scenario.urdf_path(rid) or Path(robot.urdf)
            self.robots[rid] = KinematicRobot(
                c,
                rid,
                localized_urdf(urdf, [Path(d) for d in robot.packages]),
                robot.base.xyz,
                robot.base.yaw,
                robot.near_margin,
                chain=Chain(
                    robot.base_link,
                    robot.tip_link,
                    Pose(vec3(robot.tcp.xyz), rpy_quat_deg(robot.tcp.rpy_deg)),
                ),
            )
        for r in self.robots.values():
            r.apply()  # zero pose until the first RobotState
            r.bound_motion(joint_reaches(r))
        ids = list(self.robots)
        self.robot_pairs = [
            (ids[i], ids[j]) for i in range(len(ids)) for j in range(i + 1, len(ids))
        ]

        self.hands: dict[str, Hand] = {name: create_hand(c, name) for name in HANDS}
        self.parts = {part.id: part for part in self.scenario.parts}
        self.objects: dict[str, WorldObject] = {}
        for part in self.scenario.parts:
            if part.start is not None:
                self._add_object(
                    part.id,
                    part.kind,
                    part.owner,
                    vec3(part.size),
                    vec3(part.start.xyz),
                    yaw_quat_deg(part.start.yaw),
                )
        # Parts that start lying on something start asleep: they are at rest, and the first
        # steps' gravity-versus-contact jitter is nothing to report. The others fall.
        for obj in self.objects.values():
            others = supports + [o.body for o in self.objects.values() if o is not obj]
            if any(_rests_on(c, obj.body, other) for other in others):
                ob.sleep(c, obj)

    def _static_box(self, box: StaticBox) -> int:
        c = self.c
        shape = -1
        if box.collides:
            shape = p.createCollisionShape(
                p.GEOM_BOX, halfExtents=list(box.half), physicsClientId=c
            )
        visual = p.createVisualShape(
            p.GEOM_BOX, halfExtents=list(box.half), rgbaColor=list(box.rgba), physicsClientId=c
        )
        body = p.createMultiBody(
            0.0, shape, visual, list(box.center), yaw_quat_deg(box.yaw_deg), physicsClientId=c
        )
        if box.collides:
            p.changeDynamics(
                body, -1, lateralFriction=ob.FRICTION, restitution=0.0, physicsClientId=c
            )
        return body

    def _add_object(
        self, oid: str, kind: str, owner: str, size: Vec3, pos: Vec3, rot: Quat
    ) -> WorldObject:
        mass = ob.mass_of(size)
        robot_colors = {rid: r.color_or_default for rid, r in self.scenario.robots.items()}
        color = unit_rgba(part_color(owner, robot_colors))
        body = ob.create_box(self.c, size, pos, rot, mass, color)
        part = self.parts.get(oid)
        target = (tuple(part.target.xyz), part.target.yaw) if part is not None else None
        obj = WorldObject(
            oid,
            kind,
            owner,
            size,
            mass,
            body,
            target,  # type: ignore[arg-type]
            pose=Pose(pos, rot),
        )
        self.objects[oid] = obj
        return obj

    # ------------------------------------------------------------------ inputs
    def set_robot_state(self, robot_id: str, names: list[str], positions: list[float]) -> None:
        """Records a robot's joints (applied in the next step). Raises CommandRejected."""
        robot = self.robots.get(robot_id)
        if robot is None:
            raise CommandRejected(f"robot state for unknown robot {robot_id!r}")
        problem = robot.set_state(names, positions)
        if problem:
            raise CommandRejected(problem)

    def set_human(self, msg: pb.HumanState) -> None:
        """Records the hands' poses and grips (applied in the next step). The latest wins, but
        a state that opens or closes a grip is applied in a step before any later one: in
        realtime two states can arrive between two steps, and a release followed at once by
        the hand moving away must let go of the part where it was released."""
        last = self._human_edges[-1] if self._human_edges else self._human
        if last is not None and _grips(last) != _grips(msg):
            self._human_edges.append(msg)
        self._human = msg

    # ------------------------------------------------------------------ the tick
    def step(self, commands: list[pb.WorldCommand] | None = None) -> list[str]:
        """Advances to the next tick (see the module doc).

        Returns the rejected commands' reasons.
        """
        c = self.c
        p.stepSimulation(physicsClientId=c)
        self.steps += 1
        for robot in self.robots.values():
            robot.stepped()
        self._track_motion()
        for robot in self.robots.values():
            if robot.apply():
                self._contacts_stale = True
        human = self._human_edges.popleft() if self._human_edges else self._human
        if human is not None and human is not self._human_applied:
            # A participant at rest sends no new state (states come on change): same message,
            # nothing to do.
            h = self._human_applied = human
            if self.separation is not None:
                self.separation.pose_head(h.head)
            for hand, pose, grip in (
                (self.hands["left"], h.left_hand, h.left_grip),
                (self.hands["right"], h.right_hand, h.right_grip),
            ):
                pos, rot = pose_from_pb(pose, unit=True)
                if pose_hand(c, hand, pos, rot, grip):
                    self._contacts_stale = True
        if self.separation is not None and self._contacts_stale:
            self.separation.mark_moved()  # a hand or an arm moved
        problems: list[str] = []
        for cmd in commands or ():
            try:
                self.apply(cmd)
            except CommandRejected as exc:
                problems.append(str(exc))
        self._follow_holders()
        self._hand_grips()
        return problems

    def _track_motion(self) -> None:
        """Watches awake free objects: moving or still; once still for REST_S they sleep (and a
        released one reports RESTED). While anything is awake or held, sleeping objects are
        checked too, since a body that hits them wakes them."""
        c = self.c
        need = max(1, round(ob.REST_S / self.settings.dt))
        busy = any(o.awake or o.held_by for o in self.objects.values())
        if not busy:
            return
        for obj in self.objects.values():
            if obj.frozen:
                continue
            lin, ang = p.getBaseVelocity(obj.body, physicsClientId=c)
            still = (
                lin[0] ** 2 + lin[1] ** 2 + lin[2] ** 2 < ob.STILL_SPEED**2
                and ang[0] ** 2 + ang[1] ** 2 + ang[2] ** 2 < ob.STILL_SPIN**2
            )
            if not obj.awake:
                if still:
                    continue
                obj.awake, obj.still_ticks = True, 0  # pushed by something
            obj.pose = _base_pose(c, obj.body)
            if not still:
                obj.still_ticks = 0
                if not obj.moving:
                    obj.moving = obj.dirty = True
                continue
            obj.still_ticks += 1
            if obj.still_ticks >= need:
                ob.sleep(c, obj)
                if obj.moving:
                    obj.moving, obj.dirty = False, True
                if obj.settling:
                    obj.settling = False
                    self._event(pb.ObjectEvent.KIND_RESTED, obj, obj.last_holder)

    # ------------------------------------------------------------------ commands
    def apply(self, cmd: pb.WorldCommand) -> None:
        """Applies one world command now. Raises CommandRejected naming the object."""
        which = cmd.WhichOneof("command")
        if which == "attach":
            self._attach(cmd.attach)
        elif which == "release":
            self._release_cmd(cmd.release)
        elif which == "spawn":
            self._spawn(cmd.spawn)
        elif which == "set_grabbable":
            obj = self._object(cmd.set_grabbable.object, "set_grabbable")
            if obj.grabbable != cmd.set_grabbable.grabbable:
                obj.grabbable = cmd.set_grabbable.grabbable
                obj.dirty = True
        else:
            self._reject("?", "empty world command (no attach/release/spawn/set_grabbable)")

    def _reject(self, oid: str, why: str) -> None:
        self.rejected[oid or "?"] += 1
        raise CommandRejected(why)

    def _object(self, oid: str, what: str) -> WorldObject:
        obj = self.objects.get(oid)
        if obj is None:
            if oid in self.parts:
                self._reject(oid, f"{what}: object {oid!r} has not been spawned yet")
            self._reject(oid, f"{what}: unknown object {oid!r}")
        return obj  # type: ignore[return-value]

    def _attach(self, cmd: pb.Attach) -> None:
        obj = self._object(cmd.object, "attach")
        robot = self.robots.get(cmd.holder)
        if robot is None:
            self._reject(
                cmd.object,
                f"attach {cmd.object!r}: holder {cmd.holder!r} is not a robot "
                f"(robots: {', '.join(self.robots)})",
            )
            return
        if obj.held_by:
            self._detach(obj)
        _, rel_rot = relative(robot.tool_pose(), obj.pose)
        # Convention: the part hangs below the TCP, its top-face centre at the tool tip; the
        # tool's z axis points down, so the centre is sz / 2 along tool z.
        self._hold(obj, cmd.holder, Pose((0.0, 0.0, obj.size[2] / 2), rel_rot))

    def _release_cmd(self, cmd: pb.Release) -> None:
        obj = self._object(cmd.object, "release")
        if cmd.snap:
            if not cmd.HasField("pose"):
                self._reject(cmd.object, f"release {cmd.object!r}: snap without a pose")
            problem = check_pose(cmd.pose)
            if problem:
                self._reject(cmd.object, f"release {cmd.object!r}: {problem}")
            holder = obj.held_by or obj.last_holder
            if obj.held_by:
                self._detach(obj)
            pos, rot = pose_from_pb(cmd.pose, unit=True)
            ob.set_frozen(self.c, obj, True)
            ob.place(self.c, obj, pos, rot)
            obj.placed, obj.moving, obj.settling, obj.dirty = True, False, False, True
            self._event(pb.ObjectEvent.KIND_SNAPPED, obj, holder)
            return
        if not obj.held_by:
            self._reject(cmd.object, f"release {cmd.object!r}: it is not held")
        self._let_go(obj)

    def _spawn(self, cmd: pb.Spawn) -> None:
        oid = cmd.object
        if not _ID_RE.match(oid):
            self._reject(oid, f"spawn: invalid object id {oid!r}")
        if oid in self.objects:
            self._reject(oid, f"spawn: object {oid!r} already exists")
        size = (cmd.size.x, cmd.size.y, cmd.size.z)
        if not all(math.isfinite(v) and 0.0 < v <= 2.0 for v in size):
            self._reject(oid, f"spawn {oid!r}: size {size} must be finite, > 0 and <= 2 m")
        problem = check_pose(cmd.pose)
        if problem:
            self._reject(oid, f"spawn {oid!r}: {problem}")
        pos, rot = pose_from_pb(cmd.pose, unit=True)
        obj = self._add_object(oid, cmd.kind or "part", cmd.owner, size, pos, rot)
        self._event(pb.ObjectEvent.KIND_SPAWNED, obj, cmd.owner)

    # ------------------------------------------------------------------ holding
    def _hold(self, obj: WorldObject, holder: str, offset: Pose) -> None:
        ob.set_frozen(self.c, obj, True)  # kinematic while held
        obj.held_by, obj.hold_offset = holder, offset
        obj.placed, obj.moving, obj.settling, obj.dirty = False, False, False, True
        obj.last_holder = holder
        if holder in self.hands:
            self.hands[holder].holding = obj.id
        self._follow(obj)
        self._event(pb.ObjectEvent.KIND_GRABBED, obj, holder)

    def _detach(self, obj: WorldObject) -> None:
        hand = self.hands.get(obj.held_by)
        if hand is not None and hand.holding == obj.id:
            hand.holding = ""
        obj.held_by = ""
        obj.dirty = True

    def _let_go(self, obj: WorldObject) -> None:
        """Free fall from where the holder left it; RELEASED now, RESTED when it settles."""
        holder = obj.held_by
        self._detach(obj)
        ob.set_frozen(self.c, obj, False)
        obj.placed, obj.moving, obj.settling, obj.still_ticks = False, True, True, 0
        self._event(pb.ObjectEvent.KIND_RELEASED, obj, holder)

    def _holder_pose(self, holder: str) -> Pose:
        hand = self.hands.get(holder)
        if hand is not None:
            return Pose(hand.pos, hand.rot)
        return self.robots[holder].tool_pose()

    def _follow(self, obj: WorldObject) -> None:
        pos, rot = compose(self._holder_pose(obj.held_by), obj.hold_offset)
        if (pos, rot) != obj.pose:
            ob.place(self.c, obj, pos, rot)

    def _follow_holders(self) -> None:
        for obj in self.objects.values():
            if obj.held_by:
                self._follow(obj)

    def _hand_grips(self) -> None:
        """Releases first (grip below GRIP_CLOSED), then grasps; left before right."""
        for hand in self.hands.values():
            if hand.holding and hand.grip < GRIP_CLOSED:
                self._let_go(self.objects[hand.holding])
        for hand in self.hands.values():
            if not hand.active or hand.holding or hand.grip < GRIP_CLOSED:
                continue
            best: tuple[float, WorldObject] | None = None
            for obj in self.objects.values():
                if not obj.grabbable or obj.held_by or obj.placed:  # placed parts are done
                    continue
                d = point_box_distance(hand.pos, obj.pose, obj.half)
                if d <= self.settings.grasp_distance and (best is None or d < best[0]):
                    best = (d, obj)
            if best is not None:
                obj = best[1]
                self._hold(obj, hand.name, relative(Pose(hand.pos, hand.rot), obj.pose))

    # ------------------------------------------------------------------ outputs
    def _event(self, kind: pb.ObjectEvent.Kind.ValueType, obj: WorldObject, holder: str) -> None:
        pos, rot = obj.pose
        ev = pb.ObjectEvent(
            kind=kind,
            object=obj.id,
            holder=holder,
            pose=pose_to_pb(obj.pose),
        )
        if obj.target is not None:
            ev.target_distance_m = distance(pos, obj.target[0])
            ev.target_angle_deg = yaw_difference_deg(quat_yaw_deg(rot), obj.target[1])
        self.events.append(ev)

    def take_events(self) -> list[pb.ObjectEvent]:
        events, self.events = self.events, []
        return events

    def object_states(self, full: bool = False) -> list[pb.ObjectState]:
        """Every object (``full``) or those that moved or changed since the last call."""
        out: list[pb.ObjectState] = []
        for obj in self.objects.values():
            moving = obj.moving or bool(obj.held_by)
            if full or obj.dirty or moving:
                out.append(
                    pb.ObjectState(
                        id=obj.id,
                        pose=pose_to_pb(obj.pose),
                        held_by=obj.held_by,
                        grabbable=obj.grabbable,
                        placed=obj.placed,
                        moving=moving,
                    )
                )
                obj.dirty = False
        return out

    def current_contacts(self) -> dict[ContactKey, Touch]:
        """Every contact present now (the tracker turns them into begin / end events)."""
        c = self.c
        out: dict[ContactKey, Touch] = {}
        hands = [h for h in self.hands.values() if h.active]
        hand_boxes = {h.name: p.getAABB(h.body, -1, physicsClientId=c) for h in hands}
        # An arm's AABB costs a query per link: an arm that cannot have come near since its
        # last one was measured is skipped without it (the result is the same).
        for hand in hands:
            hand_box = hand_boxes[hand.name]
            for rid, robot in self.robots.items():
                if not _may_overlap((hand_box, 0.0), robot.bounds(), 0.0):
                    continue
                if not _overlap(hand_box, robot.aabb(), 0.0):
                    continue
                hand_links = [(-1, hand_box)]
                deepest = nearest(c, hand.body, hand_links, robot.body, robot.link_boxes(), 0.0)
                if deepest is not None and deepest[8] <= 0.0:
                    out[ContactKey(HAND_ROBOT, hand.name, rid)] = Touch(
                        robot.link_name(deepest[4]), tuple(deepest[6]), deepest[8]
                    )
        for ra, rb in self.robot_pairs:
            a, b = self.robots[ra], self.robots[rb]
            # Each arm's volume is its link colliders inflated by its own margin: the two
            # volumes touch when the links are no farther apart than the sum of the margins.
            reach = a.near_margin + b.near_margin
            if not _may_overlap(a.bounds(), b.bounds(), reach):
                continue
            if not _overlap(a.aabb(), b.aabb(), reach):
                continue
            near = nearest(c, a.body, a.link_boxes(), b.body, b.link_boxes(), reach)
            if near is not None and near[8] <= reach:
                mid = vec3([0.5 * (u + v) for u, v in zip(near[5], near[6], strict=True)])
                out[ContactKey(ROBOT_ROBOT, ra, rb)] = Touch(
                    f"{a.link_name(near[3])}/{b.link_name(near[4])}", mid, near[8]
                )
        for hand in hands:
            x, y, z = hand.pos
            for i, (lo, hi) in enumerate(self.envelope):
                if lo[0] <= x <= hi[0] and lo[1] <= y <= hi[1] and lo[2] <= z <= hi[2]:
                    out[ContactKey(HAND_ENVELOPE, hand.name, str(i))] = Touch(point=hand.pos)
            if self.button is not None and _overlap(hand_boxes[hand.name], self._button_box, 0.0):
                touch = [
                    pt
                    for pt in p.getClosestPoints(hand.body, self.button, 0.0, physicsClientId=c)
                    if pt[8] <= 0.0
                ]
                if touch:
                    out[ContactKey(HAND_BUTTON, hand.name, BUTTON_ID)] = Touch(
                        "", tuple(touch[0][6]), min(pt[8] for pt in touch)
                    )
        return out

    def button_bounds(self) -> tuple[int, Box] | None:
        """The continue button's body and world AABB (None without a button)."""
        return None if self.button is None else (self.button, self._button_box)

    def contact_events(self) -> list[pb.Contact]:
        """Begin / end events of the contacts since the last call."""
        if not self._contacts_stale:
            return []
        self._contacts_stale = False
        return self.tracker.update(self.current_contacts())

    def separations(self) -> list[pb.Separation] | None:
        """ssm: the separations when they changed since the last call (else None)."""
        return self.separation.update() if self.separation is not None else None

    # ------------------------------------------------------------------ inspection
    def tool_pose(self, robot_id: str) -> Pose:
        return self.robots[robot_id].tool_pose()


def _rests_on(client: int, body: int, support: int, gap: float = 0.002) -> bool:
    """Is ``body`` within ``gap`` above ``support``, touching it from above?"""
    for pt in p.getClosestPoints(body, support, gap, physicsClientId=client):
        # contact normal points from B (support) to A (body): up means it lies on top
        if (pt[7][2] < -0.9 or pt[7][2] > 0.9) and pt[5][2] >= pt[6][2] - 1e-6:
            return True
    return False


def _may_overlap(a: tuple[Box, float] | None, b: tuple[Box, float] | None, margin: float) -> bool:
    """Can two AABBs, each known as (box, d: grown by up to d m; KinematicRobot.bounds), come
    within ``margin`` of each other? Always where a bound is unknown (None)."""
    if a is None or b is None:
        return True
    return _overlap(a[0], b[0], margin + a[1] + b[1])


def _overlap(a: tuple, b: tuple, margin: float) -> bool:
    """Do two AABBs ((lo), (hi)) come within ``margin`` of each other (per axis)?"""
    (alo, ahi), (blo, bhi) = a, b
    return (
        alo[0] <= bhi[0] + margin
        and blo[0] <= ahi[0] + margin
        and alo[1] <= bhi[1] + margin
        and blo[1] <= ahi[1] + margin
        and alo[2] <= bhi[2] + margin
        and blo[2] <= ahi[2] + margin
    )


def _base_pose(client: int, body: int) -> Pose:
    pos, rot = p.getBasePositionAndOrientation(body, physicsClientId=client)
    return Pose(vec3(pos), cast(Quat, tuple(rot)))


def _grips(msg: pb.HumanState) -> tuple[bool, bool]:
    """Which hands are closed (holding) in a state."""
    return (msg.left_grip >= GRIP_CLOSED, msg.right_grip >= GRIP_CLOSED)
