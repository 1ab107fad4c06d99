"""The observer role: follows the session's clock without taking part in the barrier, and
records what it lost (the logger is one).

The loop is the participants' (:class:`hrc.bus.lockstep.ClockFollower`) without the ack, and
without the inline path: Zenoh callbacks only decode and queue, so a slow observer never stalls
the bus threads; the run() thread works through the ticks in order. On top of it the observer
checks every message's sequence number (a gap is a lost message), measures its lag behind the
clock, keeps going when a tick's inputs never arrive (it logs what did arrive), and at the run's
end works off the queued ticks, then waits for what came after the last clock tick (listed by
run/end, or announced with :meth:`Observer.after_end`; in realtime or after a failure, until the
session goes quiet) and hands over whatever is left.

Every OBSERVER_ACK_TICKS it acks the newest clock tick it has received, from the Zenoh thread
that received it (what lockstep's window waits for: receiving, not processing, so a slow step
never slows the clock). In realtime nothing waits for it during the run: what the router could
not hand over is dropped, and shows here as sequence gaps (counted, with their ticks). At the end
it acks run/end's arrival, and the clock master stays while it is still reading towards it.

Lag: for each tick processed, the newest clock tick already received minus the tick being
processed (ticks), and the wall time since that tick arrived.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass

from hrc.bus.bus import Bus, M, Publisher
from hrc.bus.clock import OBSERVER_ACK_TICKS, RUN_END_RECEIVED
from hrc.bus.lockstep import ClockFollower, Outcome, describe_marks
from hrc.bus.sequence import SeqChecker
from hrc.wire import pb

log = logging.getLogger(__name__)

# A stopped observer's link closes when it resumes (its view of the router's lease ran out) and
# opens again at once; the clock master is gone for us only if it is not back within this.
MASTER_RETURN_S = 1.0


@dataclass
class LagStats:
    ticks: int = 0
    sum_ticks: int = 0
    max_ticks: int = 0
    sum_wall_s: float = 0.0
    max_wall_s: float = 0.0

    def add(self, lag_ticks: int, wall_s: float) -> None:
        self.ticks += 1
        self.sum_ticks += lag_ticks
        self.max_ticks = max(self.max_ticks, lag_ticks)
        self.sum_wall_s += wall_s
        self.max_wall_s = max(self.max_wall_s, wall_s)

    @property
    def mean_ticks(self) -> float:
        return self.sum_ticks / self.ticks if self.ticks else 0.0

    @property
    def mean_wall_s(self) -> float:
        return self.sum_wall_s / self.ticks if self.ticks else 0.0


class Observer(ClockFollower):
    """Subscribes, declares ``alive/<name>``, never takes part in the barrier; the clock master
    waits for its token at the start, and in lockstep keeps the clock within a window of what it
    has received (see the module's doc)."""

    inline = False
    master_grace_s = MASTER_RETURN_S

    def __init__(
        self,
        bus: Bus,
        *,
        input_timeout_s: float = 10.0,
        quiet_s: float = 0.3,
        drain_max_s: float = 3.0,
    ) -> None:
        super().__init__(bus, input_timeout_s=input_timeout_s)
        self.seq = SeqChecker()
        self.lag = LagStats()
        self.quiet_s = quiet_s
        self.drain_max_s = drain_max_s
        self.missing_inputs = 0
        self._hurry = False  # stop waiting for inputs (stopped, or the run failed)
        self._ack_pub: Publisher[pb.TickAck] | None = None
        self._acked = -OBSERVER_ACK_TICKS  # the newest tick acknowledged
        self._tail_deadline: float | None = None  # when to stop waiting for the last ticks
        self.mode: int | None = None  # the clock's mode (pb.ClockMode), from the first tick handled
        self._after_end: list[tuple[str, str]] = []  # see after_end()
        self._participants: frozenset[str] = frozenset()  # the clock's, from the ticks handled

    def input(
        self,
        key: str,
        msg_type: type[M],
        handler: Callable[[str, M], None],
        validate: Callable[[M], str | None] | None = None,
    ) -> None:
        """``handler(key, msg)`` on the run thread, in tick order, after the sequence check."""

        def checked(k: str, msg: M) -> None:
            h = msg.header  # type: ignore[attr-defined]
            self.seq.check(k, h.sender, h.seq, h.tick)
            handler(k, msg)

        super().input(key, msg_type, checked, validate)

    def _declare_publishers(self) -> None:
        self._ack_pub = self.bus.publisher(self.bus.keys.clock_ack(self.name), express=True)

    def _on_clock(self, key: str, tick: pb.ClockTick) -> None:
        k = tick.header.tick
        self.seq.check(key, tick.header.sender, tick.header.seq, k)
        if k >= self._acked + OBSERVER_ACK_TICKS and self._ack_pub is not None:
            self._acked = k
            self._ack_pub.put(pb.TickAck(participant=self.name), k, tick.header.sim_time)
        super()._on_clock(key, tick)

    def _on_run_end(self, key: str, end: pb.RunEnd) -> None:
        # The clock master stays until we have it (hrc.bus.clock.RUN_END_RECEIVED).
        if self._ack_pub is not None:
            self._ack_pub.put(pb.TickAck(participant=self.name), RUN_END_RECEIVED, end.sim_time)
        super()._on_run_end(key, end)

    def _finish(self, outcome: Outcome) -> None:
        # A failed end (a stop, a lost clock master, run/end not ok): don't wait for inputs.
        # Only the end that counts (the first): the clock master leaving after a good run/end
        # must not hurry the work still queued (the view, the last ticks).
        # (No lock needed: one attribute read is atomic.)
        if self._end is None and not outcome.ok:
            self._hurry = True
        super()._finish(outcome)

    @property
    def ended(self) -> bool:
        """The run is over (run/end came, a stop, or the clock master is gone). No lock: one
        attribute read is atomic, and the logger asks before every message it handles."""
        return self._end is not None

    @property
    def hurried(self) -> bool:
        """The run ended badly (a stop, a lost clock master): finish quickly."""
        return self._hurry

    def _work_off_queue(self) -> bool:
        return not self._aborted

    def _ticks_unseen(self) -> pb.RunEnd | None:
        """The good run/end when clock ticks it says were sent have not arrived (each key's
        callbacks run on a thread of their own, so run/end can be handled before the last
        ticks; RunEnd.last_clock_seq says which one was last). Under the lock, or after run()."""
        end = self._end.run_end if self._end is not None else None
        if end is None or self._hurry or self._clock_seq >= end.last_clock_seq:
            return None
        return end

    def _tail_wait_s(self) -> float:
        if self._ticks_unseen() is None:
            return 0.0
        now = time.monotonic()
        if self._tail_deadline is None:
            self._tail_deadline = now + self.drain_max_s
        return max(0.0, self._tail_deadline - now)

    def _input_wait_s(self) -> float:
        return 0.0 if self._hurry else self.input_timeout_s

    def _inputs_missing(self, k: int, missing: list[pb.PublishedMark]) -> bool:
        # Reliable delivery makes this a real loss; keep recording what did arrive.
        self.missing_inputs += len(missing)
        log.error("tick %d: inputs never arrived: %s", k, describe_marks(missing))
        return True

    def _tick_ready(self, tick: pb.ClockTick, arrived: float) -> None:
        self.mode = tick.mode
        if not self._participants:
            self._participants = frozenset(tick.participants)
        with self._cond:
            latest = self._latest_seen
        self.lag.add(latest - tick.header.tick, time.perf_counter() - arrived)

    def after_end(self, key: str, sender: str) -> None:
        """``sender`` publishes on ``key`` once more after run/end (the orchestrator's final
        metrics): a good lockstep end waits for that message too, if ``sender`` took part."""
        self.inbox.watch(key, sender)
        self._after_end.append((key, sender))

    def _wind_up(self) -> None:
        """Waits for what came after the last clock tick, then hands over everything still
        held at once (sorted: the last outputs, which no clock tick lists, may come on several
        keys, and their order must not depend on when each arrived).

        After a good lockstep end run/end lists those last outputs, and the messages announced
        with after_end() come with run/end's tick: they are waited for (at most ``drain_max_s``).
        Otherwise (realtime, where a late output is listed by nobody; a failed run) the session
        must have been quiet for ``quiet_s``."""
        unseen = self._ticks_unseen()
        if unseen is not None:
            log.error(
                "clock ticks seq %d..%d never arrived (run/end came %.1f s before)",
                self._clock_seq + 1,
                unseen.last_clock_seq,
                self.drain_max_s,
            )
        end = self._end.run_end if self._end is not None else None
        if end is not None and end.ok and not self._hurry and end.mode == pb.CLOCK_MODE_LOCKSTEP:
            after = [ks for ks in self._after_end if ks[1] in self._participants]
            missing, late = self.inbox.wait_for_end(
                list(end.published), after, end.ticks, self.drain_max_s
            )
            if missing or late:
                log.error(
                    "after run/end, never came within %.1f s: %s",
                    self.drain_max_s,
                    "; ".join(
                        ([describe_marks(missing)] if missing else [])
                        + [f"{k} from '{snd}'" for k, snd in late]
                    ),
                )
            self.inbox.deliver(2**62)
            return
        deadline = time.monotonic() + (0.5 if self._hurry else self.drain_max_s)
        quiet_since = time.monotonic()
        seen = self.inbox.arrived
        while True:
            now = time.monotonic()
            if self.inbox.arrived != seen:
                seen, quiet_since = self.inbox.arrived, now
            if now - quiet_since >= self.quiet_s or now >= deadline:
                self.inbox.deliver(2**62)
                return
            time.sleep(0.05)
