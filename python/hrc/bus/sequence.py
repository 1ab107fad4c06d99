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
class SeqChecker:
    """Thread-safe; ``check`` returns the problem (also logged and counted) or None."""

    gaps: int = 0  # problems seen (each gap or step back counts once)
    lost: int = 0  # messages known to be missing (sum of gap sizes)
    messages: int = 0
    _last: dict[tuple[str, str], int] = field(default_factory=dict)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def check(self, key: str, sender: str, seq: int) -> SeqProblem | None:
        with self._lock:
            self.messages += 1
            mark = (key, sender)
            expected = self._last.get(mark, 0) + 1
            problem = None
            if seq != expected:
                problem = SeqProblem(key, sender, expected, seq)
                self.gaps += 1
                self.lost += problem.missing
            if seq > self._last.get(mark, 0):
                self._last[mark] = seq
        if problem is not None:
            log.error("%s", problem.describe())
        return problem

    def last(self, key: str, sender: str) -> int:
        with self._lock:
            return self._last.get((key, sender), 0)
