"""Motor-control models of the scripted participant.

- Minimum-jerk point-to-point reaches (Flash & Hogan 1985):
  x(tau) = x0 + (x1 - x0) (10 tau^3 - 15 tau^4 + 6 tau^5), tau = t / MT in [0, 1];
  the speed profile is a single symmetric bell with peak 1.875 D / MT at tau = 0.5.
- Movement time from Fitts' law with Fitts' (1954) original index of difficulty
  ID = log2(2D/W) bits: MT = a + b * ID (ID floored at 0). Defaults a = 0.1 s, b = 0.15 s/bit:
  see the service README for where they come from.
- Reaction time: lognormal (right-skewed like measured simple/choice reaction times), with the
  median given by the scenario and a log-standard deviation of 0.25.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hrc.geometry import Vec3, distance, lerp, lerp3

# Peak speed of a minimum-jerk reach is this factor times the mean speed D / MT.
MIN_JERK_PEAK_FACTOR = 1.875
REACTION_LOG_SD = 0.25  # lognormal spread of reaction times (about +-25 % around the median)
MOVEMENT_TIME_SD = 0.08  # relative trial-to-trial variability of movement times
MIN_MOVEMENT_TIME_S = 0.05


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
    if distance_m <= 0:
        return 0.0
    return max(0.0, math.log2(2.0 * distance_m / width_m))


def fitts_mt(distance_m: float, width_m: float, a_s: float, b_s: float) -> float:
    """Fitts' law movement time MT = a + b log2(2D/W) in seconds."""
    return a_s + b_s * fitts_index(distance_m, width_m)


@dataclass(frozen=True)
class MotorParams:
    """The scripted participant's motor parameters (docs/scenario.md, the [participant] table)."""

    reaction_time_s: float = 0.4
    peak_hand_speed: float = 1.0  # m/s, upper bound of a reach's peak speed
    fitts_a_s: float = 0.1
    fitts_b_s: float = 0.15
    grip_close_s: float = 0.15  # grip 0 -> 1
    grip_open_s: float = 0.10  # grip 1 -> 0


def movement_time(
    distance_m: float, width_m: float, p: MotorParams, rng: np.random.Generator | None = None
) -> float:
    """Fitts' time, with trial-to-trial variability, and never so short that the peak speed of
    the minimum-jerk profile would exceed ``peak_hand_speed``."""
    mt = fitts_mt(distance_m, width_m, p.fitts_a_s, p.fitts_b_s)
    if rng is not None:
        mt *= float(rng.lognormal(0.0, MOVEMENT_TIME_SD))
    speed_floor = MIN_JERK_PEAK_FACTOR * distance_m / p.peak_hand_speed
    return max(mt, speed_floor, MIN_MOVEMENT_TIME_S)


def reaction_time(p: MotorParams, rng: np.random.Generator, factor: float = 1.0) -> float:
    """A reaction time drawn from a lognormal with median ``reaction_time_s * factor``."""
    median = p.reaction_time_s * factor
    if median <= 0:
        return 0.0
    return float(median * rng.lognormal(0.0, REACTION_LOG_SD))


@dataclass(frozen=True)
class Segment:
    """One minimum-jerk reach from p0 to p1 (and yaw0 to yaw1) starting at t0, lasting mt."""

    t0: float
    mt: float
    p0: Vec3
    p1: Vec3
    yaw0_rad: float = 0.0
    yaw1_rad: float = 0.0

    @property
    def t_end(self) -> float:
        return self.t0 + self.mt

    @property
    def distance(self) -> float:
        return distance(self.p0, self.p1)

    @property
    def peak_speed(self) -> float:
        return MIN_JERK_PEAK_FACTOR * self.distance / self.mt if self.mt > 0 else 0.0

    def progress(self, t: float) -> float:
        return min_jerk((t - self.t0) / self.mt) if self.mt > 0 else 1.0

    def position(self, t: float) -> Vec3:
        return lerp3(self.p0, self.p1, self.progress(t))

    def yaw_rad(self, t: float) -> float:
        return lerp(self.yaw0_rad, self.yaw1_rad, self.progress(t))

    def done(self, t: float) -> bool:
        return t >= self.t_end - 1e-12
