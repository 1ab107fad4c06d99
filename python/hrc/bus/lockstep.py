"""The two roles that follow the clock (docs/ARCHITECTURE.md, "Roles").

Both share one loop (:class:`ClockFollower`): on clock tick k, wait until every message the clock
says was published before k has arrived, hand those inputs to the service (Inbox), run the
service's step for k. A :class:`LockstepParticipant` then acks k (it is part of the barrier); an
:class:`hrc.bus.observer.Observer` never acks.

A step (or an input handler) that raises ends the run at once: the follower publishes a
``run/control`` ABORT naming the tick and the error, the clock master ends the run with
``RunEnd.failed_participant`` = this service, and :meth:`ClockFollower.run` returns a failed
outcome (exit code 1).
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from hrc.bus.bus import Bus, M, Publisher
from hrc.bus.inbox import Inbox
from hrc.wire import pb

log = logging.getLogger(__name__)

# After an abort, how long run() waits for the clock master's run/end before returning: the
# service then leaves after the clock master has ended the run, so the end names the abort.
ABORT_WAIT_S = 2.0


@dataclass
class Outcome:
    """How a service's run ended."""

    ok: bool
    reason: str
    run_end: pb.RunEnd | None = None

    @property
    def exit_code(self) -> int:
        return 0 if self.ok else 1


def watch_clock_master(bus: Bus, on_lost: Callable[[Outcome], None], grace_s: float = 0.0) -> None:
    """Calls ``on_lost`` when the clock master's token, once seen, disappears (and, with
    ``grace_s``, is not back within that time: an observer's own link may close and reopen at
    once, e.g. after the process was stopped for longer than the link's lease)."""
    master = bus.config.clock_master
    seen = False
    pending: threading.Timer | None = None
    lost = Outcome(False, f"the clock master '{master}' disappeared")

    def on_change(service: str, alive: bool) -> None:
        nonlocal seen, pending
        if service != master:
            return
        if alive:
            if pending is not None:
                pending.cancel()
                pending = None
                log.warning(
                    "the link to the trial's bus closed and reopened: what came meanwhile "
                    "is lost (sequence gaps)"
                )
            seen = True
        elif seen and grace_s <= 0:
            on_lost(lost)
        elif seen and pending is None:
            pending = threading.Timer(grace_s, on_lost, (lost,))
            pending.daemon = True
            pending.start()

    bus.watch_liveliness(on_change)


def describe_marks(marks: list[pb.PublishedMark]) -> str:
    return ", ".join(f"{m.key}#{m.seq} from {m.sender}" for m in marks)


def opens_exchange(tick: pb.ClockTick) -> bool:
    """The clock master's tick, which opens an exchange (it lists the participants), not one of
    the further ticks :func:`exchange_ticks` makes."""
    return bool(tick.participants)


def exchange_ticks(tick: pb.ClockTick) -> list[pb.ClockTick]:
    """The ticks of the exchange a clock tick opens: itself, then (span > 1) one ClockTick
    per further tick, with header.tick and sim_time of that tick (``mode`` and ``dt`` kept)."""
    if tick.span <= 1:
        return [tick]
    k, dt = tick.header.tick, tick.dt
    out = [tick]
    for i in range(1, tick.span):
        sub = pb.ClockTick(mode=tick.mode, dt=dt)  # no participants: see opens_exchange
        sub.header.session = tick.header.session
        sub.header.sender = tick.header.sender
        sub.header.tick = k + i
        sub.header.sim_time = (k + i) * dt  # as the clock master computes it
        out.append(sub)
    return out


