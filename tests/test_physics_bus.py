"""The physics service as a real process over Zenoh, with this test as the other participants.

The test plays the orchestrator (scenario queryable, world commands), human_input (HumanState
from a replayed path) and ik_cpp (RobotState joint positions), each a real Bus with a
LockstepParticipant acking every tick, and checks what physics publishes against geometry it
computes itself (its own pybullet client on the same URDF and hand size).

Timing (docs/ARCHITECTURE.md): inputs stamped k are applied by physics after the barrier of k,
so the world they produce is published with tick k + 1.
"""

from __future__ import annotations

import itertools
import math
import subprocess
import sys
import threading
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import pybullet as p
import pytest

from hrc import scenario as sc
from hrc.bus import Bus, BusConfig, LockstepParticipant
from hrc.geometry import IDENTITY, Pose, pose_to_pb, yaw_quat_deg
from hrc.ports import free_port
from hrc.scenario.conventions import HAND_SIZE
from hrc.scenario.models import DEFAULT_MAX_EXCHANGE_TICKS
from hrc.wire import pb

from .goldens import MINIMAL

pytestmark = pytest.mark.slow

AWAY = (0.0, -0.8, 0.4)  # outside every envelope box, far from both robots

Step = Callable[[int, float, "Role"], None]


@dataclass
class Role:
    """One participant played by the test: its own Zenoh session, acking every tick."""

    name: str
    bus: Bus
    part: LockstepParticipant
    step: Step | None = None

    def put(self, key: str, msg, k: int, t: float) -> None:
        self.bus.publisher(key).put(msg, k, t)


@dataclass
class Record:
    objects: list[pb.WorldObjects] = field(default_factory=list)
    contacts: list[pb.WorldContacts] = field(default_factory=list)

    def contact_events(self, kind: int) -> list[tuple[int, pb.Contact]]:
        return [(m.header.tick, c) for m in self.contacts for c in m.contacts if c.kind == kind]

    def object_events(self, kind: int) -> list[tuple[int, pb.ObjectEvent]]:
        return [(m.header.tick, e) for m in self.objects for e in m.events if e.kind == kind]


