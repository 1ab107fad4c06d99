"""A minimal stand-in for physics and the orchestrator, seen from the participant's side.

It runs the scripted participant in-process, tick by tick, feeding its TaskView the same wire
messages the bus would (world/objects, task/indicators, task/events, robot/<id>/state,
world/contacts), following the task conventions (hrc.scenario.conventions): a grabbable object
is attached to a closed hand (grip >= GRIP_CLOSED) within GRASP_DISTANCE_M of its centre (physics
measures to its surface); an open hand releases it; a release within the placement tolerance
snaps onto the target, otherwise the part rests where it was let go. Robots do not move arms here:
each robot part is "placed" a fixed delay after its dependencies, and a robot TCP can be parked
anywhere. A test double for the participant's unit tests (and for tuning parameters offline); the
real run is always the five services.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from hrc.geometry import (
    Pose,
    Vec3,
    add,
    distance,
    pose_to_pb,
    quat_yaw_rad,
    rotate_z_rad,
    sub,
    vec3_to_pb,
    wrap_angle_rad,
    yaw_quat_rad,
)
from hrc.participant.sample import Sample
from hrc.scenario.conventions import (
    GRASP_DISTANCE_M,
    GRIP_CLOSED,
    HANDS,
    outline_cue_id,
    target_cue_id,
)
from hrc.scenario.models import DEFAULT_TOLERANCE_DEG, HUMAN
from hrc.wire import pb

from hrc_human_input.facts import ScenarioFacts
from hrc_human_input.scripted import ScriptedParticipant
from hrc_human_input.task_view import TaskView


@dataclass
class SimObject:
    id: str
    pos: Vec3
    yaw_rad: float
    held_by: str = ""
    grabbable: bool = False
    placed: bool = False
    grab_rel: tuple[Vec3, float] | None = None  # (object - hand, object - hand yaw_rad)


@dataclass
class MiniWorld:
    facts: ScenarioFacts
    participant: ScriptedParticipant
    robot_delay_s: float = 2.0  # a robot part is placed this long after it may be
    collision_radius: float = 0.05  # hand this close to a robot TCP: collision
    continue_after_s: float = 2.0  # COLLISION -> CONTINUED
    tcp: dict[str, Vec3] = field(default_factory=dict)
    view: TaskView = field(init=False)
    objects: dict[str, SimObject] = field(default_factory=dict)
    tick: int = 0
    task_start: float | None = None
    placed_at: dict[str, float] = field(default_factory=dict)
    grabbed_at: dict[str, list[float]] = field(default_factory=dict)
    released: list[tuple[float, str, float]] = field(default_factory=list)  # (t, part, distance)
    collisions: list[tuple[float, str, str]] = field(default_factory=list)
    collision_until: float | None = None
    samples: list[Sample] = field(default_factory=list)
    _pending_events: list[pb.ObjectEvent] = field(default_factory=list)
    _task_events: list[pb.TaskEvent] = field(default_factory=list)
    _cues: dict[str, pb.Cue] = field(default_factory=dict)
    _cue_changes: list[pb.Cue] = field(default_factory=list)
    _contacts: list[pb.Contact] = field(default_factory=list)
    _touching: set[tuple[str, str]] = field(default_factory=set)

    def __post_init__(self) -> None:
        self.view = TaskView(self.facts)
        for part in self.facts.parts.values():
            if part.start is not None:
                self.objects[part.id] = SimObject(
                    part.id, part.start, math.radians(part.start_yaw_deg)
                )
        self._update_grabbable(0.0)

    @property
    def dt(self) -> float:
        return 1.0 / self.facts.tick_hz

    # ------------------------------------------------------------------ orchestrator-lite
    def _event(self, t: float, kind: int, **kw: object) -> None:
        ev = pb.TaskEvent(
            kind=kind, task_time=(t - self.task_start) if self.task_start else 0.0, **kw
        )
        ev.header.sim_time = t
        self._task_events.append(ev)

    def _cue(self, cue_id: str, on: bool, **kw: object) -> None:
        old = self._cues.get(cue_id)
        if old is not None and old.on == on:
            return
        cue = pb.Cue(id=cue_id, on=on, **kw)
        self._cues[cue_id] = cue
        self._cue_changes.append(cue)

    def _next_human(self) -> str | None:
        for pid in self.facts.human_sequence:
            if pid not in self.placed_at:
                return pid
        return None

    def _update_grabbable(self, t: float) -> None:
        nxt = self._next_human()
        for pid in self.facts.human_sequence:
            o = self.objects.get(pid)
            if o is None:
                continue
            g = pid == nxt and self.collision_until is None
            o.grabbable = g
            self._cue(outline_cue_id(pid), g and not o.held_by, part=pid, kind=pb.CUE_KIND_OUTLINE)

    def _place(self, t: float, pid: str) -> None:
        self.placed_at[pid] = t
        part = self.facts.parts[pid]
        o = self.objects.get(pid)
        if o is not None:
            o.pos, o.yaw_rad, o.held_by, o.placed = (
                part.target,
                math.radians(part.target_yaw_deg),
                "",
                True,
            )
            self._pending_events.append(
                pb.ObjectEvent(kind=pb.ObjectEvent.KIND_SNAPPED, object=pid)
            )
        self._event(t, pb.TASK_EVENT_KIND_PART_PLACED, part=pid)
        self._cue(target_cue_id(pid), False, part=pid)

    def _robots(self, t: float) -> None:
        if self.task_start is None:
            return
        for rid in sorted(self.facts.robots):
            last = self.task_start
            for pid in [p.id for p in self.facts.parts.values() if p.owner == rid]:
                if pid in self.placed_at:
                    last = max(last, self.placed_at[pid])
                    continue
                after = self.facts.parts[pid].after
                if any(a not in self.placed_at for a in after):
                    break  # robots work their sequence in order
                ready = max([last] + [self.placed_at[a] for a in after])
                if self.facts.anticipation:
                    self._cue(
                        target_cue_id(pid), True, part=pid, robot=rid, kind=pb.CUE_KIND_TARGET
                    )
                if t >= ready + self.robot_delay_s:
                    self._place(t, pid)
                break

    # ------------------------------------------------------------------ physics-lite
    def _apply(self, t: float, s: Sample) -> None:
        for hand in HANDS:
            pose, grip = s.hand(hand), s.grip(hand)
            hyaw_rad = quat_yaw_rad(pose.orientation)
            held = [o for o in self.objects.values() if o.held_by == hand]
            for o in held:
                assert o.grab_rel is not None
                rel, dyaw_rad = o.grab_rel
                if grip < GRIP_CLOSED:
                    o.held_by = ""
                    part = self.facts.parts[o.id]
                    d = distance(o.pos, part.target)
                    ang = abs(
                        math.degrees(wrap_angle_rad(o.yaw_rad - math.radians(part.target_yaw_deg)))
                    )
                    self.released.append((t, o.id, d))
                    self._pending_events.append(
                        pb.ObjectEvent(
                            kind=pb.ObjectEvent.KIND_RELEASED,
                            object=o.id,
                            holder=hand,
                            target_distance_m=d,
                            target_angle_deg=ang,
                        )
                    )
                    if d <= self.facts.place_tolerance_m and ang <= DEFAULT_TOLERANCE_DEG:
                        self._place(t, o.id)
                    else:
                        o.pos = (o.pos[0], o.pos[1], part.size[2] / 2.0)
                        self._pending_events.append(
                            pb.ObjectEvent(kind=pb.ObjectEvent.KIND_RESTED, object=o.id)
                        )
                    self._update_grabbable(t)
                else:
                    o.pos = add(pose.position, rotate_z_rad(rel, hyaw_rad))
                    o.yaw_rad = hyaw_rad + dyaw_rad
            if grip >= GRIP_CLOSED and not held:
                for o in sorted(self.objects.values(), key=lambda o: o.id):
                    if (
                        o.grabbable
                        and not o.held_by
                        and distance(pose.position, o.pos) <= GRASP_DISTANCE_M
                    ):
                        o.held_by = hand
                        o.grab_rel = (
                            rotate_z_rad(sub(o.pos, pose.position), -hyaw_rad),
                            o.yaw_rad - hyaw_rad,
                        )
                        self.grabbed_at.setdefault(o.id, []).append(t)
                        self._pending_events.append(
                            pb.ObjectEvent(
                                kind=pb.ObjectEvent.KIND_GRABBED, object=o.id, holder=hand
                            )
                        )
                        if self.task_start is None:
                            self.task_start = t
                            self._event(t, pb.TASK_EVENT_KIND_TASK_STARTED)
                        part = self.facts.parts[o.id]
                        self._cue(outline_cue_id(o.id), False, part=o.id)
                        if all(a in self.placed_at for a in part.after):
                            self._cue(target_cue_id(o.id), True, part=o.id)
                        break
            # hand-robot contacts
            for rid, tcp in sorted(self.tcp.items()):
                touching = distance(pose.position, tcp) <= self.collision_radius
                key = (hand, rid)
                if touching and key not in self._touching:
                    self._touching.add(key)
                    self._contacts.append(
                        pb.Contact(kind=pb.CONTACT_KIND_HAND_ROBOT, begin=True, a=hand, b=rid)
                    )
                    if self.collision_until is None and self.task_start is not None:
                        self.collisions.append((t, rid, hand))
                        self.collision_until = t + self.continue_after_s
                        self._event(t, pb.TASK_EVENT_KIND_COLLISION, robot=rid, hand=hand)
                        self._update_grabbable(t)
                elif not touching and key in self._touching:
                    self._touching.discard(key)
                    self._contacts.append(
                        pb.Contact(kind=pb.CONTACT_KIND_HAND_ROBOT, begin=False, a=hand, b=rid)
                    )
                    self._event(t, pb.TASK_EVENT_KIND_COLLISION_END, robot=rid, hand=hand)

    # ------------------------------------------------------------------ the loop
    def _publish(self, t: float) -> None:
        msg = pb.WorldObjects(full=self.tick == 0)
        msg.header.sim_time = t
        msg.header.tick = self.tick
        for o in sorted(self.objects.values(), key=lambda o: o.id):
            msg.objects.add(
                id=o.id,
                held_by=o.held_by,
                grabbable=o.grabbable,
                placed=o.placed,
                pose=pose_to_pb(Pose(o.pos, yaw_quat_rad(o.yaw_rad))),
            )
        msg.events.extend(self._pending_events)
        self._pending_events = []
        self.view.on_objects(msg)
        if self._contacts:
            c = pb.WorldContacts(contacts=self._contacts)
            c.header.sim_time = t
            self.view.on_contacts(c)
            self._contacts = []
        for rid, tcp in sorted(self.tcp.items()):
            rs = pb.RobotState(robot=rid, tcp=pb.Pose(position=vec3_to_pb(tcp)))
            rs.header.sim_time = t
            self.view.on_robot_state(rs)
        if self._cue_changes:
            self.view.on_indicators(pb.Indicators(cues=self._cue_changes))
            self._cue_changes = []
        for ev in self._task_events:
            self.view.on_task_event(ev)
        self._task_events = []

    def step(self) -> Sample:
        t = self.tick * self.dt
        if self.collision_until is not None and t >= self.collision_until:
            self.collision_until = None
            self._event(t, pb.TASK_EVENT_KIND_CONTINUED)
            self._update_grabbable(t)
        self._robots(t)
        self._publish(t)
        sample = self.participant.step(t, self.view)
        self.samples.append(sample)
        self._apply(t, sample)
        self._update_grabbable(t)
        self.tick += 1
        return sample

    def done(self) -> bool:
        return all(
            p.id in self.placed_at
            for p in self.facts.parts.values()
            if p.owner == HUMAN or p.owner in self.facts.robots
        )

    def run(self, max_s: float) -> bool:
        while self.tick * self.dt < max_s:
            self.step()
            if self.done():
                return True
        return False
