"""The ISO/TS 15066 protective separation distance and the allowed speed (hrc.ssm)."""

from __future__ import annotations

import math

import pytest

from hrc.scenario import Ssm
from hrc.ssm import allowed_speed, protective_distance, resume_distance


def test_protective_distance_adds_every_term() -> None:
    p = Ssm(
        human_speed=1.6,
        reaction_time_s=0.1,
        deceleration=2.0,
        intrusion_distance_m=0.048,
        sensing_uncertainty_m=0.02,
        position_uncertainty_m=0.01,
    )
    v = 0.5
    s_h = 1.6 * (0.1 + 0.5 / 2.0)  # 0.56: the human during reaction and stopping (0.25 s)
    s_r = 0.5 * 0.1  # 0.05
    s_s = 0.5**2 / (2 * 2.0)  # 0.0625
    assert protective_distance(p, v) == pytest.approx(s_h + s_r + s_s + 0.048 + 0.02 + 0.01)
    assert protective_distance(p, v) == pytest.approx(0.7505)
    # At rest only the human's approach during the reaction time and the constants remain.
    assert protective_distance(p, 0.0) == pytest.approx(0.16 + 0.078)


def test_allowed_speed_inverts_the_protective_distance() -> None:
    p = Ssm()
    for v in (0.01, 0.1, 0.25, 0.5, 1.0, 1.5):
        assert allowed_speed(p, protective_distance(p, v)) == pytest.approx(v, abs=1e-9)
    # More room, more speed; monotonic.
    speeds = [allowed_speed(p, s / 100) for s in range(0, 200)]
    assert speeds == sorted(speeds)


def test_no_speed_at_or_below_the_protective_distance_at_rest() -> None:
    p = Ssm()
    at_rest = protective_distance(p, 0.0)
    assert allowed_speed(p, at_rest) == 0.0
    assert allowed_speed(p, at_rest - 0.01) == 0.0
    assert allowed_speed(p, 0.0) == 0.0
    assert allowed_speed(p, math.nan) == 0.0
    assert allowed_speed(p, at_rest + 0.01) > 0.0


def test_a_slower_human_allows_more_speed_weaker_brakes_less() -> None:
    s = 0.6
    base = allowed_speed(Ssm(), s)
    assert allowed_speed(Ssm(human_speed=1.0), s) > base
    assert allowed_speed(Ssm(deceleration=1.0), s) < base
    assert allowed_speed(Ssm(reaction_time_s=0.3), s) < base


def test_resume_distance_is_above_the_stop_distance() -> None:
    p = Ssm()
    assert resume_distance(p) == pytest.approx(protective_distance(p, p.min_speed) + 0.05)
    assert allowed_speed(p, resume_distance(p)) > p.min_speed
