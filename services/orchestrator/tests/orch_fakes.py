"""Test doubles for the task logic: fake arms, a fake world and a fake participant.

`Sim` drives a `Task` tick by tick the way the co-simulation does: the orchestrator sees the arms'
states of the previous tick; the arms follow the commands of the previous tick; contacts and
object events are injected per tick by the test (or by the fake participant).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from hrc import scenario as sc
from hrc.geometry import Vec3, add, distance, pose_to_pb, vec3, yaw_pose_deg
from hrc.wire import pb

from hrc_orchestrator.task import Inputs, Outputs, Task

ROOT = Path(__file__).resolve().parents[3]
REACHED_M = 0.005
K = pb.TaskEventKind


def load(name: str, **overrides: object) -> sc.Scenario:
    """A shipped scenario (no motion check), with top-level tables patched, e.g.
    conditions={"safety_policy": "stop_colliding"}."""
    s = sc.load(ROOT / "scenarios" / name, motion_check=False)
    for table, values in overrides.items():
        model = getattr(s, table)
        # validated like the file's values (strings become enum members)
        setattr(s, table, type(model).model_validate({**model.model_dump(), **values}))
    return s


class FakeRobot:
    """Moves the TCP straight toward the commanded target at max speed; REACHED within 5 mm."""

    def __init__(self, rid: str, start: Vec3, speed: float, dt: float) -> None:
        self.id, self.tcp, self.speed, self.dt = rid, start, speed, dt
        self.cmd: pb.RobotCommand | None = None
        self.waypoints: list[Vec3] = []
        self.status = pb.MOTION_STATUS_IDLE
        self.frozen = False  # a test can stop it to keep it in a place

    def command(self, cmd: pb.RobotCommand) -> None:
        self.cmd = cmd
        if cmd.kind == pb.RobotCommand.KIND_HOLD:
            self.waypoints, self.status = [], pb.MOTION_STATUS_HOLDING
            return
        target = (cmd.target.x, cmd.target.y, cmd.target.z)
        pts: list[Vec3] = []
        if cmd.depart_height > 0:
            pts.append(add(self.tcp, (0.0, 0.0, cmd.depart_height)))
        if cmd.approach_height > 0:
            pts.append(add(target, (0.0, 0.0, cmd.approach_height)))
        pts.append(target)
        self.waypoints, self.status = pts, pb.MOTION_STATUS_MOVING

    def tick(self) -> pb.RobotState:
        moved = 0.0
        budget = 0.0 if self.frozen else self.speed * self.dt
        while self.waypoints and budget > 1e-12:
            wp = self.waypoints[0]
            d = distance(self.tcp, wp)
            if d <= budget:
                self.tcp, budget, moved = wp, budget - d, moved + d
                self.waypoints.pop(0)
            else:
                f = budget / d
                self.tcp = tuple(a + (b - a) * f for a, b in zip(self.tcp, wp, strict=True))  # type: ignore
                moved, budget = moved + budget, 0.0
        if self.cmd is not None and self.cmd.kind == pb.RobotCommand.KIND_MOVE:
            target = (self.cmd.target.x, self.cmd.target.y, self.cmd.target.z)
            if not self.waypoints and distance(self.tcp, target) <= REACHED_M:
                self.status = pb.MOTION_STATUS_REACHED
        st = pb.RobotState(
            robot=self.id,
            status=self.status,
            tcp_speed=moved / self.dt,
            command_id=self.cmd.command_id if self.cmd else 0,
        )
        st.tcp.position.x, st.tcp.position.y, st.tcp.position.z = self.tcp
        st.tcp.orientation.w = 1.0
        return st


@dataclass
class FakeHuman:
    """Grabs the grabbable part after `grab_delay_s`, releases it at its target once the target
    cue is on after `place_delay_s` (offset by `miss_m` for the first `misses` releases)."""

    grab_delay_s: float = 0.5
    place_delay_s: float = 0.5
    misses: int = 0
    miss_m: float = 0.05
    hand: str = "right"
    enabled: bool = True
    _since: float | None = None
    _held: str = ""
    _missed: int = 0


@dataclass
class Sim:
    scenario: sc.Scenario
    human: FakeHuman | None = field(default_factory=FakeHuman)
    hands_in_envelope: bool = True
    wall: str = "2001-02-03T04:05:06+00:00"

    def __post_init__(self) -> None:
        self.task = Task(self.scenario, wall_clock=lambda: self.wall)
        self.dt = 1.0 / self.scenario.scenario.tick_hz
        self.robots = {
            rid: FakeRobot(rid, vec3(r.home), r.max_tcp_speed, self.dt)
            for rid, r in self.scenario.robots.items()
        }
        self.k = 0
        self.states: list[pb.RobotState] = []
        self.grabbable: dict[str, bool] = {}
        self.cues: dict[str, pb.Cue] = {}
        self.events: list[pb.TaskEvent] = []
        self.commands: list[pb.RobotCommand] = []
        self.world: list[pb.WorldCommand] = []
        self.stop = ""
        self._contacts: list[pb.Contact] = []
        self._object_events: list[pb.ObjectEvent] = []
        self._separations: list[pb.Separation] = []
        if self.hands_in_envelope:
            self.contact(pb.CONTACT_KIND_HAND_ENVELOPE, True, "right", "0")
        self.hooks: list[Callable[[Sim], None]] = []

    # ---------------------------------------------------------------- injection
    def contact(self, kind: int, begin: bool, a: str, b: str, link: str = "") -> None:
        self._contacts.append(pb.Contact(kind=kind, begin=begin, a=a, b=b, link=link))

    def separation(self, robot: str, distance_m: float, body: str = "right") -> None:
        """The separation sensor's reading for ``robot`` in the next step's inputs (ssm)."""
        self._separations.append(pb.Separation(robot=robot, distance_m=distance_m, body=body))

    def object_event(
        self,
        kind: int,
        obj: str,
        holder: str = "",
        position: Vec3 | None = None,
        yaw_deg: float = 0.0,
    ) -> None:
        e = pb.ObjectEvent(kind=kind, object=obj, holder=holder)
        if position is not None:
            e.pose.CopyFrom(pose_to_pb(yaw_pose_deg(position, yaw_deg)))
        self._object_events.append(e)

    def grab(self, part: str, hand: str = "right") -> None:
        self.object_event(pb.ObjectEvent.KIND_GRABBED, part, hand)

    def release(self, part: str, position: Vec3, yaw_deg: float = 0.0, hand: str = "right") -> None:
        self.object_event(pb.ObjectEvent.KIND_RELEASED, part, hand, position, yaw_deg)

    # ---------------------------------------------------------------- running
    @property
    def t(self) -> float:
        return self.task.now()

    def step(self) -> Outputs:
        for hook in self.hooks:
            hook(self)
        self._fake_human()
        inputs = Inputs(robot_states=self.states)
        if self._object_events:
            inputs.objects.append(pb.WorldObjects(events=self._object_events))
        if self._contacts:
            inputs.contacts.append(pb.WorldContacts(contacts=self._contacts))
        if self._separations:
            inputs.separations.append(pb.Separations(separations=self._separations))
        self._object_events, self._contacts, self._separations = [], [], []
        out = self.task.step(self.k, self.k * self.dt, inputs)
        self.events.extend(out.events)
        self.commands.extend(out.robot_commands)
        self.world.extend(out.world_commands)
        for wc in out.world_commands:
            if wc.HasField("set_grabbable"):
                self.grabbable[wc.set_grabbable.object] = wc.set_grabbable.grabbable
        for cue in out.cues:
            if cue.on:
                self.cues[cue.id] = cue
            else:
                self.cues.pop(cue.id, None)
        if out.stop:
            self.stop = out.stop
        for cmd in out.robot_commands:
            self.robots[cmd.robot].command(cmd)
        self.states = [self.robots[rid].tick() for rid in sorted(self.robots)]
        self.k += 1
        return out

    def run(self, until: Callable[[Sim], bool], max_s: float = 300.0) -> None:
        limit = self.k + int(max_s / self.dt)
        while not until(self):
            if self.k >= limit:
                raise AssertionError(
                    f"condition not met within {max_s} s of sim time; "
                    f"last events: {[e.text for e in self.events[-8:]]}"
                )
            self.step()

    def run_to_end(self, max_s: float = 600.0) -> None:
        self.run(lambda s: bool(s.stop), max_s)

    # ---------------------------------------------------------------- queries
    def kinds(self, kind: int) -> list[pb.TaskEvent]:
        return [e for e in self.events if e.kind == kind]

    def texts(self) -> list[str]:
        return [e.text for e in self.events]

    def has(self, kind: int, **fields: object) -> bool:
        return any(all(getattr(e, k) == v for k, v in fields.items()) for e in self.kinds(kind))

    # ---------------------------------------------------------------- the fake participant
    def _fake_human(self) -> None:
        h = self.human
        if h is None or not h.enabled:
            return
        now = self.k * self.dt
        if not h._held:
            ready = [p for p, g in sorted(self.grabbable.items()) if g]
            if not ready:
                h._since = None
                return
            if h._since is None:
                h._since = now
            elif now - h._since >= h.grab_delay_s:
                h._held, h._since = ready[0], None
                self.grab(ready[0], h.hand)
            return
        if f"target:{h._held}" not in self.cues:
            h._since = None
            return
        if h._since is None:
            h._since = now
        elif now - h._since >= h.place_delay_s:
            part = self.scenario.part(h._held)
            target = vec3(part.target.xyz)
            if h._missed < h.misses:
                h._missed += 1
                target = add(target, (h.miss_m, 0.0, 0.0))
            self.release(h._held, target, part.target.yaw, h.hand)
            h._held, h._since = "", None


def idle_seconds(events: list[pb.TaskEvent], robot: str) -> float:
    return math.fsum(
        e.robot_wait_over.waited_s
        for e in events
        if e.kind == K.TASK_EVENT_KIND_ROBOT_WAIT_OVER and e.robot == robot
    )
