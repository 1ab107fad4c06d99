"""The tick protocol with a real clock master and real participants (threads, real Zenoh)."""

from __future__ import annotations

import threading
import time

import pytest

from hrc.bus import (
    Bus,
    BusConfig,
    ClockFollower,
    ClockMaster,
    ClockSettings,
    LockstepParticipant,
    Observer,
    Outcome,
)
from hrc.bus.clock import RUN_END_RECEIVED
from hrc.wire import pb

from .conftest import free_port, wait_until


class Session:
    def __init__(self, session: str, settings: ClockSettings, names: list[str]) -> None:
        self.ep = f"tcp/127.0.0.1:{free_port()}"
        self.master_bus = Bus(BusConfig(session=session, listen=[self.ep]), "physics")
        self.clock = ClockMaster(self.master_bus, settings)
        self.buses = {n: Bus(BusConfig(session=session, connect=[self.ep]), n) for n in names}

    def close(self) -> None:
        for b in self.buses.values():
            b.close()
        self.master_bus.close()


def _run_participants(
    s: Session, steps: dict[str, list[int]], only: list[str] | None = None
) -> dict[str, object]:
    outcomes: dict[str, object] = {}
    threads = []
    for name, bus in s.buses.items():
        if only is not None and name not in only:
            continue
        p: ClockFollower = Observer(bus) if name == "logger" else LockstepParticipant(bus)
        seen = steps.setdefault(name, [])
        p.on_tick(lambda t, seen=seen: seen.append(t.header.tick))
        p.start()
        th = threading.Thread(target=lambda p=p, name=name: outcomes.__setitem__(name, p.run(30)))
        th.start()
        threads.append(th)
    s._threads = threads  # type: ignore[attr-defined]
    return outcomes


def test_lockstep_runs_every_tick_through_every_participant(session_id: str) -> None:
    names = ["ik_cpp", "orchestrator", "human_input", "logger"]
    s = Session(session_id, ClockSettings(ticks=300), names)
    try:
        steps: dict[str, list[int]] = {}
        outcomes = _run_participants(s, steps)
        world: list[int] = []
        s.clock.start()
        end = s.clock.run(lambda k, t: world.append(k), lambda k, t: None)
        for th in s._threads:  # type: ignore[attr-defined]
            th.join(10)
        assert end.ok and end.ticks == 300 and end.reason == "ticks"
        for n in names:
            assert steps[n] == list(range(300)), n
            assert outcomes[n].ok  # type: ignore[attr-defined]
        assert world == list(range(300))
    finally:
        s.close()


def test_realtime_never_runs_ahead_of_the_wall_clock(session_id: str) -> None:
    s = Session(
        session_id,
        ClockSettings(mode="realtime", tick_hz=200, ticks=60, observers=[]),
        ["ik_cpp", "orchestrator", "human_input"],
    )
    try:
        _run_participants(s, {})
        s.clock.start()
        t0 = time.monotonic()
        end = s.clock.run(lambda k, t: None, lambda k, t: None)
        assert end.ok and end.ticks == 60
        assert time.monotonic() - t0 >= 59 / 200
        assert end.realtime_factor <= 1.05
    finally:
        s.close()


def test_realtime_exchanges_span_at_most_a_headset_frame_and_every_tick_is_stepped(
    session_id: str,
) -> None:
    """At 240 Hz an exchange spans two ticks (1/90 s holds 2.67) where the service allows 32;
    one where it allows one (a hand near an arm); the participants step each tick of an
    exchange, and the run keeps the wall clock's pace."""
    s = Session(
        session_id,
        ClockSettings(mode="realtime", tick_hz=240, ticks=120, observers=[]),
        ["ik_cpp", "orchestrator", "human_input"],
    )
    try:
        steps: dict[str, list[int]] = {}
        _run_participants(s, steps)
        world: list[int] = []
        asked: list[tuple[int, int]] = []

        def span(k: int, n: int) -> int:
            asked.append((k, n))
            return 1 if 60 <= k < 70 else n  # near an arm for ten ticks

        s.clock.start()
        t0 = time.monotonic()
        end = s.clock.run(lambda k, t: world.append(k), lambda k, t: None, span, max_span=32)
        for th in s._threads:  # type: ignore[attr-defined]
            th.join(10)
        assert end.ok and end.ticks == 120, end
        assert s.clock.realtime_max_span() == 2
        assert all(n <= 2 for _, n in asked), asked
        # the exchanges, as the ticks that opened them: two ticks long but near the arm (and
        # the first ticks' reaction chain, see DeclaredEvents)
        ends = [*world[1:], 120]
        spans = {a: b - a for a, b in zip(world, ends, strict=True)}
        assert set(spans.values()) == {1, 2}, spans
        assert all(spans.get(k, 1) == 1 for k in range(60, 70)), spans
        assert sum(n == 2 for n in spans.values()) >= 50, spans
        assert s.clock.exchanges == len(world)
        # every tick of an exchange, in order (a late participant may not have reached the last
        # ones when the run ends: realtime does not wait for it)
        for name in ("ik_cpp", "orchestrator", "human_input"):
            assert steps[name] == list(range(len(steps[name]))), name
            assert len(steps[name]) >= 60, (name, len(steps[name]))
        assert time.monotonic() - t0 >= 118 / 240
    finally:
        s.close()


