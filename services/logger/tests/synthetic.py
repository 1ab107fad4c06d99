"""A synthetic trial: what physics, ik_cpp, human_input and the orchestrator would send.

A test double, used by the logger's tests (services/logger/tests, tests/test_logger_bus.py) and
handy to try the view without the other services: a short
thesis-board trial with a collision-and-continue twice, a robot-robot near collision, cues
turning on and off, parts moving, both robots' joint states every tick, the finishes, TASK
FINISHED and the final metrics on the very last tick (which no clock tick lists, so only the
logger's end-of-run drain can catch them).
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np
from google.protobuf.message import Message

from hrc.geometry import pose_to_pb, vec3_to_pb, yaw_pose_deg
from hrc.scenario.conventions import WAITING_TEXT
from hrc.scenario.models import DEFAULT_TICK_HZ
from hrc.urdf_fk import UrdfModel, matrix_to_quat_xyzw, yaw_transform
from hrc.wire import pb

START_TICK = 10  # the first grab: task time 0
WALL_TIME = "2024-05-02T14:03:11+02:00"

# role -> the service name it plays
ROLES = {"physics": "physics", "ik": "ik_cpp", "human": "human_input", "orch": "orchestrator"}


@dataclass
class Outgoing:
    role: str  # physics | ik | human | orch
    # key name: world_objects, world_contacts, robot_state:<id>, human_state, task_events, ...
    key: str
    msg: Message


@dataclass
class Expected:
    """What the synthetic trial sends, to compare the logger's files with."""

    n_ticks: int
    collisions: int = 0
    near: int = 0
    event_kinds: Counter[str] = field(default_factory=Counter)
    cue_changes: int = 0
    parts_moved: set[str] = field(default_factory=set)
    cue_ids: set[str] = field(default_factory=set)


def _lerp(a: np.ndarray, b: np.ndarray, s: float) -> np.ndarray:
    return a + (b - a) * min(1.0, max(0.0, s))