class PhysicsRun:
    """Starts ``python -m hrc_physics`` and the participants; :meth:`run` plays ``ticks``."""

    def __init__(
        self,
        tmp: Path,
        scenario: Path,
        ticks: int,
        roles: dict[str, Step | None],
        observers: list[str] = (),
    ) -> None:
        self.session = f"ph{uuid.uuid4().hex[:8]}"
        self.port = free_port()
        self.scenario_msg = sc.to_proto(sc.load(scenario, motion_check=False))
        self.log_path = tmp / "physics.log"
        self.record = Record()
        self._log = open(self.log_path, "w")
        argv = [
            sys.executable,
            "-m",
            "hrc_physics",
            "--session",
            self.session,
            "--listen",
            f"tcp/127.0.0.1:{self.port}",
            "--ticks",
            str(ticks),
            "--participants",
            ",".join(roles),
            f"--observers={','.join(observers)}",
            "--start-timeout",
            "60",
            "--barrier-timeout",
            "30",
        ]
        self.proc = subprocess.Popen(
            argv, stdout=self._log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL
        )
        self.roles: list[Role] = []
        self._observer_buses: list[Bus] = []
        try:
            for name, step in roles.items():
                bus = Bus(self._config(), name)
                part = LockstepParticipant(bus, input_timeout_s=30)
                self.roles.append(Role(name, bus, part, step))
            first = self.roles[0]
            first.bus.queryable(first.bus.keys.scenario(), None, lambda _req: self.scenario_msg)
            first.part.input(
                first.bus.keys.world_objects(),
                pb.WorldObjects,
                lambda _k, m: self.record.objects.append(m),
            )
            first.part.input(
                first.bus.keys.world_contacts(),
                pb.WorldContacts,
                lambda _k, m: self.record.contacts.append(m),
            )
            for role in self.roles:
                if role.step is not None:
                    role.part.on_tick(self._stepper(role))
                role.part.start()
            for name in observers:  # present (liveliness), never acking
                bus = Bus(self._config(), name)
                bus.declare_token()
                self._observer_buses.append(bus)
        except Exception:
            self.close()
            raise

    def _config(self) -> BusConfig:
        return BusConfig(
            session=self.session, connect=[f"tcp/127.0.0.1:{self.port}"], listen=["tcp/127.0.0.1:0"]
        )

    @staticmethod
    def _stepper(role: Role) -> Callable[[pb.ClockTick], None]:
        def on_tick(tick: pb.ClockTick) -> None:
            role.step(tick.header.tick, tick.header.sim_time, role)  # type: ignore[misc]

        return on_tick

    def run(self, timeout: float = 120.0) -> pb.RunEnd:
        outcomes: dict[str, object] = {}

        def go(role: Role) -> None:
            outcomes[role.name] = role.part.run(timeout=timeout)

        threads = [threading.Thread(target=go, args=(r,)) for r in self.roles]
        for t in threads:
            t.start()
        for t in threads:
            t.join(timeout + 10)
        for role in self.roles:
            out = outcomes.get(role.name)
            assert out is not None and out.ok, f"{role.name}: {out}\n{self.log()}"  # type: ignore[attr-defined]
        result = outcomes[self.roles[0].name].run_end  # type: ignore[attr-defined]
        assert all(r.run_end == result for r in (outcomes[n] for n in outcomes))  # type: ignore[attr-defined]
        self.close()
        code = self.proc.wait(30)
        assert code == 0, self.log()
        assert result is not None
        return result

    def log(self) -> str:
        if not self._log.closed:
            self._log.flush()
        return self.log_path.read_text(errors="replace")

    def close(self) -> None:
        for role in self.roles:
            role.bus.close()
        self.roles = []
        for bus in self._observer_buses:
            bus.close()
        self._observer_buses.clear()
        if self.proc.poll() is None:
            try:
                self.proc.wait(15)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self._log.close()


@pytest.fixture
def physics_run(tmp_path: Path):
    runs: list[PhysicsRun] = []

    def make(*args, **kwargs) -> PhysicsRun:
        r = PhysicsRun(tmp_path, *args, **kwargs)
        runs.append(r)
        return r

    yield make
    for r in runs:
        r.close()


def human_state(
    left=AWAY, right=AWAY, left_grip=0.0, right_grip=0.0, rot=IDENTITY
) -> pb.HumanState:
    return pb.HumanState(
        left_hand=pose_to_pb(Pose(left, rot)),
        right_hand=pose_to_pb(Pose(right, rot)),
        head=pose_to_pb(Pose((0.0, -0.7, 0.5))),
        left_grip=left_grip,
        right_grip=right_grip,
        source=pb.INPUT_SOURCE_REPLAY,
    )


def robot_state(robot: str, q: list[float]) -> pb.RobotState:
    return pb.RobotState(
        robot=robot, joint_names=JOINTS, joint_positions=q, status=pb.MOTION_STATUS_HOLDING
    )


JOINTS = ["j1_base_yaw", "j2_shoulder", "j3_elbow", "j4_wrist_pitch", "j5_wrist_roll"]