def test_a_silent_participant_is_named_when_the_barrier_times_out(session_id: str) -> None:
    # The timeout is long enough for the two that answer to ack tick 0 on a loaded machine
    # (at 0.5 s, a CI run beside two live trials named ik_cpp: its thread was that late too).
    s = Session(
        session_id,
        ClockSettings(ticks=100, barrier_timeout_s=4.0, observers=[]),
        ["ik_cpp", "orchestrator", "human_input"],
    )
    try:
        _run_participants(s, {}, only=["ik_cpp", "orchestrator"])
        # human_input announces itself but never acks
        s.buses["human_input"].declare_token()
        s.clock.start()
        end = s.clock.run(lambda k, t: None, lambda k, t: None)
        assert not end.ok
        assert end.failed_participant == "human_input"
        assert "human_input" in end.reason and "not responding" in end.reason
    finally:
        s.close()


def test_realtime_a_participant_that_stops_answering_ends_the_run_naming_it(
    session_id: str,
) -> None:
    # As above: the two that answer must not miss 3 s of barriers on a loaded machine.
    s = Session(
        session_id,
        ClockSettings(mode="realtime", tick_hz=100, ticks=0, barrier_timeout_s=3.0, observers=[]),
        ["ik_cpp", "orchestrator", "human_input"],
    )
    try:
        _run_participants(s, {}, only=["ik_cpp", "orchestrator"])
        s.buses["human_input"].declare_token()  # alive, never acks
        s.clock.start()
        t0 = time.monotonic()
        end = s.clock.run(lambda k, t: None, lambda k, t: None)
        assert not end.ok and end.failed_participant == "human_input"
        assert "human_input" in end.reason and "realtime" in end.reason
        assert time.monotonic() - t0 < 15.0  # not forever: about the barrier timeout
        # Every barrier the run reached was missed: ticks 0 .. end.ticks (the last one unapplied).
        # (Not a count from the wall time: a loaded machine runs fewer ticks in 3 s.)
        assert end.ticks >= 1
        assert end.deadline_misses["human_input"] == end.ticks + 1
    finally:
        s.close()


def test_realtime_names_the_participant_that_stopped_first_when_several_are_over_at_once(
    session_id: str,
) -> None:
    """human_input never answers; ik_cpp is held up 2 s from tick 5 and the clock itself 1 s at
    tick 6 (a loaded machine; in a deployment, the acks of the others queue behind a router that
    cannot deliver to the stopped one). At the next barrier both are over the timeout: the one
    named is human_input, which stopped first, not ik_cpp, first in the participants' list."""
    s = Session(
        session_id,
        ClockSettings(mode="realtime", tick_hz=100, ticks=0, barrier_timeout_s=0.5, observers=[]),
        ["ik_cpp", "orchestrator", "human_input"],
    )
    try:
        _run_participants(s, {}, only=["orchestrator"])
        held = LockstepParticipant(s.buses["ik_cpp"])
        held.on_tick(lambda t: time.sleep(2.0) if t.header.tick == 5 else None)
        held.start()
        threading.Thread(target=held.run, args=(30,), daemon=True).start()
        s.buses["human_input"].declare_token()  # alive, never acks
        s.clock.start()
        end = s.clock.run(lambda k, t: None, lambda k, t: time.sleep(1.0) if k == 6 else None)
        assert not end.ok and end.failed_participant == "human_input", end.reason
        assert "last ack: tick -1" in end.reason
    finally:
        s.close()


