"""Minimum-jerk reaches and Fitts' law."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from hrc.participant.motor import (
    MIN_JERK_PEAK_FACTOR,
    MotorParams,
    Segment,
    fitts_index,
    fitts_mt,
    min_jerk,
    min_jerk_speed,
    movement_time,
    reaction_time,
)


def speed_profile(seg: Segment, hz: float = 240.0) -> np.ndarray:
    ts = np.arange(seg.t0, seg.t_end + 1.0 / hz, 1.0 / hz)
    pos = np.array([seg.position(t) for t in ts])
    return np.linalg.norm(np.diff(pos, axis=0), axis=1) * hz


def count_peaks(speed: np.ndarray, rel: float = 0.01) -> int:
    """Local maxima standing out by more than rel * max from their neighbourhood minima."""
    peaks = 0
    top = float(speed.max())
    low = float(speed[0])
    rising = True
    for a, b in itertools.pairwise(speed):
        if rising and b < a - 1e-12:
            if a - low > rel * top:
                peaks += 1
            rising, low = False, b
        elif not rising:
            if b > a + 1e-12 and a < low + 1e-12:
                rising, low = True, a
            low = min(low, b)
    return peaks


def test_min_jerk_boundaries_and_symmetry() -> None:
    assert min_jerk(0.0) == 0.0 and min_jerk(1.0) == 1.0
    assert min_jerk(0.5) == pytest.approx(0.5)
    assert min_jerk_speed(0.0) == 0.0 and min_jerk_speed(1.0) == 0.0
    assert min_jerk_speed(0.5) == pytest.approx(MIN_JERK_PEAK_FACTOR)
    for tau in (0.1, 0.3, 0.45):
        assert min_jerk(tau) + min_jerk(1 - tau) == pytest.approx(1.0)


@pytest.mark.parametrize("distance", [0.30, 0.40, 0.50, 0.60])
def test_reach_has_one_speed_peak_in_the_human_range(distance: float) -> None:
    p = MotorParams()  # the scenario defaults: a = 0.1 s, b = 0.15 s/bit, peak <= 1 m/s
    mt = movement_time(distance, 0.06, p)
    seg = Segment(0.0, mt, (0.2, -0.55, 0.1), (0.2 - distance * 0.6, -0.55 + distance * 0.8, 0.1))
    speed = speed_profile(seg)
    peak = float(speed.max())
    print(f"reach {distance:.2f} m: MT {mt:.3f} s, peak hand speed {peak:.3f} m/s")
    assert count_peaks(speed) == 1
    assert 0.5 <= peak <= 2.0
    assert peak == pytest.approx(seg.peak_speed, rel=0.01)
    # the peak is in the middle of the movement (bell-shaped, symmetric)
    assert int(np.argmax(speed)) == pytest.approx(len(speed) / 2, abs=2)


def test_peak_counter_sees_two_bells() -> None:
    a = Segment(0.0, 0.5, (0, 0, 0), (0.3, 0, 0))
    b = Segment(0.5, 0.5, (0.3, 0, 0), (0.6, 0, 0))
    ts = np.arange(0.0, 1.0, 1 / 240)
    pos = np.array([a.position(t) if t < 0.5 else b.position(t) for t in ts])
    speed = np.linalg.norm(np.diff(pos, axis=0), axis=1) * 240
    assert count_peaks(speed) == 2


def test_fitts_law() -> None:
    assert fitts_index(0.4, 0.05) == pytest.approx(math.log2(16))
    assert fitts_mt(0.4, 0.05, 0.1, 0.15) == pytest.approx(0.1 + 0.15 * 4)
    assert fitts_mt(0.2, 0.05, 0.1, 0.15) < fitts_mt(0.4, 0.05, 0.1, 0.15)
    assert fitts_mt(0.4, 0.10, 0.1, 0.15) < fitts_mt(0.4, 0.05, 0.1, 0.15)
    assert fitts_index(0.0, 0.05) == 0.0
    assert fitts_index(0.01, 0.05) == 0.0  # already within the target
    with pytest.raises(ValueError):
        fitts_index(0.1, 0.0)


def test_movement_time_respects_peak_speed_and_varies_with_seed() -> None:
    slow = MotorParams(peak_hand_speed=0.5)
    mt = movement_time(0.5, 0.06, slow)
    assert MIN_JERK_PEAK_FACTOR * 0.5 / mt <= 0.5 + 1e-9
    rng1, rng2 = np.random.default_rng(1), np.random.default_rng(1)
    a = [movement_time(0.3, 0.06, MotorParams(peak_hand_speed=5.0), rng1) for _ in range(20)]
    b = [movement_time(0.3, 0.06, MotorParams(peak_hand_speed=5.0), rng2) for _ in range(20)]
    assert a == b and len(set(a)) == 20
    assert np.median(a) == pytest.approx(fitts_mt(0.3, 0.06, 0.1, 0.15), rel=0.1)


def test_reaction_time_distribution() -> None:
    rng = np.random.default_rng(7)
    p = MotorParams(reaction_time_s=0.4)
    rts = np.array([reaction_time(p, rng) for _ in range(4000)])
    print(f"reaction time median {np.median(rts):.3f} s, mean {rts.mean():.3f} s")
    assert np.median(rts) == pytest.approx(0.4, rel=0.05)
    assert rts.mean() > np.median(rts)  # right-skewed like measured reaction times
    assert (rts > 0).all()
    assert reaction_time(MotorParams(reaction_time_s=0.0), rng) == 0.0