class ClockFollower:
    """The loop shared by participants and observers; use one of the two subclasses.

    Register inputs with :meth:`input` and the step with :meth:`on_tick` before :meth:`start`.
    Inputs and steps run one tick at a time, on the thread that calls :meth:`run` (or, for a
    participant, inline on the Zenoh thread that delivered the clock), never concurrently.
    """

    # A tick may be computed on the Zenoh thread that delivered it (saves a thread hand-off).
    inline = False
    # Ask a sender again for a message a tick vouches for that is long late (participants; an
    # observer records what it lost instead: docs/ARCHITECTURE.md, "Lost messages").
    replay = False
    # How long the clock master may be gone before the run is over for us (see
    # watch_clock_master); a participant's link that closed has failed the run already.
    master_grace_s = 0.0

    def __init__(self, bus: Bus, *, input_timeout_s: float = 10.0) -> None:
        self.bus = bus
        self.name = bus.sender
        self.input_timeout_s = input_timeout_s
        self.inbox = Inbox(bus, gapless=self.replay)
        self._step: Callable[[pb.ClockTick], None] | None = None
        self._cond = threading.Condition(threading.Lock())
        self._ticks: deque[tuple[pb.ClockTick, float]] = deque()  # (tick, perf_counter at arrival)
        self._busy = False  # a tick is being computed (one at a time, whichever thread)
        self._running = False
        self._latest_seen = -1  # the newest clock tick received
        self._clock_seq = 0  # the highest ClockTick header.seq received
        self._end: Outcome | None = None
        self._aborted = False  # our own step failed and we asked the clock master to abort
        self._master_done = False  # run/end came, or the clock master is gone
        self._control_pub: Publisher[pb.RunControl] | None = None
        self.last_tick: pb.ClockTick | None = None
        # where a tick's time goes (reported at the end): hand-off, waiting for inputs, compute
        self._ticks_done = 0
        self._lag_s = self._wait_s = self._compute_s = 0.0

    # ------------------------------------------------------------------ setup
    def input(
        self,
        key: str,
        msg_type: type[M],
        handler: Callable[[str, M], None],
        validate: Callable[[M], str | None] | None = None,
    ) -> None:
        """``handler(key, msg)`` for each message on ``key``, before the step of its tick."""
        self.inbox.add(key, msg_type, handler, validate)

    def on_tick(self, step: Callable[[pb.ClockTick], None]) -> None:
        self._step = step

    def _declare_publishers(self) -> None:
        """The role's own publishers (before the token)."""

    def start(self) -> None:
        """Subscribes to the clock and run end, serves stats, then announces readiness."""
        keys = self.bus.keys
        self._declare_publishers()
        self._control_pub = self.bus.publisher(keys.run_control(self.bus.sender), express=True)
        self.bus.subscribe(keys.clock(), pb.ClockTick, self._on_clock)
        self.bus.subscribe(keys.run_end(), pb.RunEnd, self._on_run_end)
        watch_clock_master(self.bus, self._on_master_lost, self.master_grace_s)
        self.bus.serve_stats()
        self.bus.serve_replay()
        self.bus.declare_token()

    # ------------------------------------------------------------------ zenoh threads
    def _on_clock(self, _key: str, tick: pb.ClockTick) -> None:
        arrived = time.perf_counter()
        with self._cond:
            if tick.header.tick > self._latest_seen:
                self._latest_seen = tick.header.tick
            self._clock_seq = max(self._clock_seq, tick.header.seq)
            # Fast path: when nothing is queued and every input of the tick is here, compute it
            # right on this thread; otherwise the run() thread does (and waits for the inputs).
            inline = (
                self.inline
                and not self._ticks
                and not self._busy
                and self._end is None
                and self._running
                and not self.inbox.missing(list(tick.published))
            )
            if not inline:
                self._ticks.append((tick, arrived))
                self._cond.notify_all()
                return
            self._busy = True
        self._process_claimed(tick, arrived, inputs_ready=True)

    def _process_claimed(
        self, tick: pb.ClockTick, arrived: float, inputs_ready: bool = False
    ) -> None:
        """Computes a tick this thread claimed (``_busy`` set) and releases the claim."""
        try:
            self._process(tick, arrived, inputs_ready)
        finally:
            with self._cond:
                self._busy = False
                if self._ticks or self._end is not None:  # else run() has nothing to do
                    self._cond.notify_all()

    def _on_run_end(self, _key: str, end: pb.RunEnd) -> None:
        with self._cond:
            self._master_done = True
            if self._end is not None and self._end.run_end is None:
                self._end.run_end = end  # e.g. after our abort: the end the clock master gave
        self._finish(Outcome(end.ok, end.reason, end))

    def _on_master_lost(self, outcome: Outcome) -> None:
        with self._cond:
            self._master_done = True
        self._finish(outcome)

    def _finish(self, outcome: Outcome) -> None:
        with self._cond:
            if self._end is None:
                self._end = outcome
            self._cond.notify_all()

    def stop(self, reason: str = "stopped") -> None:
        """Ends the run (first outcome wins); safe from any thread, but not from a signal
        handler (it takes the role's lock, which the interrupted thread may hold: start a
        thread that calls it, as hrc.service does)."""
        self._finish(Outcome(False, reason))

    # ------------------------------------------------------------------ run() thread
    def _work_off_queue(self) -> bool:
        """After the end: compute the ticks still queued (observers) or drop them."""
        return False

    def run(self, timeout: float | None = None) -> Outcome:
        """Processes ticks until the run ends (or ``timeout`` seconds pass without one)."""
        with self._cond:
            self._running = True
        while True:
            with self._cond:
                ready = self._cond.wait_for(
                    lambda: (self._ticks and not self._busy) or self._end is not None, timeout
                )
                if self._end is not None and not (self._ticks and self._work_off_queue()):
                    left = self._tail_wait_s()
                    if left > 0:  # run/end overtook ticks still on their way
                        self._cond.wait_for(lambda: bool(self._ticks), left)
                        continue
                    # An inline tick may still be under way: let it end before the bus goes.
                    self._cond.wait_for(lambda: not self._busy, self.input_timeout_s)
                    break
                if not ready:
                    self._end = Outcome(False, f"no clock tick within {timeout:g} s")
                    break
                tick, arrived = self._ticks.popleft()
                self._busy = True
            self._process_claimed(tick, arrived)
        if self._aborted:
            with self._cond:
                self._cond.wait_for(lambda: self._master_done, ABORT_WAIT_S)
        self._wind_up()
        log.info("%s", self.report())
        end = self._end
        assert end is not None
        return end

    def _tail_wait_s(self) -> float:
        """After the end, with nothing queued: how long to wait still for clock ticks sent
        before run/end (called under the lock; 0: none, or don't wait)."""
        return 0.0

    def _wind_up(self) -> None:
        """The role's last work after the end (observers: the late messages)."""

    def report(self) -> str:
        n = max(1, self._ticks_done)
        return (
            f"{self._ticks_done} ticks; mean us per tick: "
            f"hand-off {self._lag_s / n * 1e6:.0f}, input wait {self._wait_s / n * 1e6:.0f}, "
            f"compute {self._compute_s / n * 1e6:.0f}"
        )

    # ------------------------------------------------------------------ one tick
    def _input_wait_s(self) -> float:
        return self.input_timeout_s

    def _inputs_missing(self, k: int, missing: list[pb.PublishedMark]) -> bool:
        """Inputs of tick k never arrived: returns whether to compute the tick anyway."""
        raise NotImplementedError

    def _tick_ready(self, tick: pb.ClockTick, arrived: float) -> None:
        """All inputs of the tick are here (observers measure their lag)."""

    def _after_step(self, tick: pb.ClockTick, t0: float) -> None:
        """The step of the tick ran (participants ack); ``t0``: when its inputs were all here."""

    def _process(self, tick: pb.ClockTick, arrived: float, inputs_ready: bool = False) -> None:
        """``inputs_ready``: the caller has just checked that nothing the tick lists is missing."""
        k = tick.header.tick
        tw = time.perf_counter()
        self._lag_s += tw - arrived
        if tick.mode == pb.CLOCK_MODE_LOCKSTEP and not inputs_ready:
            missing = self.inbox.wait_for(
                list(tick.published), self._input_wait_s(), replay=self.replay
            )
            if missing and not self._inputs_missing(k, missing):
                return
        # TickAck.compute_us starts here: every input of tick k is at hand.
        t0 = time.perf_counter()
        self._wait_s += t0 - tw
        self._ticks_done += 1
        self._tick_ready(tick, arrived)
        try:
            # Every input of the exchange is handed over before its first tick (Jacobi): the
            # others' outputs of ticks inside this exchange are not for us yet.
            self.inbox.deliver(k, master=self.bus.config.clock_master)
            # What the exchange publishes on a key goes out in one put, before the ack.
            self.bus.begin_batch()
            try:
                for sub in self._ticks_of(tick):
                    self.last_tick = sub
                    self.bus.stats.tick(sub.header.tick)
                    if self._step is not None:
                        self._step(sub)
            finally:
                self.bus.flush_batches()
            self._after_step(tick, t0)
        except Exception as exc:  # any failure of the service ends the run
            self._abort(tick, exc)
        self._compute_s += time.perf_counter() - t0

    def _ticks_of(self, tick: pb.ClockTick) -> list[pb.ClockTick]:
        """The ticks this service steps through for one clock tick: a participant every tick
        of the exchange (k .. k + span - 1, each a ClockTick of its own with header.tick and
        sim_time set); an observer only the clock tick itself."""
        return [tick]

    def _abort(self, tick: pb.ClockTick, exc: Exception) -> None:
        """The service failed in tick k: ask the clock master to end the run, naming us."""
        k = tick.header.tick
        reason = f"tick {k} failed: {type(exc).__name__}: {exc}"
        log.error("%s", reason, exc_info=exc)
        with self._cond:
            first = self._end is None and not self._aborted
            self._aborted = True
        # Our end before the abort goes out: the clock master's run/end, which answers it on
        # another thread, would otherwise be first to end the run and take our reason's place.
        self._finish(Outcome(False, reason))
        if first and self._control_pub is not None:
            try:
                self._control_pub.put(
                    pb.RunControl(command=pb.RunControl.COMMAND_ABORT, reason=reason),
                    k,
                    tick.header.sim_time,
                )
            except Exception:  # the bus itself may be what failed
                log.exception("could not ask the clock master to abort")


