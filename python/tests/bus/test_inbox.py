"""Inputs reach the service in one order whatever order they arrived in."""

from __future__ import annotations

import random

from hrc.bus import Bus, BusConfig, Inbox
from hrc.wire import pb

from .conftest import free_port, wait_until


def _feed(session: str, order: list[tuple[str, int, int]]) -> list[tuple[str, int, int]]:
    """Publishes (sender, tick, value) in ``order``; returns what the inbox delivered at tick 2."""
    ep = f"tcp/127.0.0.1:{free_port()}"
    with (
        Bus(BusConfig(session=session, listen=[ep]), "svc") as me,
        Bus(BusConfig(session=session, connect=[ep]), "physics") as physics,
        Bus(BusConfig(session=session, connect=[ep]), "ik_cpp") as ik,
    ):
        inbox = Inbox(me)
        got: list[tuple[str, int, int]] = []
        inbox.add(
            me.keys.robot_states(),
            pb.RobotState,
            lambda _k, m: got.append((m.header.sender, m.header.tick, len(m.joint_positions))),
        )
        inbox.add(
            me.keys.world_objects(),
            pb.WorldObjects,
            lambda _k, m: got.append((m.header.sender, m.header.tick, len(m.objects))),
        )
        senders = {
            "physics": physics.publisher(me.keys.world_objects()),
            "ik_cpp": ik.publisher(me.keys.robot_state("r1")),
        }
        import time

        time.sleep(0.3)
        for sender, tick, value in order:
            if sender == "physics":
                senders[sender].put(pb.WorldObjects(objects=[pb.ObjectState()] * value), tick)
            else:
                senders[sender].put(pb.RobotState(joint_positions=[0.0] * value), tick)
        marks = [pb.PublishedMark(key=p.key, sender=s, seq=p.seq) for s, p in senders.items()]
        assert inbox.wait_for(marks, timeout=5) == []
        inbox.deliver(2, master="physics")
        return got


def test_delivery_order_is_independent_of_arrival_order(session_id: str) -> None:
    msgs = [
        ("physics", 0, 1),
        ("ik_cpp", 0, 2),
        ("physics", 1, 3),
        ("ik_cpp", 1, 4),
        ("physics", 2, 5),
        ("ik_cpp", 2, 6),
        ("ik_cpp", 3, 7),
    ]
    first = _feed(session_id, msgs)
    shuffled = msgs[:]
    random.Random(3).shuffle(shuffled)
    # per-sender order is what a real sender produces; keep it, interleave senders differently
    phys = [m for m in msgs if m[0] == "physics"]
    ik = [m for m in msgs if m[0] == "ik_cpp"]
    second = _feed(session_id + "b", ik + phys)
    assert first == second
    # ticks < 2 from everyone, tick 2 only from the clock master, nothing of tick 3
    assert ("physics", 2, 5) in first and ("ik_cpp", 2, 6) not in first
    assert all(t < 3 for _, t, _ in first)
    # by tick, then within a tick robot states (subscribed first) before world objects
    assert [(s, t) for s, t, _ in first] == [
        ("ik_cpp", 0),
        ("physics", 0),
        ("ik_cpp", 1),
        ("physics", 1),
        ("physics", 2),
    ]


def test_missing_marks_are_reported_after_the_timeout(session_id: str) -> None:
    ep = f"tcp/127.0.0.1:{free_port()}"
    with Bus(BusConfig(session=session_id, listen=[ep]), "svc") as me:
        inbox = Inbox(me)
        inbox.add(me.keys.human_state(), pb.HumanState, lambda _k, _m: None)
        mark = pb.PublishedMark(key=me.keys.human_state(), sender="human_input", seq=3)
        other = pb.PublishedMark(key=me.keys.task_events(), sender="orchestrator", seq=9)
        assert inbox.wait_for([mark, other], timeout=0.2) == [mark]  # other key: not subscribed
        assert wait_until(lambda: True)


def test_a_rejected_message_still_satisfies_its_mark(session_id: str) -> None:
    """Its sender published it; waiting for it must not hang the tick (it is dropped, counted)."""
    import math

    ep = f"tcp/127.0.0.1:{free_port()}"
    with (
        Bus(BusConfig(session=session_id, listen=[ep]), "svc") as me,
        Bus(BusConfig(session=session_id, connect=[ep]), "human_input") as human,
    ):
        inbox = Inbox(me)
        got: list[pb.HumanState] = []
        key = me.keys.human_state()
        inbox.add(
            key,
            pb.HumanState,
            lambda _k, m: got.append(m),
            validate=lambda m: "NaN" if math.isnan(m.left_grip) else None,
        )
        pub = human.publisher(key)
        import time

        time.sleep(0.3)
        pub.put(pb.HumanState(left_grip=math.nan), 0)
        pub.put(pb.HumanState(left_grip=0.5), 0)
        mark = pb.PublishedMark(key=key, sender="human_input", seq=pub.seq)
        assert inbox.wait_for([mark], timeout=5) == []
        inbox.deliver(1)
        assert [m.left_grip for m in got] == [0.5]
        assert me.stats.decode_errors[key] == 1