def test_a_vanished_participant_ends_the_run_naming_it(session_id: str) -> None:
    s = Session(
        session_id,
        ClockSettings(ticks=0, observers=["logger"]),
        ["ik_cpp", "orchestrator", "human_input", "logger"],
    )
    try:
        steps: dict[str, list[int]] = {}
        _run_participants(s, steps)
        s.clock.start()
        threading.Timer(0.5, s.buses["logger"].close).start()
        end = s.clock.run(lambda k, t: None, lambda k, t: None)
        assert not end.ok and end.failed_participant == "logger"
        assert "left the bus" in end.reason
    finally:
        s.close()


def test_an_abort_before_every_service_came_up_ends_the_start_naming_the_service(
    session_id: str,
) -> None:
    """hrc run saw human_input's process end before it came up: its abort ends the start at
    once (the clock master waited for every token first, up to the start timeout)."""
    s = Session(
        session_id,
        ClockSettings(ticks=0, observers=[], start_timeout_s=30.0),
        ["ik_cpp", "orchestrator", "experimenter"],
    )
    try:
        steps: dict[str, list[int]] = {}
        _run_participants(s, steps, only=["ik_cpp", "orchestrator"])  # human_input never comes
        hrc_run = s.buses["experimenter"]
        abort = pb.RunControl(
            command=pb.RunControl.COMMAND_ABORT,
            reason="service 'human_input' exited with code 2",
            failed_service="human_input",
        )
        s.clock.start()
        threading.Timer(
            0.5, lambda: hrc_run.publisher(hrc_run.keys.run_control(hrc_run.sender)).put(abort)
        ).start()
        t0 = time.monotonic()
        end = s.clock.run(lambda k, t: None, lambda k, t: None)
        assert not end.ok and end.failed_participant == "human_input", end
        assert end.reason == "service 'human_input' exited with code 2" and end.ticks == 0
        assert time.monotonic() - t0 < 20, "the start went on to its timeout"
    finally:
        s.close()


def test_a_stop_request_ends_the_run_cleanly(session_id: str) -> None:
    s = Session(
        session_id, ClockSettings(ticks=0, observers=[]), ["ik_cpp", "orchestrator", "human_input"]
    )
    try:
        steps: dict[str, list[int]] = {}
        _run_participants(s, steps)
        stop = s.buses["orchestrator"].publisher(
            s.buses["orchestrator"].keys.run_control(s.buses["orchestrator"].sender)
        )
        s.clock.start()

        def world(k: int, t: float) -> None:
            if k == 50:
                stop.put(pb.RunControl(command=pb.RunControl.COMMAND_STOP, reason="done"), k, t)

        end = s.clock.run(world, lambda k, t: None)
        assert end.ok and "stopped by orchestrator: done" in end.reason
        assert end.ticks > 50  # the request is handled at a tick boundary after it arrives
    finally:
        s.close()


def test_the_first_tick_waits_for_a_watcher_whose_leaving_ends_nothing(session_id: str) -> None:
    """hrc run's own session (a watcher): the run does not begin before its token, so a run of
    a few ticks cannot end before it listens; it takes no part in the run after that."""
    s = Session(
        session_id,
        ClockSettings(ticks=0, participants=["ik_cpp"], observers=[], watchers=["experimenter"]),
        ["ik_cpp", "experimenter"],
    )
    try:
        _run_participants(s, {}, only=["ik_cpp"])
        ik = s.buses["ik_cpp"]
        stop = ik.publisher(ik.keys.run_control(ik.sender))
        world: list[int] = []
        s.clock.start()
        ends: list[Outcome] = []
        runner = threading.Thread(
            target=lambda: ends.append(s.clock.run(lambda k, t: world.append(k), lambda k, t: None))
        )
        runner.start()
        assert wait_until(lambda: "ik_cpp" in s.clock._alive, 20), "ik_cpp never came up"
        time.sleep(0.5)  # (what must not happen: a tick without the watcher)
        assert world == [], f"ticked before the watcher came: {world[:5]}"
        watcher = s.buses["experimenter"]
        watcher.declare_token()
        assert wait_until(lambda: len(world) >= 10, 20), "no tick after the watcher came"
        left_at = len(world)
        watcher.close()  # it leaves: the run goes on
        assert wait_until(lambda: len(world) >= left_at + 200, 30), "the run stopped"
        stop.put(pb.RunControl(command=pb.RunControl.COMMAND_STOP, reason="done"))
        runner.join(30)
        assert ends and ends[0].ok and "stopped by ik_cpp: done" in ends[0].reason, ends
    finally:
        s.close()


