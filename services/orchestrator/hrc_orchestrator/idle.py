"""Interval accounting on the task timer (robot dependency waits, human idle)."""

from __future__ import annotations


class IntervalClock:
    """Sums the lengths of [begin, end) intervals of task time; at most one is open at a time."""

    def __init__(self) -> None:
        self.total = 0.0
        self.open_since: float | None = None

    @property
    def running(self) -> bool:
        return self.open_since is not None

    def begin(self, t: float) -> bool:
        """Opens an interval at t; False if one is already open."""
        if self.open_since is not None:
            return False
        self.open_since = t
        return True

    def end(self, t: float) -> float | None:
        """Closes the open interval at t and returns its length (None if none was open)."""
        if self.open_since is None:
            return None
        length = max(0.0, t - self.open_since)
        self.total += length
        self.open_since = None
        return length

    def value(self, t: float) -> float:
        """The total including the open interval up to t."""
        if self.open_since is None:
            return self.total
        return self.total + max(0.0, t - self.open_since)