class Geometry:
    """The test's own pybullet world: the scenario's arms and a hand box, nothing else."""

    def __init__(self, scenario: Path) -> None:
        scen = sc.load(scenario, motion_check=False)
        self.c = p.connect(p.DIRECT)
        self.robots = {}
        for rid, robot in scen.robots.items():
            self.robots[rid] = p.loadURDF(
                str(scen.urdf_path(rid)),
                robot.base.xyz,
                yaw_quat_deg(robot.base.yaw),
                useFixedBase=True,
                physicsClientId=self.c,
            )
        shape = p.createCollisionShape(
            p.GEOM_BOX, halfExtents=[s / 2 for s in HAND_SIZE], physicsClientId=self.c
        )
        self.hand = p.createMultiBody(0.0, shape, -1, AWAY, physicsClientId=self.c)

    def pose(self, robot: str, q: list[float]) -> None:
        for j, v in enumerate(q):
            p.resetJointState(self.robots[robot], j, v, physicsClientId=self.c)

    def point_on(self, robot: str, link: int, along: float) -> tuple[float, float, float]:
        s = p.getLinkState(
            self.robots[robot], link, computeForwardKinematics=True, physicsClientId=self.c
        )
        pos, rot = s[4], s[5]
        m = p.getMatrixFromQuaternion(rot)
        return (pos[0] + m[2] * along, pos[1] + m[5] * along, pos[2] + m[8] * along)

    def hand_touches(self, robot: str, pos) -> bool:
        p.resetBasePositionAndOrientation(self.hand, pos, IDENTITY, physicsClientId=self.c)
        pts = p.getClosestPoints(self.hand, self.robots[robot], 0.0, physicsClientId=self.c)
        return any(pt[8] <= 0.0 for pt in pts)

    def link_distance(self, a: str, b: str) -> float:
        pts = p.getClosestPoints(self.robots[a], self.robots[b], 10.0, physicsClientId=self.c)
        return min(pt[8] for pt in pts)

    def close(self) -> None:
        p.disconnect(physicsClientId=self.c)


# ---------------------------------------------------------------------------------------- tests


def test_hand_path_into_a_robot_link_begins_and_ends_contact_on_time(physics_run) -> None:
    geo = Geometry(MINIMAL)
    q_r1 = [0.3, 0.4, 0.9, math.pi - 1.3 - 1.6, 0.0]  # tilted: the forearm leans over the board
    geo.pose("r1", q_r1)
    target = geo.point_on("r1", 2, 0.20)  # halfway along link3_forearm (joint index 2)
    n_in, n_hold, n_out = 100, 10, 100
    start = (target[0], target[1] - 0.40, target[2])

    def hand_at(k: int) -> tuple[float, float, float]:
        if k < n_in:  # 4 mm per tick along +y into the forearm
            s = k / n_in
        elif k < n_in + n_hold:
            s = 1.0
        else:
            s = max(0.0, 1.0 - (k - n_in - n_hold) / n_out)
        return (start[0], start[1] + 0.40 * s, start[2])

    ticks = n_in + n_hold + n_out + 20
    touching = [geo.hand_touches("r1", hand_at(k)) for k in range(ticks)]
    geo.close()
    k_touch = touching.index(True)
    k_leave = next(k for k in range(k_touch, ticks) if not touching[k])
    assert 0 < k_touch < n_in and k_touch < k_leave < ticks

    def human(k: int, t: float, role: Role) -> None:
        role.put(role.bus.keys.human_state(), human_state(left=hand_at(k)), k, t)

    def ik(k: int, t: float, role: Role) -> None:
        for rid, q in (("r1", q_r1), ("r2", [0.0] * 5)):
            role.put(role.bus.keys.robot_state(rid), robot_state(rid, q), k, t)

    run = physics_run(
        MINIMAL,
        ticks,
        {"human_input": human, "ik_cpp": ik, "orchestrator": None},
        observers=["logger"],
    )
    end = run.run()
    assert end.ok and end.ticks == ticks
    events = run.record.contact_events(pb.CONTACT_KIND_HAND_ROBOT)
    assert [(c.begin, c.a, c.b, c.link) for _, c in events] == [
        (True, "left", "r1", "link3_forearm"),
        (False, "left", "r1", "link3_forearm"),
    ]
    (t_begin, _), (t_end, _) = events
    # The hand input of tick k shows in the world of tick k + 1: the begin comes one tick after
    # the geometric touch of the path, the end one tick after it leaves (never later: the clock
    # waits for the inputs each ack announces).
    assert t_begin - k_touch == 1, (t_begin, k_touch)
    assert t_end - k_leave == 1, (t_end, k_leave)