class SyntheticTrial:
    """Messages of each tick, in publishing order: physics's world, then the participants'."""

    def __init__(self, scenario: pb.Scenario, n_ticks: int = 600) -> None:
        if n_ticks < 580:
            raise ValueError(f"the synthetic trial needs at least 580 ticks, got {n_ticks}")
        self.sc = scenario
        self.n = n_ticks
        self.dt = 1.0 / (scenario.info.tick_hz or DEFAULT_TICK_HZ)
        self.parts = {p.id: p for p in scenario.parts}
        self.robots = {r.id: r for r in scenario.robots}
        self.models = {r.id: UrdfModel.from_file(r.urdf_path) for r in scenario.robots}
        self.expected = Expected(n_ticks)
        screws = [p.id for p in scenario.parts if not p.start_given]
        self.screw = screws[0]
        # part -> (first tick, last tick, holder); it moves from start (or the feeder) to target
        self.moves: dict[str, tuple[int, int, str]] = {
            "H1": (50, 200, "left"),
            "RA1": (100, 350, "r1"),
            self.screw: (300, 450, "r2"),
        }
        self.expected.parts_moved = set(self.moves)

    # ------------------------------------------------------------------ pieces
    def task_time(self, k: int) -> float:
        return max(0, k - START_TICK) * self.dt

    def _part_pose(self, pid: str, k: int) -> tuple[np.ndarray, float, str, bool]:
        p = self.parts[pid]
        if p.start_given:
            start = np.array([p.start.xyz.x, p.start.xyz.y, p.start.xyz.z])
            yaw0 = p.start.yaw_deg
        else:
            f = self.robots["r2"].feeder
            start, yaw0 = np.array([f.x, f.y, f.z]), 0.0
        target = np.array([p.target.xyz.x, p.target.xyz.y, p.target.xyz.z])
        if pid not in self.moves:
            return start, yaw0, "", False
        a, b, holder = self.moves[pid]
        s = (k - a) / (b - a)
        pos = _lerp(start, target, s)
        pos[2] += 0.1 * math.sin(math.pi * min(1.0, max(0.0, s)))  # lifted on the way
        yaw = yaw0 + (p.target.yaw_deg - yaw0) * min(1.0, max(0.0, s))
        return pos, yaw, holder if a <= k < b else "", k >= b

    def _object(self, pid: str, k: int) -> pb.ObjectState:
        pos, yaw, holder, placed = self._part_pose(pid, k)
        a, b, _ = self.moves.get(pid, (0, 0, ""))
        return pb.ObjectState(
            id=pid,
            pose=pose_to_pb(yaw_pose_deg(pos, yaw)),
            held_by=holder,
            grabbable=False,
            placed=placed,
            moving=a <= k <= b,
        )

    def q(self, rid: str, k: int) -> list[float]:
        t = k * self.dt
        phase = 0.0 if rid == "r1" else 1.0
        return [
            0.4 * math.sin(2 * math.pi * 0.5 * t + i + phase) + (0.6 if i in (1, 2) else 0.0)
            for i in range(len(self.models[rid].movable))
        ]

    def robot_state(self, rid: str, k: int) -> pb.RobotState:
        model = self.models[rid]
        r = self.robots[rid]
        q = self.q(rid, k)
        base = yaw_transform([r.base.xyz.x, r.base.xyz.y, r.base.xyz.z], r.base.yaw_deg)
        tool = model.link_poses(dict(zip(model.movable, q, strict=True)), base)[
            model.joints[-1].child
        ]
        prev = model.link_poses(dict(zip(model.movable, self.q(rid, k - 1), strict=True)), base)[
            model.joints[-1].child
        ]
        speed = float(np.linalg.norm(tool[:3, 3] - prev[:3, 3]) / self.dt)
        qx, qy, qz, qw = matrix_to_quat_xyzw(tool[:3, :3])
        return pb.RobotState(
            robot=rid,
            joint_names=model.movable,
            joint_positions=q,
            tcp=pb.Pose(
                position=vec3_to_pb(tool[:3, 3]), orientation=pb.Quat(x=qx, y=qy, z=qz, w=qw)
            ),
            tcp_speed=speed,
            status=pb.MOTION_STATUS_MOVING,
            command_id=1,
        )

    def human_state(self, k: int) -> pb.HumanState:
        t = k * self.dt
        left, _, _, _ = self._part_pose("H1", k)
        right = np.array([0.2 + 0.05 * math.sin(t), -0.3, 0.15])
        grip = 1.0 if 50 <= k < 200 else 0.0
        return pb.HumanState(
            head=pb.Pose(position=vec3_to_pb((0.0, -0.6, 0.5)), orientation=pb.Quat(w=1.0)),
            left_hand=pb.Pose(position=vec3_to_pb([*left, 0, 0, 0.03]), orientation=pb.Quat(w=1.0)),
            right_hand=pb.Pose(position=vec3_to_pb(right), orientation=pb.Quat(w=1.0)),
            left_grip=grip,
            right_grip=0.0,
            source=pb.INPUT_SOURCE_SCRIPTED,
        )

    def _event(self, k: int, kind: int, **kw: object) -> pb.TaskEvent:
        ev = pb.TaskEvent(kind=kind, task_time=self.task_time(k), **kw)  # type: ignore[arg-type]
        name = pb.TaskEventKind.Name(kind).removeprefix("TASK_EVENT_KIND_")
        self.expected.event_kinds[name] += 1
        if kind == pb.TASK_EVENT_KIND_COLLISION:
            self.expected.collisions += 1
        if kind == pb.TASK_EVENT_KIND_NEAR_COLLISION:
            self.expected.near += 1
        return ev

    def _cue(self, cid: str, kind: int, on: bool, **kw: object) -> pb.Cue:
        self.expected.cue_changes += 1
        self.expected.cue_ids.add(cid)
        return pb.Cue(id=cid, kind=kind, on=on, flashing=True, **kw)  # type: ignore[arg-type]

    def events(self, k: int) -> list[pb.TaskEvent]:
        K = pb.TaskEventKind
        last = self.n - 1
        out: list[pb.TaskEvent] = []
        if k == START_TICK:
            out.append(
                self._event(
                    k, K.TASK_EVENT_KIND_TASK_STARTED, wall_time=WALL_TIME, agent="human", part="H1"
                )
            )
        if k == 50:
            out.append(
                self._event(
                    k, K.TASK_EVENT_KIND_PART_GRABBED, agent="human", part="H1", hand="left"
                )
            )
        if k == 200:
            out.append(self._event(k, K.TASK_EVENT_KIND_PART_PLACED, agent="human", part="H1"))
        if k == 250:  # the orchestrator wrote the thesis line itself
            out.append(
                self._event(
                    k,
                    K.TASK_EVENT_KIND_COLLISION,
                    robot="r1",
                    hand="left",
                    text=(
                        f"{self.task_time(k):.2f} sec : "
                        "Collision 1 occurred between r1 and left hand."
                    ),
                )
            )
        if k == 300:
            out.append(
                self._event(
                    k,
                    K.TASK_EVENT_KIND_CONTINUED,
                    continued=pb.Continued(number=1, delay_s=50 * self.dt),
                )
            )
        if k == 400:
            out.append(self._event(k, K.TASK_EVENT_KIND_NEAR_COLLISION, robot="r2"))
        if k == 420:
            out.append(self._event(k, K.TASK_EVENT_KIND_NEAR_COLLISION_END, robot="r2"))
        if k == 450:
            out.append(self._event(k, K.TASK_EVENT_KIND_COLLISION, robot="r2", hand="right"))
        if k == 480:
            out.append(
                self._event(
                    k,
                    K.TASK_EVENT_KIND_CONTINUED,
                    continued=pb.Continued(number=2, delay_s=30 * self.dt),
                )
            )
        if k == 500:
            out.append(
                self._event(
                    k,
                    K.TASK_EVENT_KIND_ROBOT_FINISHED,
                    agent="r1",
                    robot="r1",
                    robot_finished=pb.RobotFinished(
                        max_tcp_speed_mps=0.5, avg_tcp_speed_mps=0.21, idle_s=0.4
                    ),
                )
            )
        if k == 520:
            out.append(
                self._event(
                    k,
                    K.TASK_EVENT_KIND_ROBOT_FINISHED,
                    agent="r2",
                    robot="r2",
                    robot_finished=pb.RobotFinished(
                        max_tcp_speed_mps=0.45, avg_tcp_speed_mps=0.19, idle_s=0.25
                    ),
                )
            )
        if k == 540:
            out.append(
                self._event(
                    k,
                    K.TASK_EVENT_KIND_HUMAN_FINISHED,
                    agent="human",
                    human_finished=pb.HumanFinished(idle_s=0.1),
                )
            )
        if k == last:
            out.append(
                self._event(
                    k,
                    K.TASK_EVENT_KIND_TASK_FINISHED,
                    task_finished=pb.TaskFinished(human_robot_collisions=2, near_collisions=1),
                )
            )
        return out

    def cues(self, k: int) -> list[pb.Cue]:
        C = pb
        out: list[pb.Cue] = []
        if k == 0:
            out.append(self._cue("outline:H1", C.CUE_KIND_OUTLINE, True, part="H1", color="white"))
        if k == 50:
            out.append(self._cue("outline:H1", C.CUE_KIND_OUTLINE, False, part="H1"))
            out.append(self._cue("target:H1", C.CUE_KIND_TARGET, True, part="H1", color="#5a96eb"))
        if k == 100:
            out.append(
                self._cue(
                    "target:RA1", C.CUE_KIND_TARGET, True, part="RA1", robot="r1", color="yellow"
                )
            )
            out.append(
                self._cue(
                    "waiting:r2",
                    C.CUE_KIND_WAITING,
                    True,
                    robot="r2",
                    color="green",
                    text=WAITING_TEXT,
                )
            )
        if k == 200:
            out.append(self._cue("waiting:r2", C.CUE_KIND_WAITING, False, robot="r2"))
            out.append(self._cue("target:H1", C.CUE_KIND_TARGET, False, part="H1"))
        if k == 250:
            out.append(self._cue("continue_button", C.CUE_KIND_CONTINUE_BUTTON, True, color="red"))
        if k == 300:
            out.append(self._cue("continue_button", C.CUE_KIND_CONTINUE_BUTTON, False))
            out.append(
                self._cue(
                    f"target:{self.screw}",
                    C.CUE_KIND_TARGET,
                    True,
                    part=self.screw,
                    robot="r2",
                    color="green",
                )
            )
        if k == 350:
            out.append(self._cue("target:RA1", C.CUE_KIND_TARGET, False, part="RA1", robot="r1"))
        if k == 450:
            out.append(
                self._cue(
                    f"target:{self.screw}", C.CUE_KIND_TARGET, False, part=self.screw, robot="r2"
                )
            )
        return out

    def metrics(self) -> pb.MetricsReport:
        m = pb.Metrics(
            scenario=self.sc.info.name, participant=self.sc.participant.name, seed=self.sc.info.seed
        )
        m.conditions.anticipation = self.sc.conditions.anticipation
        m.conditions.safety_policy = self.sc.conditions.safety_policy
        m.task.CopyFrom(
            pb.TaskMetrics(started=True, finished=True, completion_s=self.task_time(self.n - 1))
        )
        m.human.CopyFrom(pb.HumanMetrics(completion_s=self.task_time(540), idle_s=0.1))
        col = m.collisions
        col.human_robot.add(t_s=self.task_time(250), robot="r1", hand="left", delay_s=50 * self.dt)
        col.human_robot.add(t_s=self.task_time(450), robot="r2", hand="right", delay_s=30 * self.dt)
        col.human_robot_count, col.total_delay_s = 2, 80 * self.dt
        col.near.add(t_s=self.task_time(400))
        col.near_count = 1
        m.robots["r1"].CopyFrom(
            pb.RobotMetrics(
                completion_s=self.task_time(500),
                idle_s=0.4,
                avg_tcp_speed_mps=0.21,
                max_tcp_speed_mps=0.5,
            )
        )
        m.robots["r2"].CopyFrom(
            pb.RobotMetrics(
                completion_s=self.task_time(520),
                idle_s=0.25,
                avg_tcp_speed_mps=0.19,
                max_tcp_speed_mps=0.45,
            )
        )
        for pid in self.parts:
            m.parts[pid].SetInParent()  # never grabbed: times unset
        m.run.CopyFrom(pb.RunMetrics(mode=pb.CLOCK_MODE_LOCKSTEP, ticks=self.n, ok=True))
        return pb.MetricsReport(final=True, metrics=m)

    # ------------------------------------------------------------------ the trial
    def world(self, k: int) -> list[Outgoing]:
        """Physics's messages of tick k (published before clock tick k)."""
        out: list[Outgoing] = []
        wo = pb.WorldObjects(full=k == 0)
        for pid in self.parts:
            if not self.parts[pid].start_given and (pid != self.screw or k < self.moves[pid][0]):
                continue  # screws exist once spawned at the feeder
            a, b, _ = self.moves.get(pid, (-1, -1, ""))
            if k == 0 or a <= k <= b:
                wo.objects.append(self._object(pid, k))
            if k == a:
                kind = (
                    pb.ObjectEvent.KIND_SPAWNED
                    if pid == self.screw
                    else pb.ObjectEvent.KIND_GRABBED
                )
                wo.events.add(kind=kind, object=pid, holder=self.moves[pid][2])
            if k == b:
                wo.events.add(kind=pb.ObjectEvent.KIND_SNAPPED, object=pid)
        out.append(Outgoing("physics", "world_objects", wo))
        contacts: list[pb.Contact] = []
        if k in (250, 262):
            contacts.append(
                pb.Contact(
                    kind=pb.CONTACT_KIND_HAND_ROBOT,
                    begin=k == 250,
                    a="left",
                    b="r1",
                    link="link3_forearm",
                    point=vec3_to_pb((0.3, 0.2, 0.3)),
                )
            )
        if k in (400, 420):
            contacts.append(
                pb.Contact(
                    kind=pb.CONTACT_KIND_ROBOT_ROBOT,
                    begin=k == 400,
                    a="r1",
                    b="r2",
                    point=vec3_to_pb((0.0, 0.35, 0.4)),
                )
            )
        if k == 5:
            contacts.append(
                pb.Contact(kind=pb.CONTACT_KIND_HAND_ENVELOPE, begin=True, a="left", b="0")
            )
        if contacts:
            out.append(Outgoing("physics", "world_contacts", pb.WorldContacts(contacts=contacts)))
        return out

    def outputs(self, k: int) -> list[Outgoing]:
        """The participants' outputs of tick k (published after clock tick k)."""
        out = [
            Outgoing("ik", f"robot_state:{rid}", self.robot_state(rid, k))
            for rid in sorted(self.robots)
        ]
        out.append(Outgoing("human", "human_state", self.human_state(k)))
        for ev in self.events(k):
            out.append(Outgoing("orch", "task_events", ev))
        cues = self.cues(k)
        if cues:
            out.append(Outgoing("orch", "task_indicators", pb.Indicators(cues=cues)))
        if k == self.n - 1:
            out.append(Outgoing("orch", "task_metrics", self.metrics()))
        return out

    def ticks(self) -> Iterator[tuple[int, list[Outgoing], list[Outgoing]]]:
        for k in range(self.n):
            yield k, self.world(k), self.outputs(k)
