"""Deterministic input delivery for the tick protocol.

Messages from different Zenoh sessions arrive in no defined order relative to each other, and a
peer may already publish its outputs for tick k while we are still computing k. So a service never
handles a message when it arrives: the Inbox keeps it until the service asks for "everything up to
tick k", then hands it over sorted by (tick, subscription order, key, sender, seq) — the same
order on any machine at any load.
"""

from __future__ import annotations

import heapq
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from operator import attrgetter
from typing import cast

import zenoh
from google.protobuf.message import Message

from hrc.bus.bus import Bus, M
from hrc.wire import pb

Handler = Callable[[str, Message], None]


@dataclass(slots=True)
class _Pending:
    tick: int  # first: an exchange hands over several ticks' messages, oldest tick first
    index: int
    key: str
    sender: str
    seq: int
    msg: Message


# The delivery order; a C-level key (a dataclass's generated __lt__ costs a Python call per
# comparison, and every message of every exchange is sorted).
_ORDER = attrgetter("tick", "index", "key", "sender", "seq")


class Inbox:
    """Buffers typed inputs and releases them tick by tick."""

    def __init__(self, bus: Bus) -> None:
        self._bus = bus
        # One lock; the condition only for wait_for, notified only while someone waits
        # (per message: a Condition's Python-level enter and notify cost more than the rest).
        self._lock = threading.Lock()
        self._cond = threading.Condition(self._lock)
        self._waiting = 0
        self._handlers: list[Handler] = []
        self._exprs: list[zenoh.KeyExpr] = []
        # Pending messages by tick, and a heap of those ticks: delivery takes the oldest ticks
        # without scanning everything held (an observer running behind holds thousands).
        self._pending: dict[int, list[_Pending]] = {}
        self._pending_ticks: list[int] = []
        self._received: dict[tuple[str, str], int] = {}
        self.arrived = 0  # messages received so far (delivered or not)
        self._matches: dict[str, bool] = {}

    def add(
        self,
        key: str,
        msg_type: type[M],
        handler: Callable[[str, M], None],
        validate: Callable[[M], str | None] | None = None,
    ) -> None:
        index = len(self._handlers)
        # Each handler gets only messages of its own type (the key's subscription decodes them).
        self._handlers.append(cast(Handler, handler))
        self._exprs.append(zenoh.KeyExpr(key))

        def on_msg(k: str, msg: M) -> None:
            h = msg.header  # type: ignore[attr-defined]
            tick, sender, seq = h.tick, h.sender, h.seq
            # A message that fails validation still counts as received: its sender published
            # it (and says so in its marks), so nobody may wait for it forever.
            problem = validate(msg) if validate is not None else None
            with self._lock:
                if problem is None:
                    bucket = self._pending.get(tick)
                    if bucket is None:
                        bucket = self._pending[tick] = []
                        heapq.heappush(self._pending_ticks, tick)
                    bucket.append(_Pending(tick, index, k, sender, seq, msg))
                self.arrived += 1
                mark = (k, sender)
                if seq > self._received.get(mark, 0):
                    self._received[mark] = seq
                if self._waiting:
                    self._cond.notify_all()
            if problem is not None:
                self._bus.reject(k, sender, problem)

        self._bus.subscribe(key, msg_type, on_msg)

    def _subscribed(self, key: str) -> bool:
        hit = self._matches.get(key)
        if hit is None:
            ke = zenoh.KeyExpr(key)
            hit = any(e.intersects(ke) for e in self._exprs)
            self._matches[key] = hit
        return hit

    def missing(self, marks: list[pb.PublishedMark]) -> list[pb.PublishedMark]:
        """The marks (on keys we subscribe to) whose messages have not all arrived yet."""
        with self._lock:
            return [
                m
                for m in marks
                if self._subscribed(m.key) and self._received.get((m.key, m.sender), 0) < m.seq
            ]

    def last_seq(self, key: str, sender: str) -> int:
        """The highest seq received on ``key`` from ``sender`` (0: none yet)."""
        with self._lock:
            return self._received.get((key, sender), 0)

    def wait_for(self, marks: list[pb.PublishedMark], timeout: float) -> list[pb.PublishedMark]:
        """Waits until every mark is satisfied; returns what is still missing at the timeout."""
        wanted = [m for m in marks if self._subscribed(m.key)]
        if not wanted:
            return []
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                missing = [m for m in wanted if self._received.get((m.key, m.sender), 0) < m.seq]
                left = deadline - time.monotonic()
                if not missing or left <= 0:
                    return missing
                self._waiting += 1
                try:
                    self._cond.wait(left)
                finally:
                    self._waiting -= 1

    def deliver(self, upto_tick: int, master: str | None = None) -> int:
        """Hands every message of ticks < ``upto_tick`` to its handler (plus the clock master's of
        tick ``upto_tick`` when ``master`` is given), in deterministic order. Returns the count."""
        ready: list[_Pending] = []
        with self._lock:
            heap = self._pending_ticks
            while heap and heap[0] < upto_tick:
                ready.extend(self._pending.pop(heapq.heappop(heap)))
            if master is not None and upto_tick in self._pending:
                bucket = self._pending[upto_tick]
                ready.extend(p for p in bucket if p.sender == master)
                # The others' messages of this tick stay (the bucket, maybe empty, stays in the
                # heap until the tick is passed).
                self._pending[upto_tick] = [p for p in bucket if p.sender != master]
        if not ready:
            return 0
        ready.sort(key=_ORDER)
        for p in ready:
            self._handlers[p.index](p.key, p.msg)
        return len(ready)

    def deliver_through(self, tick: int) -> int:
        """Hands over every message of ticks <= ``tick`` (the clock master after a barrier)."""
        return self.deliver(tick + 1)