def test_the_tick_transition_runs_on_the_ack_thread_when_nothing_is_missing(
    session_id: str,
) -> None:
    # Lockstep: whoever receives the last ack of a tick applies it and publishes the next one, so
    # in a plain run (outputs arrive before the acks that list them) the run() thread only waits.
    names = ["ik_cpp", "orchestrator", "human_input"]
    s = Session(session_id, ClockSettings(ticks=200, observers=[]), names)
    try:
        _run_participants(s, {})
        threads: list[str] = []
        s.clock.start()
        end = s.clock.run(
            lambda k, t: None, lambda k, t: threads.append(threading.current_thread().name)
        )
        assert end.ok and end.ticks == 200
        on_main = threads.count(threading.current_thread().name)
        assert on_main < 20, f"{on_main} of 200 transitions ran on the run() thread"
    finally:
        s.close()


def test_an_output_acked_before_it_arrives_is_waited_for_and_applied_in_its_tick(
    session_id: str,
) -> None:
    # The ack lists an output that is still on its way (published 20 ms after the ack): the clock
    # master must not apply the tick without it, whichever thread ends up doing the transition.
    s = Session(
        session_id, ClockSettings(ticks=30, participants=["ik_cpp"], observers=[]), ["ik_cpp"]
    )
    try:
        bus = s.buses["ik_cpp"]
        out_key = bus.keys.robot_state("r1")
        out = bus.publisher(out_key)
        ack = bus.publisher(bus.keys.clock_ack("ik_cpp"))

        def on_clock(_k: str, tick: pb.ClockTick) -> None:
            k = tick.header.tick
            mark = pb.PublishedMark(key=out_key, sender="ik_cpp", seq=out.seq + 1)
            ack.put(pb.TickAck(participant="ik_cpp", published=[mark]), k)
            threading.Timer(0.02, lambda: out.put(pb.RobotState(robot="r1"), k)).start()

        bus.subscribe(bus.keys.clock(), pb.ClockTick, on_clock)
        bus.declare_token()
        applied: list[int] = []
        stepped: list[tuple[int, list[int]]] = []
        s.clock.input(out_key, pb.RobotState, lambda _k, m: applied.append(m.header.tick))
        s.clock.start()
        end = s.clock.run(lambda k, t: None, lambda k, t: stepped.append((k, list(applied))))
        assert end.ok and end.ticks == 30, end.reason
        for k, seen in stepped:
            assert seen == list(range(k + 1)), (k, seen)  # tick k's output, and nothing later
    finally:
        s.close()


def test_an_output_acked_but_never_sent_ends_the_run_naming_it_and_what_came(
    session_id: str,
) -> None:
    # 4 s: on a loaded machine an ack of the ticks before must not be what times out
    settings = ClockSettings(ticks=30, participants=["ik_cpp"], observers=[], barrier_timeout_s=4.0)
    s = Session(session_id, settings, ["ik_cpp"])
    try:
        bus = s.buses["ik_cpp"]
        out_key = bus.keys.robot_state("r1")
        out = bus.publisher(out_key)
        ack = bus.publisher(bus.keys.clock_ack("ik_cpp"))

        def on_clock(_k: str, tick: pb.ClockTick) -> None:
            k = tick.header.tick
            if k < 5:
                out.put(pb.RobotState(robot="r1"), k)
                mark = pb.PublishedMark(key=out_key, sender="ik_cpp", seq=out.seq)
            else:  # vouches for a sixth state that never goes out
                mark = pb.PublishedMark(key=out_key, sender="ik_cpp", seq=out.seq + 1)
            ack.put(pb.TickAck(participant="ik_cpp", published=[mark]), k)

        bus.subscribe(bus.keys.clock(), pb.ClockTick, on_clock)
        bus.declare_token()
        s.clock.input(out_key, pb.RobotState, lambda _k, _m: None)
        s.clock.start()
        end = s.clock.run(lambda k, t: None, lambda k, t: None)
        assert not end.ok and end.failed_participant == "ik_cpp", end
        assert f"{out_key} #6 from 'ik_cpp' was acknowledged but never arrived" in end.reason
        assert "(received up to #5)" in end.reason, end.reason
    finally:
        s.close()


