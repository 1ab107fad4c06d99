"""A message the bus loses is asked of its sender again (docs/ARCHITECTURE.md, "Lost messages"):
real Zenoh sessions, one put of a real publisher swallowed before it reaches Zenoh."""

from __future__ import annotations

import logging
import threading

import pytest

from hrc.bus import Bus, ClockSettings, LockstepParticipant
from hrc.bus.bus import Publisher
from hrc.wire import pb

from .conftest import wait_until
from .test_clock import Session


class _Lossy:
    """Stands for a publisher's Zenoh publisher and loses its ``nth`` put (counted from 1)."""

    def __init__(self, inner: object, nth: int) -> None:
        self.inner = inner
        self.nth = nth
        self.puts = 0
        self.lost = 0

    def put(self, *args: object, **kwargs: object) -> None:
        self.puts += 1
        if self.puts == self.nth:
            self.lost += 1
            return
        self.inner.put(*args, **kwargs)  # type: ignore[attr-defined]

    def undeclare(self) -> None:
        self.inner.undeclare()  # type: ignore[attr-defined]


def _lose(pub: Publisher[pb.RobotState], nth: int) -> _Lossy:
    lossy = _Lossy(pub._pub, nth)
    pub._pub = lossy  # type: ignore[assignment]
    return lossy


def test_an_output_the_bus_lost_is_got_from_its_sender_and_the_run_goes_on(
    session_id: str, caplog: pytest.LogCaptureFixture
) -> None:
    # the clock master waits for what an ack vouches for: without the replay the run ends
    # "acknowledged but never arrived" after the barrier timeout
    settings = ClockSettings(ticks=30, participants=["ik_cpp"], observers=[], barrier_timeout_s=8)
    s = Session(session_id, settings, ["ik_cpp"])
    try:
        bus = s.buses["ik_cpp"]
        out_key = bus.keys.robot_state("r1")
        out = bus.publisher(out_key)
        ack = bus.publisher(bus.keys.clock_ack("ik_cpp"), express=True)
        lossy = _lose(out, 6)

        def on_clock(_k: str, tick: pb.ClockTick) -> None:
            k = tick.header.tick
            out.put(pb.RobotState(robot="r1"), k)
            mark = pb.PublishedMark(key=out_key, sender="ik_cpp", seq=out.seq)
            ack.put(pb.TickAck(participant="ik_cpp", published=[mark]), k)

        bus.subscribe(bus.keys.clock(), pb.ClockTick, on_clock)
        bus.serve_replay()
        bus.declare_token()
        applied: list[int] = []
        stepped: list[tuple[int, list[int]]] = []
        s.clock.input(out_key, pb.RobotState, lambda _k, m: applied.append(m.header.tick))
        s.clock.start()
        with caplog.at_level(logging.WARNING, logger="hrc.bus.inbox"):
            end = s.clock.run(lambda k, t: None, lambda k, t: stepped.append((k, list(applied))))
        assert lossy.lost == 1
        assert end.ok and end.ticks == 30, end.reason
        # every output once, in its tick, the lost one too
        for k, seen in stepped:
            assert seen == list(range(k + 1)), (k, seen)
        assert s.clock.inbox.recovered == 1
        said = [r.getMessage() for r in caplog.records if "did not come within" in r.message]
        assert said and f"{out_key} #6 from 'ik_cpp' did not come" in said[0], said
        assert "sent #6-#6 again, 1 of them new" in said[0], said
    finally:
        s.close()


def test_a_participant_gets_a_lost_input_from_its_sender_and_the_run_goes_on(
    session_id: str,
) -> None:
    # r1's state goes from one participant to another; the clock master does not read it, so
    # only the reader's wait (its clock tick lists the state) can notice the loss
    names = ["ik_cpp", "orchestrator"]
    settings = ClockSettings(ticks=40, participants=names, observers=[], barrier_timeout_s=8)
    s = Session(session_id, settings, names)
    try:
        writer = LockstepParticipant(s.buses["ik_cpp"], input_timeout_s=8)
        reader = LockstepParticipant(s.buses["orchestrator"], input_timeout_s=8)
        out = s.buses["ik_cpp"].publisher(s.buses["ik_cpp"].keys.robot_state("r1"))
        writer.on_tick(lambda t: out.put(pb.RobotState(robot="r1"), t.header.tick))
        got: list[int] = []
        seen: list[tuple[int, list[int]]] = []
        reader.input(out.key, pb.RobotState, lambda _k, m: got.append(m.header.tick))
        reader.on_tick(lambda t: seen.append((t.header.tick, list(got))))
        writer.start()
        reader.start()
        lossy = _lose(out, 11)
        ends: dict[str, object] = {}
        threads = [
            threading.Thread(target=lambda p=p, n=n: ends.__setitem__(n, p.run(30)))
            for n, p in (("ik_cpp", writer), ("orchestrator", reader))
        ]
        for th in threads:
            th.start()
        s.clock.start()
        end = s.clock.run(lambda k, t: None, lambda k, t: None)
        for th in threads:
            th.join(15)
        assert lossy.lost == 1
        assert end.ok and end.ticks == 40, end.reason
        assert all(e.ok for e in ends.values()), ends  # type: ignore[attr-defined]
        assert [k for k, _ in seen] == list(range(40))
        for k, before in seen:  # the outputs of every earlier tick, the lost one too, once
            assert before == list(range(k)), (k, before)
        assert reader.inbox.recovered >= 1
    finally:
        s.close()


def test_a_sender_replays_only_what_it_still_holds_from_the_seq_asked(session_id: str) -> None:
    s = Session(session_id, ClockSettings(ticks=1), ["ik_cpp"])
    try:
        bus: Bus = s.buses["ik_cpp"]
        out = bus.publisher(bus.keys.robot_state("r1"))
        for k in range(5):
            out.put(pb.RobotState(robot="r1"), k)
        bus.serve_replay()
        asker = s.master_bus
        # (the link and the queryable come up a moment after the sessions open)
        assert wait_until(lambda: bool(asker.replay(out.key, "ik_cpp", 2, timeout=1)), 30)
        items = asker.replay(out.key, "ik_cpp", 2, timeout=5)
        seqs = [pb.RobotState.FromString(i).header.seq for i in items]
        assert seqs == [3, 4, 5]
        assert asker.replay(out.key, "ik_cpp", 5, timeout=5) == []
        assert asker.replay(bus.keys.robot_state("r2"), "ik_cpp", 0, timeout=5) == []
        out._recent.popleft()  # seq 1 no longer held: a replay from 0 would have a hole
        assert asker.replay(out.key, "ik_cpp", 0, timeout=5) == []
    finally:
        s.close()
