"""Follows the session's clock without taking part in the barrier, and loses nothing.

Zenoh callbacks only decode and queue (the bus Inbox, and a tick queue here), so a slow logger
never stalls the bus threads; this service's main thread works through the ticks in order:
for tick k it waits (lockstep) until every message the clock lists as published has arrived,
hands over the inputs of ticks < k (plus physics's of k) in the Inbox's deterministic order,
checks each message's sequence number, and runs the step. At run end it works off the queued
ticks, then waits for the session to go quiet and hands over whatever is left (the last outputs
of the final tick are not listed by any clock tick).

Lag: for each tick processed, the newest clock tick already received minus the tick being
processed (ticks), and the wall time since that tick arrived.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from dataclasses import dataclass
from typing import Callable

from google.protobuf.message import Message

from hrc.bus import Bus, Inbox, Outcome, watch_clock_master
from hrc.wire import pb

from hrc_logger.sequence import SeqChecker

log = logging.getLogger(__name__)

Handler = Callable[[str, Message], None]


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


class Observer:
    """An observer of the tick protocol: subscribes, declares ``alive/<name>``, never acks."""

    def __init__(self, bus: Bus, *, input_timeout_s: float = 10.0, quiet_s: float = 0.3,
                 drain_max_s: float = 3.0) -> None:
        self.bus = bus
        self.inbox = Inbox(bus)
        self.seq = SeqChecker()
        self.lag = LagStats()
        self.input_timeout_s = input_timeout_s
        self.quiet_s = quiet_s
        self.drain_max_s = drain_max_s
        self.missing_inputs = 0
        self._cond = threading.Condition()
        self._ticks: deque[tuple[pb.ClockTick, float]] = deque()
        self._latest_seen = -1
        self._end: Outcome | None = None
        self._step: Callable[[pb.ClockTick], None] | None = None
        self._hurry = False  # stop waiting for inputs (terminated, or the run failed)

    # ------------------------------------------------------------------ setup
    def input(self, key: str, msg_type: type[Message], handler: Handler) -> None:
        """``handler(key, msg)`` on the run thread, in tick order, after the sequence check."""

        def checked(k: str, msg: Message) -> None:
            h = msg.header  # type: ignore[attr-defined]
            self.seq.check(k, h.sender, h.seq)
            handler(k, msg)

        self.inbox.add(key, msg_type, checked)

    def on_tick(self, step: Callable[[pb.ClockTick], None]) -> None:
        self._step = step

    def start(self) -> None:
        """Subscribes to the clock and run end, serves stats, then declares ``alive/<name>``."""
        keys = self.bus.keys
        self.bus.subscribe(keys.clock(), pb.ClockTick, self._on_clock)
        self.bus.subscribe(keys.run_end(), pb.RunEnd, self._on_run_end)
        watch_clock_master(self.bus, self.stop)
        self.bus.serve_stats()
        self.bus.declare_token()

    # ------------------------------------------------------------------ zenoh threads
    def _on_clock(self, key: str, tick: pb.ClockTick) -> None:
        self.seq.check(key, tick.header.sender, tick.header.seq)
        with self._cond:
            self._latest_seen = max(self._latest_seen, int(tick.header.tick))
            self._ticks.append((tick, time.monotonic()))
            self._cond.notify_all()

    def _on_run_end(self, _key: str, end: pb.RunEnd) -> None:
        self.stop(Outcome(end.ok, end.reason, end))

    def stop(self, outcome: Outcome, hurry: bool = False) -> None:
        """Ends the run (first outcome wins); safe from any thread or a signal handler.
        ``hurry`` (and any failed outcome): don't wait for missing inputs any more."""
        with self._cond:
            if self._end is None:
                self._end = outcome
            self._hurry = self._hurry or hurry or not outcome.ok
            self._cond.notify_all()

    # ------------------------------------------------------------------ run thread
    def run(self) -> Outcome:
        """Processes ticks until the run ends, then the queued ticks and the late messages."""
        while True:
            with self._cond:
                while not self._ticks and self._end is None:
                    self._cond.wait(0.5)
                if not self._ticks:
                    break
                tick, arrived = self._ticks.popleft()
            self._process(tick, arrived)
        self._drain()
        assert self._end is not None
        return self._end

    def _process(self, tick: pb.ClockTick, arrived: float) -> None:
        k = int(tick.header.tick)
        if tick.mode == pb.CLOCK_MODE_LOCKSTEP:
            wait = 0.0 if self._hurry else self.input_timeout_s
            missing = self.inbox.wait_for(list(tick.published), wait)
            if missing:
                # Reliable delivery makes this a real loss; keep logging what did arrive.
                self.missing_inputs += len(missing)
                names = ", ".join(f"{m.key}#{m.seq} from {m.sender}" for m in missing)
                log.error("tick %d: inputs never arrived: %s", k, names)
        with self._cond:
            latest = self._latest_seen
        self.lag.add(latest - k, time.monotonic() - arrived)
        self.inbox.deliver(k, master=self.bus.config.clock_master)
        self.bus.stats.tick(k)
        if self._step is not None:
            self._step(tick)

    def _drain(self) -> None:
        """Hands over everything still arriving until the session is quiet for ``quiet_s``."""
        deadline = time.monotonic() + (0.5 if self._hurry else self.drain_max_s)
        quiet_since = time.monotonic()
        while True:
            if self.inbox.deliver(2**62) > 0:
                quiet_since = time.monotonic()
            now = time.monotonic()
            if now - quiet_since >= self.quiet_s or now >= deadline:
                return
            time.sleep(0.05)