def test_arms_driven_together_near_collide_before_their_links_meet(physics_run) -> None:
    geo = Geometry(MINIMAL)

    def q(k: int, robot: str) -> list[float]:
        a = min(0.006 * k, 1.5)  # the shoulders lean towards each other
        sign = 1.0 if robot == "r1" else -1.0  # both bases turned 180 degrees; r1 at +x
        return [0.0, sign * a, sign * 0.3, 0.0, 0.0]

    ticks = 260
    dist = []
    for k in range(ticks):
        geo.pose("r1", q(k, "r1"))
        geo.pose("r2", q(k, "r2"))
        dist.append(geo.link_distance("r1", "r2"))
    geo.close()
    margin = 0.05 + 0.05  # each arm inflated by its near_margin (default 5 cm)
    k_near = next(k for k, d in enumerate(dist) if d <= margin)
    k_meet = next(k for k, d in enumerate(dist) if d <= 0.0)
    assert k_near + 5 < k_meet

    def ik(k: int, t: float, role: Role) -> None:
        for rid in ("r1", "r2"):
            role.put(role.bus.keys.robot_state(rid), robot_state(rid, q(k, rid)), k, t)

    run = physics_run(MINIMAL, ticks, {"ik_cpp": ik})
    run.run()
    events = run.record.contact_events(pb.CONTACT_KIND_ROBOT_ROBOT)
    assert events, run.log()
    t_near, first = events[0]
    assert first.begin and (first.a, first.b) == ("r1", "r2")
    assert t_near - k_near == 1, (t_near, k_near)
    assert t_near <= k_meet  # the warning comes before the links intersect
    assert first.distance <= margin
    assert not run.record.contact_events(pb.CONTACT_KIND_HAND_ROBOT)  # no hands were sent


H1_START = (-0.20, -0.38, 0.02)  # minimal.toml
H1_TARGET = (-0.18, -0.02, 0.02)


def _path(points: list[tuple[int, tuple, float]]):
    """Piecewise-linear hand path: (tick, position, grip) keys; hold the last one."""

    def at(k: int) -> tuple[tuple[float, float, float], float]:
        for (k0, p0, g0), (k1, p1, _g1) in itertools.pairwise(points):
            if k0 <= k < k1:
                s = (k - k0) / (k1 - k0)
                return tuple(a + (b - a) * s for a, b in zip(p0, p1, strict=True)), g0  # type: ignore[return-value]
        return points[-1][1], points[-1][2]

    return at


