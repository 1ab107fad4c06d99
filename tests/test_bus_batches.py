"""Batches (docs/ARCHITECTURE.md, "Batches"): what one exchange publishes on a key goes out in one
put, and receivers see the messages one by one, each with its own tick and seq. Two real Zenoh
sessions on loopback."""

from __future__ import annotations

import threading
import uuid

import zenoh

from hrc.bus import Bus, BusConfig
from hrc.bus.bus import BATCH_SUFFIX
from hrc.ports import free_port
from hrc.wire import pb

from .conftest import wait_until


def _pair() -> tuple[Bus, Bus]:
    session, port = f"bt{uuid.uuid4().hex[:8]}", free_port()
    sender = Bus(BusConfig(session=session, listen=[f"tcp/127.0.0.1:{port}"]), "human_input")
    receiver = Bus(
        BusConfig(session=session, mode="client", connect=[f"tcp/127.0.0.1:{port}"], listen=[]),
        "physics",
    )
    return sender, receiver


def test_an_exchange_goes_out_in_one_put_and_arrives_message_by_message() -> None:
    sender, receiver = _pair()
    with sender, receiver:
        key = sender.keys.human_state()
        got: list[tuple[int, int, float]] = []
        probes: list[int] = []
        puts: list[bytes] = []
        lock = threading.Lock()

        def on_state(_k: str, msg: pb.HumanState) -> None:
            with lock:
                if msg.header.tick == 0:  # the probes that show the route is up
                    probes.append(msg.header.seq)
                else:
                    got.append((msg.header.tick, msg.header.seq, msg.left_grip))

        receiver.subscribe(key, pb.HumanState, on_state)

        def on_put(sample: zenoh.Sample) -> None:
            att = sample.attachment.to_bytes() if sample.attachment is not None else b""
            if not att.endswith(BATCH_SUFFIX):
                single = pb.HumanState()
                single.ParseFromString(sample.payload.to_bytes())
                if single.header.tick == 0:
                    return  # a probe
            puts.append(att)

        # a raw subscriber counts the puts (not the probes) and sees the batch mark
        receiver.session.declare_subscriber(key, on_put)
        pub = sender.publisher(key)
        probe = pb.HumanState(left_grip=0.0)
        assert wait_until(lambda: pub.put(probe, 0) > 0 and bool(probes), 10, 0.1)
        seq0 = pub.seq
        assert wait_until(lambda: probes[-1] == seq0, 5)  # every probe is in
        sender.begin_batch()
        for i in range(5):
            pub.put(pb.HumanState(left_grip=0.1 * i), 10 + i, (10 + i) / 240)
        assert not puts  # held back until the flush
        sender.flush_batches()
        # (the two subscribers' callbacks run one after the other: wait for both)
        assert wait_until(lambda: len(got) == 5 and len(puts) >= 1, 10), (got, puts)
        assert puts == [b"human_input" + BATCH_SUFFIX]
        assert [(t, s) for t, s, _ in got] == [(10 + i, seq0 + 1 + i) for i in range(5)]
        assert [round(g, 6) for _, _, g in got] == [round(0.1 * i, 6) for i in range(5)]
        # a single message goes as it is
        sender.begin_batch()
        pub.put(pb.HumanState(left_grip=1.0), 20)
        sender.flush_batches()
        assert wait_until(lambda: len(got) == 6 and len(puts) >= 2, 10), (got, puts)
        assert puts == [b"human_input" + BATCH_SUFFIX, b"human_input"]


def test_a_batch_that_does_not_decode_is_counted_against_its_sender() -> None:
    sender, receiver = _pair()
    with sender, receiver:
        key = sender.keys.human_state()
        receiver.subscribe(key, pb.HumanState, lambda _k, _m: None)

        def garbage_counted() -> bool:
            sender.session.put(key, b"\xff" * 12, attachment=b"garbler" + BATCH_SUFFIX)
            return receiver.stats.decode_errors.get(key, 0) >= 1

        assert wait_until(garbage_counted, 10, 0.2)