class LockstepParticipant(ClockFollower):
    """A member of the clock barrier: acks every tick after its step's outputs."""

    inline = True
    replay = True

    def __init__(self, bus: Bus, *, input_timeout_s: float = 10.0) -> None:
        super().__init__(bus, input_timeout_s=input_timeout_s)
        self._ack_pub: Publisher[pb.TickAck] | None = None
        self._next_event: Callable[[], int] | None = None
        self._next_sample: Callable[[], tuple[int, int]] | None = None

    def on_next_sample(self, next_sample: Callable[[], tuple[int, int]]) -> None:
        """``next_sample()``, asked after the exchange's steps: the earliest tick at which the
        service reads its inputs to decide from what it perceives, and the period in ticks at
        which it goes on doing so (0: once); (0, 0) if none (``TickAck.next_sample_tick``,
        ``sample_period_ticks``; docs/ARCHITECTURE.md "Exchange step")."""
        self._next_sample = next_sample

    def on_next_event(self, next_event: Callable[[], int]) -> None:
        """``next_event()``, asked after the exchange's steps: the earliest tick at which the
        service, holding its inputs, may make a change others react to; 0 if none is known
        (``TickAck.next_event_tick``, docs/ARCHITECTURE.md "Exchange step")."""
        self._next_event = next_event

    def _declare_publishers(self) -> None:
        self._ack_pub = self.bus.publisher(self.bus.keys.clock_ack(self.name), express=True)

    def _ticks_of(self, tick: pb.ClockTick) -> list[pb.ClockTick]:
        return exchange_ticks(tick)

    def _inputs_missing(self, k: int, missing: list[pb.PublishedMark]) -> bool:
        names = describe_marks(missing)
        log.error("tick %d: inputs never arrived: %s", k, names)
        self._finish(Outcome(False, f"tick {k}: inputs never arrived: {names}"))
        return False

    def _after_step(self, tick: pb.ClockTick, t0: float) -> None:
        ack_pub = self._ack_pub
        assert ack_pub is not None, "start() declares the ack publisher"
        # TickAck.compute_us ends here, before the ack is built and published.
        ack = pb.TickAck(participant=self.name, compute_us=int((time.perf_counter() - t0) * 1e6))
        ack.published.extend(self.bus.new_marks(exclude=ack_pub.key))
        if self._next_event is not None:
            ack.next_event_tick = self._next_event()
        if self._next_sample is not None:
            ack.next_sample_tick, ack.sample_period_ticks = self._next_sample()
        ack_pub.put(ack, tick.header.tick, tick.header.sim_time)
