"""Deterministic input delivery for the tick protocol.

Messages from different Zenoh sessions arrive in no defined order relative to each other, and a
peer may already publish its outputs for tick k while we are still computing k. So a service never
handles a message when it arrives: the Inbox keeps it until the service asks for "everything up to
tick k", then hands it over sorted by (tick, subscription order, key, sender, seq) — the same
order on any machine at any load.
"""

from __future__ import annotations

import heapq
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from operator import attrgetter
from typing import cast

import zenoh
from google.protobuf.message import Message

from hrc.bus.bus import Bus, Feed, M
from hrc.wire import pb

log = logging.getLogger(__name__)

Handler = Callable[[str, Message], None]

# How long a lockstep wait lets a vouched-for message be late before it asks the sender for it
# again, and how long each such ask may take (docs/ARCHITECTURE.md, "Lost messages").
REPLAY_AFTER_S = 2.0
REPLAY_ASK_S = 2.0


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

    def __init__(self, bus: Bus, gapless: bool = False) -> None:
        """``gapless`` (lockstep services): a (key, sender)'s messages count as received up to
        the last one with none missing before it, and a message had already is dropped. A lost
        message is then seen as missing even when later ones from the same sender came first
        (a participant's output of the next tick may overtake the tick that lists the lost
        one), and a replay's originals, should they still come, are not handed over twice.
        Without it (observers, whose router may drop what they cannot take), the highest seq
        received counts."""
        self._bus = bus
        self.gapless = gapless
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
        self._ahead: dict[tuple[str, str], set[int]] = {}  # gapless: seqs got past a hole
        self._feeds: list[Feed] = []  # per subscription, as _exprs
        self.recovered = 0  # messages got by a replay
        self.duplicates = 0  # messages dropped as had already (gapless)
        self.arrived = 0  # messages received so far (delivered or not)
        self._matches: dict[str, bool] = {}
        # (key, sender) -> the newest tick of its messages received, for those watched (watch())
        self._newest: dict[tuple[str, str], int] = {}

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
                mark = (k, sender)
                got = self._received.get(mark, 0)
                if not self.gapless:
                    if seq > got:
                        self._received[mark] = seq
                elif seq == got + 1:
                    ahead = self._ahead.get(mark)
                    while ahead and seq + 1 in ahead:
                        ahead.remove(seq + 1)
                        seq += 1
                    self._received[mark] = seq
                elif seq <= got or seq in self._ahead.get(mark, ()):
                    self.duplicates += 1
                    return
                else:  # past a hole: a message before it is late, or lost
                    self._ahead.setdefault(mark, set()).add(seq)
                if self._newest and self._newest.get(mark, tick) < tick:
                    self._newest[mark] = tick
                if problem is None:
                    bucket = self._pending.get(tick)
                    if bucket is None:
                        bucket = self._pending[tick] = []
                        heapq.heappush(self._pending_ticks, tick)
                    bucket.append(_Pending(tick, index, k, sender, h.seq, msg))
                self.arrived += 1
                if self._waiting:
                    self._cond.notify_all()
            if problem is not None:
                self._bus.reject(k, sender, problem)

        self._feeds.append(self._bus.subscribe(key, msg_type, on_msg))

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
            return self._lacking([m for m in marks if self._subscribed(m.key)])

    def _lacking(self, marks: list[pb.PublishedMark]) -> list[pb.PublishedMark]:
        """The marks whose messages have not all been received. Under the lock."""
        return [m for m in marks if self._received.get((m.key, m.sender), 0) < m.seq]

    def last_seq(self, key: str, sender: str) -> int:
        """The seq received up to on ``key`` from ``sender`` (0: none yet): gapless, the last
        one with none missing before it; else the highest."""
        with self._lock:
            return self._received.get((key, sender), 0)

    def wait_for(
        self, marks: list[pb.PublishedMark], timeout: float, replay: bool = False
    ) -> list[pb.PublishedMark]:
        """Waits until every mark is satisfied; returns what is still missing at the timeout.
        With ``replay``, what is still missing after REPLAY_AFTER_S (and again each
        REPLAY_AFTER_S) is asked of its sender (:meth:`recover`)."""
        wanted = [m for m in marks if self._subscribed(m.key)]
        if not wanted:
            return []
        start = time.monotonic()
        deadline = start + timeout
        ask_at = start + REPLAY_AFTER_S if replay else deadline
        while True:
            with self._cond:
                while True:
                    missing = self._lacking(wanted)
                    now = time.monotonic()
                    if not missing or now >= deadline:
                        return missing
                    if now >= ask_at:
                        break
                    self._await_arrival(min(deadline, ask_at) - now)
            for m in missing:
                self.recover(m, min(REPLAY_ASK_S, max(0.05, deadline - time.monotonic())))
            ask_at = time.monotonic() + REPLAY_AFTER_S

    def watch(self, key: str, sender: str) -> None:
        """Keep the newest tick of the messages from ``sender`` on ``key`` (wait_for_end)."""
        with self._lock:
            self._newest.setdefault((key, sender), -1)

    def wait_for_end(
        self, marks: list[pb.PublishedMark], after: list[tuple[str, str]], tick: int, timeout: float
    ) -> tuple[list[pb.PublishedMark], list[tuple[str, str]]]:
        """Waits until every mark is satisfied and a message of tick ``tick`` or later has come
        from each watched (key, sender) in ``after``; returns what is still missing of each at
        the timeout."""
        wanted = [m for m in marks if self._subscribed(m.key)]
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                missing = self._lacking(wanted)
                late = [ks for ks in after if self._newest.get(ks, -1) < tick]
                now = time.monotonic()
                if (not missing and not late) or now >= deadline:
                    return missing, late
                self._await_arrival(deadline - now)

    def _await_arrival(self, timeout: float) -> None:
        """Sleeps until a message arrives or ``timeout`` passes. Under the lock (the
        condition's); arrivals notify only while someone is counted as waiting."""
        self._waiting += 1
        try:
            self._cond.wait(timeout)
        finally:
            self._waiting -= 1

    def recover(self, mark: pb.PublishedMark, timeout: float) -> int:
        """Asks ``mark``'s sender for its messages on the key after the last one received and
        hands them over as if they had come (duplicates of them that still come are dropped).
        Returns how many came that way; each is a message the bus lost, or one very late."""
        key, sender = mark.key, mark.sender
        ke = zenoh.KeyExpr(key)
        feed = next(
            (f for e, f in zip(self._exprs, self._feeds, strict=True) if e.intersects(ke)), None
        )
        if feed is None:
            return 0
        got = self.last_seq(key, sender)
        items = self._bus.replay(key, sender, got, timeout)
        if not items:
            log.warning(
                "%s #%d from '%s' is late (received up to #%d) and its sender did not replay it",
                key, mark.seq, sender, got,
            )  # fmt: skip
            return 0
        before = self.duplicates
        for item in items:
            feed(key, sender, item)
        new = len(items) - (self.duplicates - before)
        self.recovered += new
        log.warning(
            "%s #%d from '%s' did not come within %g s (received up to #%d): its sender sent "
            "#%d-#%d again, %d of them new (a message the bus lost, or one very late)",
            key, mark.seq, sender, REPLAY_AFTER_S, got, got + 1, got + len(items), new,
        )  # fmt: skip
        return new

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
