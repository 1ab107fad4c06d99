"""The contact -> reaction bound, in simulated time, with the five real services.

A hand touches a robot (the scripted participant provokes it); the robots' new command must be in
effect within one thesis frame (1/90 s) of simulated time: from the tick whose world state first
holds the contact (the ``world/contacts`` message that reports it) to the tick whose robot state,
the first computed under a new command, physics applies. The exchange step may be large far from
the hands; near them it must shrink so that this holds (docs/ARCHITECTURE.md, "Exchange step").

The test joins the trial as one more observer physics waits for (so it misses nothing), acking the
clock as every observer does (lockstep keeps the clock within a window of an observer's acks), and
records every contact and robot state with its tick.
"""

from __future__ import annotations

import threading
import uuid
from pathlib import Path

import pytest

from hrc.bus import Bus, access
from hrc.bus.bus import Publisher
from hrc.paths import ik_binary
from hrc.ports import free_port
from hrc.trial import TrialOptions, TrialResult, run_trial
from hrc.wire import pb

from .goldens import THESIS

ROOT = Path(__file__).resolve().parents[1]
TICK_HZ = 240
THESIS_FRAME_S = 1.0 / 90.0
WATCHER = "reactionwatch"

pytestmark = [
    pytest.mark.e2e,
    pytest.mark.skipif(
        not ik_binary().exists(), reason=f"the IK service binary {ik_binary()} is missing"
    ),
]


def provoking_scenario(tmp: Path) -> Path:
    text = THESIS.read_text()
    assert "provoke_collisions = false" in text
    path = tmp / "thesis-provoke.toml"
    path.write_text(text.replace("provoke_collisions = false", "provoke_collisions = [3.0, 9.0]"))
    return path


def test_robots_react_to_a_hand_contact_within_one_thesis_frame(tmp_path: Path) -> None:
    session, port = f"rb{uuid.uuid4().hex[:8]}", free_port()
    lock = threading.Lock()
    contacts: list[tuple[int, str]] = []  # (tick, robot) of each hand-robot contact begin
    states: list[tuple[int, str, int]] = []  # (tick, robot, command_id)
    spans: list[int] = []
    acks: list[Publisher[pb.TickAck]] = []

    def on_contacts(_key: str, msg: pb.WorldContacts) -> None:
        with lock:
            for c in msg.contacts:
                if c.kind == pb.CONTACT_KIND_HAND_ROBOT and c.begin:
                    contacts.append((msg.header.tick, c.b))

    def on_state(_key: str, msg: pb.RobotState) -> None:
        with lock:
            states.append((msg.header.tick, msg.robot, msg.command_id))

    def on_clock(_key: str, msg: pb.ClockTick) -> None:
        with lock:
            spans.append(max(1, msg.span))
        if acks:  # received: the clock may go on (docs/ARCHITECTURE.md, "Observers")
            acks[0].put(pb.TickAck(participant=WATCHER), msg.header.tick, msg.header.sim_time)

    result: list[TrialResult] = []
    opts = TrialOptions(
        scenario=provoking_scenario(tmp_path),
        session=session,
        port=port,
        max_ticks=12 * TICK_HZ,
        # physics waits for this test's token too, so it misses no message
        extra={"physics": ["--observers", f"logger,{WATCHER}"]},
    )
    runner = threading.Thread(target=lambda: result.append(run_trial(opts, tmp_path / "trial")))
    runner.start()
    try:
        with Bus(access.join(session, port), WATCHER) as bus:
            bus.subscribe(bus.keys.world_contacts(), pb.WorldContacts, on_contacts)
            bus.subscribe(bus.keys.robot_states(), pb.RobotState, on_state)
            acks.append(bus.publisher(bus.keys.clock_ack(WATCHER)))
            bus.subscribe(bus.keys.clock(), pb.ClockTick, on_clock)
            bus.declare_token()
            runner.join(300)
    finally:
        runner.join(30)
    assert result and result[0].ok, result[0].message if result else "the trial never ended"
    assert max(spans) > 1, "the exchange never grew past one tick: nothing to show"
    assert contacts, "the participant never touched a robot"
    states.sort()
    for tick, robot in contacts:
        before = [cid for t, r, cid in states if r == robot and t <= tick]
        in_force = before[-1] if before else 0
        new = [t for t, r, cid in states if r == robot and t > tick and cid != in_force]
        assert new, f"robot {robot} never got a new command after the contact at tick {tick}"
        delay_s = (new[0] - tick) / TICK_HZ
        assert delay_s <= THESIS_FRAME_S, (
            f"contact with {robot} at tick {tick}: new command in effect at tick {new[0]} "
            f"({delay_s * 1000:.1f} ms > {THESIS_FRAME_S * 1000:.1f} ms)"
        )
