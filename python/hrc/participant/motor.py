"""Motor-control models of the scripted participant.

- Minimum-jerk point-to-point reaches (Flash & Hogan 1985):
  x(tau) = x0 + (x1 - x0) (10 tau^3 - 15 tau^4 + 6 tau^5), tau = t / MT in [0, 1];
  the speed profile is a single symmetric bell with peak 1.875 D / MT at tau = 0.5.
- Movement time from Fitts' law with Fitts' (1954) original index of difficulty
  ID = log2(2D/W) bits, plus a transport term linear in the distance travelled:
  MT = a + b * ID + c * D (ID floored at 0). Fitts' law alone is concave in D; the MTM-1 element
  times a person is checked against grow linearly in D over 10-60 cm, which c carries
  (docs/participant-model.md). A move to a place the hand knows without looking (FIXED_PLACE)
  needs no homing: ID 0.
- A move may pass through via points (a reach that comes down onto a part from above in one
  motion): the minimum-jerk profile then runs along the polyline's length.
- Reaction time: lognormal (right-skewed like measured simple/choice reaction times), with the
  median given by the scenario and a log-standard deviation of 0.25.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from hrc.geometry import Vec3, distance, lerp, lerp3
from hrc.scenario import ScriptedParams

# Peak speed of a minimum-jerk reach is this factor times the mean speed D / MT.
MIN_JERK_PEAK_FACTOR = 1.875
REACTION_LOG_SD = 0.25  # lognormal spread of reaction times (about +-25 % around the median)
MOVEMENT_TIME_SD = 0.08  # relative trial-to-trial variability of movement times
MIN_MOVEMENT_TIME_S = 0.05
# Fitts width of a move to a place the hand knows without looking (its resting place): no homing
# phase, so no index of difficulty (MTM-1's case A, "reach to an object in a fixed location").
FIXED_PLACE = math.inf


def min_jerk(tau: float) -> float:
    """Normalised minimum-jerk position profile s(tau), s(0) = 0, s(1) = 1."""
    tau = min(1.0, max(0.0, tau))
    return tau**3 * (10.0 - 15.0 * tau + 6.0 * tau * tau)


def min_jerk_speed(tau: float) -> float:
    """ds/dtau of the profile (multiply by D / MT for m/s)."""
    tau = min(1.0, max(0.0, tau))
    return 30.0 * tau * tau * (1.0 - tau) ** 2


def fitts_index(distance_m: float, width_m: float) -> float:
    """Fitts' index of difficulty log2(2D/W) in bits; 0 when the target is already within reach."""
    if width_m <= 0:
        raise ValueError(f"target width must be > 0, got {width_m}")
    if distance_m <= 0 or math.isinf(width_m):
        return 0.0
    return max(0.0, math.log2(2.0 * distance_m / width_m))


def fitts_mt(
    distance_m: float, width_m: float, a_s: float, b_s: float, c_s_per_m: float = 0.0
) -> float:
    """Movement time MT = a + b log2(2D/W) + c D in seconds (c = 0: Fitts' law)."""
    return a_s + b_s * fitts_index(distance_m, width_m) + c_s_per_m * max(0.0, distance_m)


@dataclass(frozen=True)
class MotorParams:
    """The scripted participant's motor parameters (docs/scenario.md, the [participant] table)."""

    reaction_time_s: float = 0.4
    peak_hand_speed: float = 1.0  # m/s, upper bound of a reach's peak speed
    fitts_a_s: float = 0.1
    fitts_b_s: float = 0.15
    fitts_c_s_per_m: float = 0.0
    grip_close_s: float = 0.15  # grip 0 -> 1
    grip_open_s: float = 0.10  # grip 1 -> 0

    @classmethod
    def of(cls, p: ScriptedParams) -> MotorParams:
        """The motor parameters among a scenario's scripted-participant parameters."""
        return cls(
            reaction_time_s=p.reaction_time_s,
            peak_hand_speed=p.peak_hand_speed,
            fitts_a_s=p.fitts_a_s,
            fitts_b_s=p.fitts_b_s,
            fitts_c_s_per_m=p.fitts_c_s_per_m,
            grip_close_s=p.grip_close_s,
            grip_open_s=p.grip_open_s,
        )


def movement_time(
    distance_m: float, width_m: float, p: MotorParams, rng: np.random.Generator | None = None
) -> float:
    """Fitts' time, with trial-to-trial variability, and never so short that the peak speed of
    the minimum-jerk profile would exceed ``peak_hand_speed``."""
    mt = fitts_mt(distance_m, width_m, p.fitts_a_s, p.fitts_b_s, p.fitts_c_s_per_m)
    if rng is not None:
        mt *= float(rng.lognormal(0.0, MOVEMENT_TIME_SD))
    speed_floor = MIN_JERK_PEAK_FACTOR * distance_m / p.peak_hand_speed
    return max(mt, speed_floor, MIN_MOVEMENT_TIME_S)


def reaction_time(p: MotorParams, rng: np.random.Generator, factor: float = 1.0) -> float:
    """A reaction time drawn from a lognormal with median ``reaction_time_s * factor``."""
    return reaction_draw(p.reaction_time_s * factor, rng)


def reaction_draw(median_s: float, rng: np.random.Generator) -> float:
    """A reaction time drawn from a lognormal with median ``median_s`` (0 if it is <= 0)."""
    if median_s <= 0:
        return 0.0
    return float(median_s * rng.lognormal(0.0, REACTION_LOG_SD))


def path_length(points: tuple[Vec3, ...]) -> float:
    return sum(distance(a, b) for a, b in itertools.pairwise(points))


@dataclass(frozen=True)
class Segment:
    """One minimum-jerk reach from p0 to p1 (and yaw0 to yaw1) starting at t0, lasting mt; with
    via points, along the polyline p0 -> via... -> p1 (the profile over its whole length)."""

    t0: float
    mt: float
    p0: Vec3
    p1: Vec3
    yaw0_rad: float = 0.0
    yaw1_rad: float = 0.0
    via: tuple[Vec3, ...] = ()

    @property
    def t_end(self) -> float:
        return self.t0 + self.mt

    @property
    def distance(self) -> float:
        """The length of the hand's path."""
        if not self.via:
            return distance(self.p0, self.p1)
        return path_length((self.p0, *self.via, self.p1))

    @property
    def peak_speed(self) -> float:
        return MIN_JERK_PEAK_FACTOR * self.distance / self.mt if self.mt > 0 else 0.0

    def progress(self, t: float) -> float:
        return min_jerk((t - self.t0) / self.mt) if self.mt > 0 else 1.0

    def position(self, t: float) -> Vec3:
        u = self.progress(t)
        if not self.via:
            return lerp3(self.p0, self.p1, u)
        points = (self.p0, *self.via, self.p1)
        left = u * path_length(points)
        for a, b in itertools.pairwise(points):
            d = distance(a, b)
            if left <= d and d > 0.0:
                return lerp3(a, b, left / d)
            left -= d
        return self.p1

    def yaw_rad(self, t: float) -> float:
        return lerp(self.yaw0_rad, self.yaw1_rad, self.progress(t))

    def done(self, t: float) -> bool:
        return t >= self.t_end - 1e-12
