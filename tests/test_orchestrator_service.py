"""The orchestrator process on a real bus: a stand-in clock master (world) and a stand-in IK
participant drive `python -m hrc_orchestrator` through scenarios/minimal.toml to the end.

Checks the service wiring: the scenario is served, inputs reach the task each tick, commands,
events and cues are published, the task's stop request ends the run, metrics.json is written and
the final metrics are published.
"""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import uuid
from pathlib import Path

import pytest

from hrc import scenario as sc
from hrc.bus import Bus, BusConfig, ClockMaster, ClockSettings, LockstepParticipant
from hrc.ports import free_port
from hrc.wire import pb

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "services" / "orchestrator" / "tests"))
from orch_fakes import FakeRobot  # noqa: E402

pytestmark = pytest.mark.slow


class FakeWorld:
    """Physics stand-in: the participant grabs H1 once it is grabbable and places it on target."""

    def __init__(self, scenario: sc.Scenario) -> None:
        self.scenario = scenario
        self.grabbable: dict[str, bool] = {}
        self.commands: list[pb.WorldCommand] = []
        self.grab_tick: int | None = None
        self.released = False
        self.lock = threading.Lock()

    def on_commands(self, _key: str, msg: pb.WorldCommands) -> None:
        with self.lock:
            self.commands.extend(msg.commands)
            for c in msg.commands:
                if c.HasField("set_grabbable"):
                    self.grabbable[c.set_grabbable.object] = c.set_grabbable.grabbable

    def world(self, k: int) -> tuple[list[pb.ObjectEvent], list[pb.Contact]]:
        events: list[pb.ObjectEvent] = []
        contacts: list[pb.Contact] = []
        if k == 0:
            contacts.append(
                pb.Contact(kind=pb.CONTACT_KIND_HAND_ENVELOPE, begin=True, a="right", b="0")
            )
        with self.lock:
            if self.grab_tick is None and self.grabbable.get("H1") and k >= 20:
                self.grab_tick = k
                events.append(
                    pb.ObjectEvent(kind=pb.ObjectEvent.KIND_GRABBED, object="H1", holder="right")
                )
            elif self.grab_tick is not None and not self.released and k >= self.grab_tick + 120:
                self.released = True
                target = self.scenario.part("H1").target.xyz
                e = pb.ObjectEvent(kind=pb.ObjectEvent.KIND_RELEASED, object="H1", holder="right")
                e.pose.position.x, e.pose.position.y, e.pose.position.z = target
                e.pose.orientation.w = 1.0
                events.append(e)
        return events, contacts


def test_orchestrator_runs_minimal_over_the_bus(tmp_path: Path) -> None:
    scenario_path = ROOT / "scenarios" / "minimal.toml"
    scenario = sc.load(scenario_path, motion_check=False)
    session = f"o{uuid.uuid4().hex[:8]}"
    ep = f"tcp/127.0.0.1:{free_port()}"
    master = Bus(BusConfig(session=session, listen=[ep]), "physics")
    ik_bus = Bus(BusConfig(session=session, connect=[ep]), "ik_cpp")
    log_path = tmp_path / "orchestrator.log"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "hrc_orchestrator",
            "--session",
            session,
            "--connect",
            ep,
            "--scenario",
            str(scenario_path),
            "--out",
            str(tmp_path),
            "--no-reach-check",
            "--seed",
            "5",
        ],
        stdout=open(log_path, "wb"),
        stderr=subprocess.STDOUT,
    )
    try:
        served = master.get_one(master.keys.scenario(), pb.Scenario, timeout=30)
        assert served.info.name == "minimal" and served.info.seed == 5
        dt = 1.0 / served.info.tick_hz

        # --- the IK stand-in: follows commands, publishes a state per robot every tick
        robots = {
            rid: FakeRobot(rid, tuple(r.home), r.max_tcp_speed, dt)
            for rid, r in scenario.robots.items()
        }
        ik = LockstepParticipant(ik_bus)
        state_pubs = {rid: ik_bus.publisher(ik_bus.keys.robot_state(rid)) for rid in robots}
        ik.input(
            ik_bus.keys.robot_commands(),
            pb.RobotCommand,
            lambda _k, cmd: robots[cmd.robot].command(cmd),
        )

        def ik_step(tick: pb.ClockTick) -> None:
            for rid in sorted(robots):
                state_pubs[rid].put(robots[rid].tick(), tick.header.tick, tick.header.sim_time)

        ik.on_tick(ik_step)
        ik.start()
        ik_thread = threading.Thread(target=ik.run, daemon=True)
        ik_thread.start()

        # --- the clock master / world stand-in
        world = FakeWorld(scenario)
        events: list[pb.TaskEvent] = []
        cues: list[pb.Cue] = []
        final: list[pb.MetricsReport] = []
        clock = ClockMaster(
            master,
            ClockSettings(
                tick_hz=served.info.tick_hz,
                ticks=20_000,
                participants=["ik_cpp", "orchestrator"],
                observers=[],
                barrier_timeout_s=20,
            ),
        )
        clock.input(master.keys.world_commands(), pb.WorldCommands, world.on_commands)
        master.subscribe(master.keys.task_events(), pb.TaskEvent, lambda _k, m: events.append(m))
        master.subscribe(
            master.keys.task_indicators(), pb.Indicators, lambda _k, m: cues.extend(m.cues)
        )
        master.subscribe(
            master.keys.task_metrics(),
            pb.MetricsReport,
            lambda _k, m: final.append(m) if m.final else None,
        )
        objects_pub = master.publisher(master.keys.world_objects())
        contacts_pub = master.publisher(master.keys.world_contacts())

        def publish_world(k: int, t: float) -> None:
            evs, contacts = world.world(k)
            if evs or k == 0:
                objects_pub.put(pb.WorldObjects(events=evs, full=k == 0), k, t)
            if contacts:
                contacts_pub.put(pb.WorldContacts(contacts=contacts), k, t)

        clock.start()
        end = clock.run(publish_world, lambda k, t: None)
        assert end.ok, end.reason
        assert end.reason.startswith("stopped") and "task finished" in end.reason
        assert proc.wait(timeout=30) == 0
        ik_thread.join(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        ik_bus.close()
        master.close()
    log_text = log_path.read_text(errors="replace")
    kinds = [pb.TaskEventKind.Name(e.kind) for e in events]
    assert kinds[0] == "TASK_EVENT_KIND_TASK_STARTED", log_text[-2000:]
    # TASK FINISHED at the last placement; only the robots' trips home follow
    finished = [e for e in events if e.kind == pb.TASK_EVENT_KIND_TASK_FINISHED]
    assert len(finished) == 1 and finished[0].text.endswith("TASK FINISHED. 0 total collisions.")
    after = kinds[kinds.index("TASK_EVENT_KIND_TASK_FINISHED") + 1 :]
    assert set(after) <= {"TASK_EVENT_KIND_ROBOT_PHASE"}
    assert kinds.count("TASK_EVENT_KIND_PART_PLACED") == 3
    assert {c.id for c in cues} >= {"outline:H1", "target:H1", "target:RA1", "target:S1"}
    assert any(w.HasField("spawn") for w in world.commands)
    data = json.loads((tmp_path / "metrics.json").read_text())
    assert data["seed"] == 5 and data["run"]["mode"] == "lockstep"
    assert data["run"]["ticks"] == end.ticks
    assert data["task"]["completion_s"] > 0
    assert data["parts"]["S1"]["placed_s"] >= data["parts"]["H1"]["placed_s"]
    assert final and final[-1].metrics.task.completion_s == pytest.approx(
        data["task"]["completion_s"]
    )