def test_a_participant_follows_the_clock_master_its_config_names(session_id: str) -> None:
    # hrc run passes --clock-master; the lost token of that service, not physics's, ends the run.
    ep = f"tcp/127.0.0.1:{free_port()}"
    master = Bus(BusConfig(session=session_id, listen=[ep]), "world")
    bus = Bus(BusConfig(session=session_id, connect=[ep], clock_master="world"), "ik_cpp")
    bystander = Bus(BusConfig(session=session_id, connect=[ep]), "physics")
    try:
        p = LockstepParticipant(bus)
        p.start()
        master.declare_token()
        bystander.declare_token()
        assert wait_until(lambda: {"world", "physics"} <= bus.alive_services(timeout=0.2), 10)
        time.sleep(0.2)  # the participant's own liveliness watch has seen both too
        bystander.close()  # not its clock master: nothing happens
        time.sleep(0.3)
        threading.Timer(0.2, master.close).start()
        outcome = p.run(10)
        assert not outcome.ok and outcome.reason == "the clock master 'world' disappeared"
    finally:
        bus.close()
        master.close()


@pytest.mark.parametrize("failing", ["human_input", "logger"])
def test_a_service_whose_step_raises_ends_the_run_at_once_naming_it(
    session_id: str, failing: str
) -> None:
    # human_input: a participant computing on the inline path (it has no inputs to wait for);
    # logger: an observer, computing on its run() thread.
    names = ["ik_cpp", "orchestrator", "human_input", "logger"]
    s = Session(session_id, ClockSettings(ticks=0, barrier_timeout_s=10.0), names)
    try:
        raised_at: list[float] = []
        outcomes: dict[str, Outcome] = {}
        returned_at: dict[str, float] = {}
        threads = []
        for name, bus in s.buses.items():
            p: ClockFollower = Observer(bus) if name == "logger" else LockstepParticipant(bus)
            if name == failing:

                def step(tick: pb.ClockTick) -> None:
                    if tick.header.tick == 50:
                        raised_at.append(time.monotonic())
                        raise ValueError("bad value in tick 50")

                p.on_tick(step)
            p.start()

            def follow(p: ClockFollower = p, n: str = name) -> None:
                outcomes[n] = p.run(30)
                returned_at[n] = time.monotonic()

            th = threading.Thread(target=follow)
            th.start()
            threads.append(th)
        s.clock.start()
        end = s.clock.run(lambda k, t: None, lambda k, t: None)  # lingers while they leave
        for th in threads:
            th.join(10)
        assert raised_at, "the step never raised"
        # The run has ended for everybody when the last service's run() has returned.
        took = max(returned_at.values()) - raised_at[0]
        print(
            f"{failing}: every service's run ended {took * 1e3:.1f} ms after its step raised",
            {n: round((t - raised_at[0]) * 1e3, 1) for n, t in returned_at.items()},
        )
        assert not end.ok and end.failed_participant == failing, end
        assert (
            f"aborted by {failing}: tick 50 failed: ValueError: bad value in tick 50" in end.reason
        ), end.reason
        assert took < 2.0
        failed = outcomes[failing]
        assert not failed.ok and failed.exit_code == 1
        assert "tick 50 failed: ValueError" in failed.reason
        assert failed.run_end is not None and failed.run_end.failed_participant == failing
        for n in names:
            assert not outcomes[n].ok, n  # everybody learns the run failed
    finally:
        s.close()


class _SlowReader(Observer):
    """An observer whose Zenoh thread takes 20 ms per clock message: what comes after waits in
    its link, as for a logger starved on a loaded machine."""

    got_end_at: float | None = None

    def _on_clock(self, key: str, tick: pb.ClockTick) -> None:
        if self.ended:  # (the test closes the bus then; the rest would fail to ack)
            return
        time.sleep(0.02)
        super()._on_clock(key, tick)

    def _on_run_end(self, key: str, end: pb.RunEnd) -> None:
        self.got_end_at = time.monotonic()
        super()._on_run_end(key, end)


