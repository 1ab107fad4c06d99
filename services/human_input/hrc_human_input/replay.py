"""Playing a recording back on simulation time (the format and its reading and writing:
hrc.participant.recording, docs/replay-format.md)."""

from __future__ import annotations

import bisect
import itertools
import logging
import math

from hrc.geometry import Quat, distance, quat_norm
from hrc.participant.recording import Recording
from hrc.participant.sample import Sample, interpolate
from hrc.scenario.conventions import HAND_RADIUS_M, HANDS

log = logging.getLogger(__name__)


def _turn_rad(a: Quat, b: Quat) -> float:
    """The angle between two orientations (pi if one is degenerate)."""
    na, nb = quat_norm(a), quat_norm(b)
    if na <= 0 or nb <= 0:
        return math.pi
    dot = abs(sum(x * y for x, y in zip(a, b, strict=True))) / (na * nb)
    return 2.0 * math.acos(min(1.0, dot))


class Replayer:
    """Plays a recording on simulation time: the sample at t, interpolated between neighbours;
    before the first sample the first one holds, after the last the last one holds."""

    def __init__(self, recording: Recording) -> None:
        if not recording.samples:
            raise ValueError("a recording without samples cannot be played")
        self.samples = recording.samples
        self._times = [s.t for s in self.samples]

    @property
    def duration(self) -> float:
        return self._times[-1]

    def grip_crossing_after(self, t: float, threshold: float) -> float | None:
        """The first time after ``t`` a grip crosses ``threshold`` as played (grips are
        interpolated linearly between samples); None if none does."""
        i = max(0, bisect.bisect_right(self._times, t) - 1)
        for a, b in itertools.pairwise(self.samples[i:]):
            for ga, gb in ((a.left_grip, b.left_grip), (a.right_grip, b.right_grip)):
                if (ga < threshold) != (gb < threshold):
                    u = (threshold - ga) / (gb - ga)
                    at = a.t + u * (b.t - a.t)
                    if at > t:
                        return at
        return None

    def hand_speed_bound(self) -> float:
        """m/s no point of a hand exceeds in this recording: between two samples a hand moves
        and turns at a constant rate (interpolate), a point at most |v| + w * HAND_RADIUS_M."""
        bound = 0.0
        for a, b in itertools.pairwise(self.samples):
            span = b.t - a.t
            if span <= 0:
                continue
            for name in HANDS:
                pa, pb_ = a.hand(name), b.hand(name)
                turn = _turn_rad(pa.orientation, pb_.orientation)
                move = distance(pa.position, pb_.position) + turn * HAND_RADIUS_M
                bound = max(bound, move / span)
        return bound

    def sample_at(self, t: float) -> Sample:
        i = bisect.bisect_left(self._times, t)
        if i < len(self._times) and self._times[i] == t:
            return self.samples[i]  # exact hit: bit-identical to what was recorded
        if i == 0:
            return self.samples[0].at(t)
        if i >= len(self._times):
            return self.samples[-1].at(t)
        return interpolate(self.samples[i - 1], self.samples[i], t)
