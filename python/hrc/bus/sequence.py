"""Per (sender, key) sequence-number check: the logger must notice every lost message.

``header.seq`` starts at 1 and grows by 1 per message a sender publishes on a key
(docs/ARCHITECTURE.md). A jump means messages were lost; a repeat or step back means a duplicate
or reordering. Each problem is logged as an error line and counted.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass, field

log = logging.getLogger(__name__)


@dataclass
class SeqProblem:
    key: str
    sender: str
    expected: int
    got: int

    @property
    def missing(self) -> int:
        """Messages lost (0 for a duplicate / step back)."""
        return max(0, self.got - self.expected)

    def describe(self) -> str:
        if self.got > self.expected:
            return (
                f"sequence gap on {self.key} from {self.sender!r}: expected seq {self.expected}, "
                f"got {self.got} ({self.missing} message(s) lost)"
            )
        return (
            f"sequence out of order on {self.key} from {self.sender!r}: expected seq "
            f"{self.expected}, got {self.got} (duplicate or reordered)"
        )


@dataclass
class LossSpan:
    """Messages lost between two ticks: those of the last message received before a gap and of
    the first after it."""

    from_tick: int
    to_tick: int
    messages: int
    key: str = ""


def _merged(spans: list[LossSpan]) -> list[LossSpan]:
    out: list[LossSpan] = []
    for sp in sorted(spans, key=lambda sp: (sp.from_tick, sp.to_tick)):
        if out and sp.from_tick <= out[-1].to_tick:
            out[-1].to_tick = max(out[-1].to_tick, sp.to_tick)
            out[-1].messages += sp.messages
        else:
            out.append(LossSpan(sp.from_tick, sp.to_tick, sp.messages))
    return out


@dataclass
class SeqChecker:
    """Thread-safe; ``check`` returns the problem (also logged and counted) or None."""

    gaps: int = 0  # problems seen (each gap or step back counts once)
    lost: int = 0  # messages known to be missing (sum of gap sizes)
    messages: int = 0
    _last: dict[tuple[str, str], int] = field(default_factory=dict)
    _last_tick: dict[tuple[str, str], int] = field(default_factory=dict)
    _spans: list[LossSpan] = field(default_factory=list)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def check(self, key: str, sender: str, seq: int, tick: int = 0) -> SeqProblem | None:
        """``tick``: the message's (header.tick), to tell when a gap happened."""
        with self._lock:
            self.messages += 1
            mark = (key, sender)
            expected = self._last.get(mark, 0) + 1
            problem = None
            if seq != expected:
                problem = SeqProblem(key, sender, expected, seq)
                self.gaps += 1
                self.lost += problem.missing
                if problem.missing:
                    self._spans.append(
                        LossSpan(self._last_tick.get(mark, 0), tick, problem.missing, key)
                    )
            if seq > self._last.get(mark, 0):
                self._last[mark] = seq
                self._last_tick[mark] = tick
        if problem is not None:
            log.error("%s", problem.describe())
        return problem

    def loss_spans(self, timeline: str = "") -> list[LossSpan]:
        """When messages were lost, in tick order. The gaps of the ``timeline`` key (the clock:
        a message every tick or exchange) tell when nothing came through; a gap of a key that
        publishes seldom (its last message may be far older) counts towards the first of those
        spans it overlaps. Without timeline gaps, the gaps themselves, overlapping ones merged."""
        with self._lock:
            gaps = list(self._spans)
        spans = _merged([g for g in gaps if g.key == timeline])
        rest: list[LossSpan] = []
        for g in gaps:
            if g.key == timeline:
                continue
            hit = next(
                (sp for sp in spans if g.from_tick <= sp.to_tick and sp.from_tick <= g.to_tick),
                None,
            )
            if hit is not None:
                hit.messages += g.messages
            else:
                rest.append(g)
        return sorted(spans + _merged(rest), key=lambda sp: sp.from_tick)

    def last(self, key: str, sender: str) -> int:
        with self._lock:
            return self._last.get((key, sender), 0)
