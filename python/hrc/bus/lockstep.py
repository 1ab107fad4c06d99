"""The participant side of the tick protocol (docs/ARCHITECTURE.md).

On clock tick k: wait until every message the clock says was published before k has arrived,
hand those inputs to the service (Inbox), run the service's step for k, publish the ack.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from dataclasses import dataclass
from typing import Callable

from google.protobuf.message import Message

from hrc.bus.bus import Bus, Validator
from hrc.bus.inbox import Handler, Inbox
from hrc.wire import pb

log = logging.getLogger(__name__)


@dataclass
class Outcome:
    """How a participant's run ended."""

    ok: bool
    reason: str
    run_end: pb.RunEnd | None = None

    @property
    def exit_code(self) -> int:
        return 0 if self.ok else 1


def watch_clock_master(bus: Bus, on_lost: Callable[[Outcome], None]) -> None:
    """Calls ``on_lost`` when the clock master's token, once seen, disappears."""
    master = bus.config.clock_master
    seen = False

    def on_change(service: str, alive: bool) -> None:
        nonlocal seen
        if service != master:
            return
        if alive:
            seen = True
        elif seen:
            on_lost(Outcome(False, f"the clock master '{master}' disappeared"))

    bus.watch_liveliness(on_change)


class LockstepParticipant:
    """Takes part in the clock barrier (``ack=True``) or just follows it (observers).

    Register inputs with :meth:`input` and the step with :meth:`on_tick` before :meth:`start`.
    Inputs and steps run on the thread that calls :meth:`run`, never on Zenoh's threads.
    """

    def __init__(self, bus: Bus, *, ack: bool = True, input_timeout_s: float = 10.0) -> None:
        self.bus = bus
        self.name = bus.sender
        self.ack = ack
        self.input_timeout_s = input_timeout_s
        self.inbox = Inbox(bus)
        self._step: Callable[[pb.ClockTick], None] | None = None
        self._cond = threading.Condition(threading.Lock())
        self._ticks: deque[pb.ClockTick] = deque()
        self._busy = False  # a tick is being computed (one at a time, whichever thread)
        # where a tick's time goes (reported at the end): hand-off, waiting for inputs, compute
        self._ticks_done = 0
        self._lag_s = self._wait_s = self._compute_s = 0.0
        self._last_clock_rx = 0.0
        self._running = False
        self._end: Outcome | None = None
        self.last_tick: pb.ClockTick | None = None
        self._ack_pub = None

    def input(self, key: str, msg_type: type[Message], handler: Handler,
              validate: Validator | None = None) -> None:
        self.inbox.add(key, msg_type, handler, validate)

    def on_tick(self, step: Callable[[pb.ClockTick], None]) -> None:
        self._step = step

    def start(self) -> None:
        """Subscribes to the clock and run end, serves stats, then announces readiness."""
        keys = self.bus.keys
        if self.ack:
            self._ack_pub = self.bus.publisher(keys.clock_ack(self.name), express=True)
        self.bus.subscribe(keys.clock(), pb.ClockTick, self._on_clock)
        self.bus.subscribe(keys.run_end(), pb.RunEnd, self._on_run_end)
        watch_clock_master(self.bus, self._finish)
        self.bus.serve_stats()
        self.bus.declare_token()

    # ------------------------------------------------------------------ zenoh threads
    def report(self) -> str:
        n = max(1, self._ticks_done)
        return (f"{self._ticks_done} ticks; mean us per tick: hand-off {self._lag_s / n * 1e6:.0f}, "
                f"input wait {self._wait_s / n * 1e6:.0f}, compute {self._compute_s / n * 1e6:.0f}")

    def _on_clock(self, _key: str, tick: pb.ClockTick) -> None:
        self._last_clock_rx = time.perf_counter()
        # Fast path: when nothing is queued and every input of the tick is here, compute it right
        # on this thread (saves a thread hand-off per tick); otherwise the run() thread waits.
        with self._cond:
            inline = (not self._ticks and not self._busy and self._end is None
                      and self._running and not self.inbox.missing(list(tick.published)))
            if not inline:
                self._ticks.append(tick)
                self._cond.notify_all()
                return
            self._busy = True
        self._process_claimed(tick, inputs_ready=True)

    def _process_claimed(self, tick: pb.ClockTick, inputs_ready: bool = False) -> None:
        """Computes a tick this thread claimed (``_busy`` set) and releases the claim."""
        try:
            self._process(tick, inputs_ready)
        finally:
            with self._cond:
                self._busy = False
                if self._ticks:  # only a queued tick concerns the run() thread; don't wake it idly
                    self._cond.notify_all()

    def _on_run_end(self, _key: str, end: pb.RunEnd) -> None:
        self._finish(Outcome(end.ok, end.reason, end))

    def _finish(self, outcome: Outcome) -> None:
        with self._cond:
            if self._end is None:
                self._end = outcome
            self._cond.notify_all()

    def stop(self, reason: str = "stopped") -> None:
        self._finish(Outcome(False, reason))

    # ------------------------------------------------------------------ main thread
    def run(self, timeout: float | None = None) -> Outcome:
        """Processes ticks until the run ends (or ``timeout`` seconds pass without one)."""
        with self._cond:
            self._running = True
        while True:
            with self._cond:
                ok = self._cond.wait_for(
                    lambda: (self._ticks and not self._busy) or self._end is not None, timeout)
                if self._end is not None:
                    log.info("%s", self.report())
                    return self._end
                if not ok:
                    return Outcome(False, f"no clock tick within {timeout:g} s")
                tick = self._ticks.popleft()
                self._busy = True
            self._process_claimed(tick)

    def _process(self, tick: pb.ClockTick, inputs_ready: bool = False) -> None:
        """``inputs_ready``: the caller has just checked that nothing the tick lists is missing."""
        k = tick.header.tick
        tw = time.perf_counter()
        self._lag_s += tw - self._last_clock_rx
        if tick.mode == pb.CLOCK_MODE_LOCKSTEP and not inputs_ready:
            missing = self.inbox.wait_for(list(tick.published), self.input_timeout_s)
            if missing:
                names = ", ".join(f"{m.key}#{m.seq} from {m.sender}" for m in missing)
                log.error("tick %d: inputs never arrived: %s", k, names)
                self._finish(Outcome(False, f"tick {k}: inputs never arrived: {names}"))
                return
        t0 = time.perf_counter()  # compute time, not time spent waiting for inputs
        self._wait_s += t0 - tw
        self._ticks_done += 1
        self.inbox.deliver(k, master=self.bus.config.clock_master)
        self.last_tick = tick
        self.bus.stats.tick(k)
        if self._step is not None:
            self._step(tick)
        if self._ack_pub is not None:
            ack = pb.TickAck(participant=self.name,
                             compute_us=int((time.perf_counter() - t0) * 1e6))
            ack.published.extend(self.bus.new_marks(exclude=self._ack_pub.key))
            self._ack_pub.put(ack, k, tick.header.sim_time)
        self._compute_s += time.perf_counter() - t0
