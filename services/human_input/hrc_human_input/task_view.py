"""The task state as the scripted participant perceives it, built from bus messages.

Handlers are called at the tick boundary in the bus's deterministic order; the participant reads
the view in its step. Nothing here decides anything.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from hrc.geometry import Vec3, quat_from_pb, quat_yaw_rad, vec3_from_pb
from hrc.scenario.conventions import TARGET_CUE_PREFIX, outline_cue_id, waiting_cue_id
from hrc.wire import pb

from hrc_human_input.facts import ScenarioFacts


@dataclass
class ObjectView:
    id: str
    position: Vec3
    yaw_rad: float
    held_by: str = ""
    grabbable: bool = False
    placed: bool = False


@dataclass
class RobotView:
    id: str
    tcp: Vec3
    speed: float = 0.0
    velocity: Vec3 = (0.0, 0.0, 0.0)
    status: int = 0
    t: float = 0.0


@dataclass
class ObjectEventView:
    t: float
    kind: int
    object: str
    holder: str


@dataclass
class TaskEventView:
    t: float
    kind: int
    part: str = ""
    robot: str = ""
    hand: str = ""


@dataclass
class TaskView:
    facts: ScenarioFacts
    objects: dict[str, ObjectView] = field(default_factory=dict)
    robots: dict[str, RobotView] = field(default_factory=dict)
    cues: dict[str, pb.Cue] = field(default_factory=dict)
    placed_events: set[str] = field(default_factory=set)
    task_start: float | None = None  # sim time of TASK_STARTED
    hand_robot_contacts: set[tuple[str, str]] = field(default_factory=set)
    # Events since the participant last looked (it drains them every step).
    object_events: list[ObjectEventView] = field(default_factory=list)
    task_events: list[TaskEventView] = field(default_factory=list)
    robot_waiting_events: set[str] = field(default_factory=set)
    # Sim time of the tick that opened the exchange being computed: the view holds the inputs
    # of the ticks before it, whichever tick of the exchange the participant is at.
    exchange_t: float | None = None

    # ------------------------------------------------------------------ bus handlers
    def on_objects(self, msg: pb.WorldObjects) -> None:
        t = msg.header.sim_time
        for o in msg.objects:
            self.objects[o.id] = ObjectView(
                o.id,
                vec3_from_pb(o.pose.position),
                quat_yaw_rad(quat_from_pb(o.pose.orientation)),
                o.held_by,
                o.grabbable,
                o.placed,
            )
        for e in msg.events:
            self.object_events.append(ObjectEventView(t, e.kind, e.object, e.holder))

    def on_robot_state(self, msg: pb.RobotState) -> None:
        t = msg.header.sim_time
        tcp = vec3_from_pb(msg.tcp.position)
        prev = self.robots.get(msg.robot)
        velocity: Vec3 = (0.0, 0.0, 0.0)
        if prev is not None and t > prev.t:
            # States are published on change: the arm stood at prev.tcp until the tick before
            # this one, so the displacement took one tick, however long ago prev came.
            dt = 1.0 / self.facts.tick_hz
            velocity = (
                (tcp[0] - prev.tcp[0]) / dt,
                (tcp[1] - prev.tcp[1]) / dt,
                (tcp[2] - prev.tcp[2]) / dt,
            )
        self.robots[msg.robot] = RobotView(msg.robot, tcp, msg.tcp_speed, velocity, msg.status, t)

    def robot_velocity(self, robot: RobotView, now: float) -> Vec3:
        """The arm's TCP velocity as last heard: zero once its last state is older than the
        tick before the inputs' (no new state means nothing changed, so it stands still). The
        inputs' tick is the exchange's first (``exchange_t``), not ``now``: inside a longer
        exchange no state can have come since, so a moving arm is not taken for a still one."""
        ref = now if self.exchange_t is None else self.exchange_t
        if ref - robot.t > 1.5 / self.facts.tick_hz:
            return (0.0, 0.0, 0.0)
        return robot.velocity

    def on_indicators(self, msg: pb.Indicators) -> None:
        for cue in msg.cues:
            self.cues[cue.id] = cue

    def on_task_event(self, msg: pb.TaskEvent) -> None:
        t = msg.header.sim_time
        if msg.kind == pb.TASK_EVENT_KIND_TASK_STARTED and self.task_start is None:
            self.task_start = t - msg.task_time
        elif msg.kind == pb.TASK_EVENT_KIND_PART_PLACED and msg.part:
            self.placed_events.add(msg.part)
        elif msg.kind == pb.TASK_EVENT_KIND_ROBOT_WAITING:
            self.robot_waiting_events.add(msg.robot or msg.agent)
        elif msg.kind == pb.TASK_EVENT_KIND_ROBOT_WAIT_OVER:
            self.robot_waiting_events.discard(msg.robot or msg.agent)
        self.task_events.append(
            TaskEventView(t, msg.kind, msg.part, msg.robot or msg.agent, msg.hand)
        )

    def on_contacts(self, msg: pb.WorldContacts) -> None:
        for c in msg.contacts:
            if c.kind != pb.CONTACT_KIND_HAND_ROBOT:
                continue
            if c.begin:
                self.hand_robot_contacts.add((c.a, c.b))
            else:
                self.hand_robot_contacts.discard((c.a, c.b))

    # ------------------------------------------------------------------ questions
    def drain(self) -> tuple[list[ObjectEventView], list[TaskEventView]]:
        o, e = self.object_events, self.task_events
        self.object_events, self.task_events = [], []
        return o, e

    def cue_on(self, cue_id: str) -> bool:
        cue = self.cues.get(cue_id)
        return cue is not None and cue.on

    def is_placed(self, part: str) -> bool:
        o = self.objects.get(part)
        return part in self.placed_events or (o is not None and o.placed)

    def is_grabbable(self, part: str) -> bool:
        o = self.objects.get(part)
        return (o is not None and o.grabbable) or self.cue_on(outline_cue_id(part))

    def held_by(self, part: str) -> str:
        o = self.objects.get(part)
        return o.held_by if o is not None else ""

    def task_time(self, t: float) -> float | None:
        return None if self.task_start is None else t - self.task_start

    def robot_waiting(self, robot: str) -> bool:
        """Only visible to a participant through the "Waiting.." cue (anticipation on)."""
        return self.cue_on(waiting_cue_id(robot))

    def robot_heading_points(self, robot: str) -> list[Vec3]:
        """Where the anticipation cues say this robot is heading (lit `target:<part>` cues)."""
        points: list[Vec3] = []
        for cue_id, cue in sorted(self.cues.items()):
            if not cue.on or not cue_id.startswith(TARGET_CUE_PREFIX):
                continue
            part = cue.part or cue_id.removeprefix(TARGET_CUE_PREFIX)
            owner = cue.robot
            facts = self.facts.parts.get(part)
            if not owner and facts is not None:
                owner = facts.owner
            if owner != robot:
                continue
            if cue.HasField("position"):
                points.append(vec3_from_pb(cue.position))
            elif facts is not None:
                points.append(facts.target)
        return points