def test_the_clock_master_stays_until_a_slow_observer_has_the_run_end(session_id: str) -> None:
    # Lockstep keeps the clock within 240 ticks of what the observer acked; reading those at
    # 20 ms each, the observer gets run/end about 4.8 s after the last tick, past the 3 s the
    # clock master waits for the others to leave. It stays while the observer's acks advance,
    # so its process (and link) cannot go before the observer has run/end: a link closed with
    # run/end still in the clock master's queue loses it.
    settings = ClockSettings(ticks=480, participants=[], observers=["logger"])
    s = Session(session_id, settings, ["logger"])
    try:
        observer = _SlowReader(s.buses["logger"])
        observer.start()
        outcome: list[Outcome] = []
        th = threading.Thread(target=lambda: outcome.append(observer.run(60)))
        th.start()
        s.clock.start()
        end = s.clock.run(lambda k, t: None, lambda k, t: None)
        left_at = time.monotonic()
        th.join(30)
        assert end.ok and end.ticks == 480, end
        assert outcome and outcome[0].ok, outcome
        assert observer.got_end_at is not None
        # the observer said it has run/end (hrc.bus.clock.RUN_END_RECEIVED), before physics left
        assert s.clock._observed["logger"] == RUN_END_RECEIVED
        assert observer.got_end_at <= left_at, "the clock master left before the observer had it"
    finally:
        s.close()


class _LateLastTick(Observer):
    """An observer whose clock thread gets to the last tick only after run/end was handled:
    each key's callbacks run on a thread of their own, so a starved clock thread does this."""

    def __init__(self, bus: Bus, last: int) -> None:
        super().__init__(bus)
        self.last = last
        self.steps: list[int] = []
        self.on_tick(lambda t: self.steps.append(t.header.tick))

    def _on_clock(self, key: str, tick: pb.ClockTick) -> None:
        if tick.header.tick == self.last:
            wait_until(lambda: self.ended, timeout=10)
        super()._on_clock(key, tick)


def test_an_observer_reads_the_ticks_run_end_overtook(session_id: str) -> None:
    settings = ClockSettings(ticks=60, participants=[], observers=["logger"])
    s = Session(session_id, settings, ["logger"])
    try:
        observer = _LateLastTick(s.buses["logger"], last=59)
        observer.start()
        outcome: list[Outcome] = []
        th = threading.Thread(target=lambda: outcome.append(observer.run(60)))
        th.start()
        s.clock.start()
        end = s.clock.run(lambda k, t: None, lambda k, t: None)
        th.join(30)
        assert end.ok and end.last_clock_seq == 60, end
        assert outcome and outcome[0].ok, outcome
        assert observer.steps == list(range(60)), observer.steps[-3:]
    finally:
        s.close()


def test_an_observer_has_the_last_outputs_and_the_final_report_that_come_after_run_end(
    session_id: str,
) -> None:
    # The orchestrator publishes on its metrics key every tick, and once more after run/end,
    # 0.6 s later (a busy machine): run/end lists the last tick's outputs, and the logger,
    # told that a final report comes after the end, waits for it instead of for 0.3 s of quiet.
    settings = ClockSettings(ticks=30, participants=["orchestrator"], observers=["logger"])
    s = Session(session_id, settings, ["orchestrator", "logger"])
    try:
        key = s.buses["orchestrator"].keys.task_metrics()
        pub = s.buses["orchestrator"].publisher(key)
        orch = LockstepParticipant(s.buses["orchestrator"])
        orch.on_tick(lambda t: pub.put(pb.MetricsReport(), t.header.tick, t.header.sim_time))
        logger = Observer(s.buses["logger"])
        got: list[tuple[int, bool]] = []
        logger.input(key, pb.MetricsReport, lambda _k, m: got.append((m.header.tick, m.final)))
        logger.after_end(key, "orchestrator")
        outcomes: dict[str, Outcome] = {}

        def orchestrate() -> None:
            outcomes["orchestrator"] = out = orch.run(30)
            assert out.run_end is not None
            time.sleep(0.6)
            pub.put(pb.MetricsReport(final=True), out.run_end.ticks, out.run_end.sim_time)

        threads = [
            threading.Thread(target=orchestrate),
            threading.Thread(target=lambda: outcomes.__setitem__("logger", logger.run(30))),
        ]
        for p in (orch, logger):
            p.start()
        for th in threads:
            th.start()
        s.clock.start()
        end = s.clock.run(lambda k, t: None, lambda k, t: None)
        for th in threads:
            th.join(10)
        assert end.ok and end.ticks == 30, end
        # run/end lists the orchestrator's output of the last tick (no clock tick lists it)
        listed = {(m.key, m.sender): m.seq for m in end.published}
        assert listed.get((key, "orchestrator")) == 30, list(end.published)
        assert outcomes["logger"].ok, outcomes
        assert got == [(k, False) for k in range(30)] + [(30, True)], got
    finally:
        s.close()