def test_release_near_and_far_from_the_target(physics_run) -> None:
    near = (H1_TARGET[0] + 0.01, H1_TARGET[1], H1_TARGET[2])  # 1 cm beside the target
    far = (H1_TARGET[0] + 0.10, H1_TARGET[1], 0.08)  # 10 cm beside, 6 cm up
    path = _path(
        [
            (0, AWAY, 0.0),
            (20, H1_START, 0.0),
            (25, H1_START, 1.0),  # reach, close the hand
            (95, near, 1.0),
            (100, near, 0.0),  # carry, let go
            (160, (near[0], near[1], 0.10), 0.0),  # hand up and away...
            (200, near, 0.0),
            (205, near, 1.0),  # ...back, grab again
            (265, far, 1.0),
            (270, far, 0.0),  # carry, let go in the air
            (330, AWAY, 0.0),
        ]
    )

    def human(k: int, t: float, role: Role) -> None:
        pos, grip = path(k)
        role.put(role.bus.keys.human_state(), human_state(left=pos, left_grip=grip), k, t)

    def orchestrator(k: int, t: float, role: Role) -> None:
        if k == 0:
            cmd = pb.WorldCommand(set_grabbable=pb.SetGrabbable(object="H1", grabbable=True))
            role.put(role.bus.keys.world_commands(), pb.WorldCommands(commands=[cmd]), k, t)

    run = physics_run(MINIMAL, 420, {"human_input": human, "orchestrator": orchestrator})
    run.run()
    rec = run.record
    assert rec.objects[0].header.tick == 0 and rec.objects[0].full
    assert {o.id for o in rec.objects[0].objects} == {"H1", "RA1"}
    grabbed = rec.object_events(pb.ObjectEvent.KIND_GRABBED)
    released = rec.object_events(pb.ObjectEvent.KIND_RELEASED)
    rested = rec.object_events(pb.ObjectEvent.KIND_RESTED)
    assert [(e.object, e.holder) for _, e in grabbed] == [("H1", "left")] * 2
    assert [(e.object, e.holder) for _, e in released] == [("H1", "left")] * 2
    assert len(rested) == 2, run.log()
    # The grip closes at tick 25 (input), so the world of tick 26 has it held.
    assert grabbed[0][0] == 26
    (t_rel1, rel1), (t_rel2, rel2) = released
    assert t_rel1 == 101  # grip opened in the input of tick 100
    assert rel1.target_distance_m == pytest.approx(0.01, abs=1e-6)
    assert rel1.target_angle_deg == pytest.approx(0.0, abs=1e-6)
    (t_rest1, rest1), (t_rest2, rest2) = rested
    assert t_rel1 < t_rest1 < grabbed[1][0]
    assert rest1.pose.position.z == pytest.approx(0.02, abs=1e-3)
    assert rel2.target_distance_m == pytest.approx(math.hypot(0.10, 0.06), abs=2e-3)
    assert rel2.pose.position.z == pytest.approx(0.08, abs=1e-3)
    assert t_rest2 > t_rel2
    pos = rest2.pose.position
    assert pos.z == pytest.approx(0.02, abs=2e-3)  # size z / 2: resting on the board
    assert (pos.x, pos.y) == pytest.approx(far[:2], abs=0.01)
    # While held or falling it is published with every exchange (at most the scenario's
    # max_exchange_ticks); at rest, not at all.
    longest = DEFAULT_MAX_EXCHANGE_TICKS
    ticks_with_h1 = {m.header.tick for m in rec.objects for o in m.objects if o.id == "H1"}
    held = sorted(t for t in ticks_with_h1 if 26 <= t <= t_rel1)
    assert held and held[0] == 26 and t_rel1 - held[-1] <= longest
    assert all(b - a <= longest for a, b in itertools.pairwise(held)), held
    assert not ticks_with_h1 & set(range(t_rest1 + 1, grabbed[1][0]))


def test_bad_inputs_are_counted_and_the_run_goes_on(physics_run) -> None:
    stats: list[pb.ServiceStats] = []

    def human(k: int, t: float, role: Role) -> None:
        msg = human_state(left=(0.0, 0.0, 0.2))
        if k == 5:
            msg.left_hand.position.x = math.nan  # dropped at the door
        role.put(role.bus.keys.human_state(), msg, k, t)

    def orchestrator(k: int, t: float, role: Role) -> None:
        if k == 3:
            bad = pb.WorldCommands(
                commands=[
                    pb.WorldCommand(attach=pb.Attach(object="NOPE", holder="r1")),
                    pb.WorldCommand(
                        release=pb.Release(
                            object="H1", snap=True, pose=pose_to_pb(Pose((math.inf, 0.0, 0.0)))
                        )
                    ),
                    pb.WorldCommand(set_grabbable=pb.SetGrabbable(object="H1", grabbable=True)),
                ]
            )
            role.put(role.bus.keys.world_commands(), bad, k, t)
        if k == 30:
            stats.extend(role.bus.get(role.bus.keys.stats("physics"), pb.ServiceStats, timeout=5))

    run = physics_run(MINIMAL, 40, {"human_input": human, "orchestrator": orchestrator})
    end = run.run()
    assert end.ok and end.ticks == 40
    assert stats, "no stats from physics"
    errors = stats[0].decode_errors
    session = run.session
    assert errors[f"hrc/{session}/world/commands"] == 2
    assert errors[f"hrc/{session}/human/state"] == 1
    log = run.log()
    assert "unknown object 'NOPE'" in log and "'H1'" in log and "left_hand" in log
    # The good command of the same message was applied.
    states = [o for m in run.record.objects for o in m.objects if o.id == "H1"]
    assert states[-1].grabbable
