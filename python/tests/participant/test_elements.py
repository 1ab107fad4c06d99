"""The scripted participant's profiles against published element times (docs/participant-model.md).

The `real` profile must stay within +-15 % of MTM-1 for reach (R-A, R-B) and move (M-B, M-C) at
10-61 cm and for a 40 cm pick-and-place; the baseline, which nobody fitted, is far outside: the
check tells them apart.
"""

from __future__ import annotations

import numpy as np
import pytest

from hrc.participant.elements import (
    DISTANCES_IN,
    MTM_TMU,
    REAL_TOLERANCE,
    element_times,
    pick_and_place_time,
    profile_report,
)
from hrc.participant.hand import Hand, Move
from hrc.participant.motor import MIN_JERK_PEAK_FACTOR, MotorParams
from hrc.scenario import ParticipantProfile, ScriptedParams


def params(profile: str) -> ScriptedParams:
    return ScriptedParams.model_validate({"profile": profile})


def test_real_profile_matches_mtm_within_15_percent() -> None:
    times = element_times(params("real"))
    assert len(times) == len(MTM_TMU) * len(DISTANCES_IN)
    worst = max(times, key=lambda e: abs(e.ratio - 1.0))
    print(f"\nreal: worst {worst.element} at {worst.distance_cm:.0f} cm: ratio {worst.ratio:.3f}")
    for e in times:
        assert abs(e.ratio - 1.0) <= REAL_TOLERANCE, e
    pnp = pick_and_place_time(params("real"))
    print(f"pick-and-place: {pnp.model_s:.3f} s vs MTM {pnp.reference_s:.3f} s")
    assert abs(pnp.ratio - 1.0) <= REAL_TOLERANCE


def test_the_check_tells_an_unfitted_participant_apart() -> None:
    report = profile_report(ParticipantProfile.BASELINE)
    assert not report["within_15pct_of_mtm"]
    assert report["pick_and_place"]["ratio"] > 1.5
    # written keys win over the profile: the real profile with the baseline's Fitts line fails
    slow = ScriptedParams.model_validate({"profile": "real", "fitts_a_s": 0.1, "fitts_b_s": 0.15})
    assert any(abs(e.ratio - 1.0) > REAL_TOLERANCE for e in element_times(slow))


def test_vr_profile_is_slower_and_later_than_real() -> None:
    real, vr = profile_report(ParticipantProfile.REAL), profile_report(ParticipantProfile.VR)
    assert vr["within_vr_band"]
    assert vr["pick_and_place"]["model_s"] > 2.0 * real["pick_and_place"]["model_s"]
    assert vr["reaction_s"]["visual"] > real["reaction_s"]["visual"]
    # reaction medians inside the literature's ranges for the real person
    assert 0.19 <= real["reaction_s"]["visual"] <= 0.23
    assert 0.16 <= real["reaction_s"]["collision"] <= 0.19


def test_a_reach_in_one_motion_passes_above_the_part_under_the_speed_cap() -> None:
    p = params("real")
    motor = MotorParams.of(p)
    above, goal = (0.3, 0.0, 0.18), (0.3, 0.0, 0.10)
    hand = Hand("right", (0.0, 0.0, 0.18), 0.0, motor, np.random.default_rng(3))
    hand.do(Move(goal, None, 0.06, "reach", via=(above,)))
    hand.advance(0.0)
    seg = hand.segment
    assert seg is not None and seg.distance == pytest.approx(0.38)
    ts = np.linspace(seg.t0, seg.t_end, 2001)
    pos = np.array([seg.position(float(t)) for t in ts])
    # it comes down onto the part: never below the approach height before it is above the part
    assert all(z >= 0.18 - 1e-9 for x, _y, z in pos if x < 0.3 - 1e-6)
    assert np.allclose(pos[-1], goal)
    speed = np.linalg.norm(np.diff(pos, axis=0), axis=1) / (ts[1] - ts[0])
    assert speed.max() <= p.peak_hand_speed * 1.001
    assert speed.max() == pytest.approx(MIN_JERK_PEAK_FACTOR * 0.38 / seg.mt, rel=0.01)


def test_a_cancelled_move_is_followed_without_a_jump() -> None:
    """Cancelling a move half-way and starting another goes on from where the hand is: the
    next move starts then, not when the cancelled one did (the hand used to jump)."""
    motor = MotorParams.of(params("vr"))  # long moves: a jump would be centimetres
    hand = Hand("right", (0.0, 0.0, 0.1), 0.0, motor, np.random.default_rng(5))
    hand.do(Move((0.5, 0.0, 0.1), None, 0.06))
    t, dt, last = 0.0, 1.0 / 240.0, (0.0, 0.0, 0.1)
    hand.advance(t)
    steps = []
    while t < 4.0:
        t += dt
        if abs(t - 1.0) < dt / 2:
            hand.cancel()
            hand.do(Move((0.2, -0.3, 0.2), None, 0.06))
        hand.advance(t)
        steps.append(float(np.linalg.norm(np.subtract(hand.pos, last))) / dt)
        last = hand.pos
    assert max(steps) <= motor.peak_hand_speed * 1.001


def test_the_bench_command_prints_the_figures(capsys: pytest.CaptureFixture[str]) -> None:
    import argparse
    import json

    from hrc.bench.participant import run

    assert run(argparse.Namespace(json=True)) == 0
    data = json.loads(capsys.readouterr().out)
    assert set(data["profiles"]) == {"baseline", "real", "vr"}
    assert data["profiles"]["real"]["within_15pct_of_mtm"]
    assert not data["profiles"]["baseline"]["within_15pct_of_mtm"]
    elements = {(e["element"], e["distance_cm"]) for e in data["profiles"]["real"]["elements"]}
    assert ("R-A", 10.2) in elements and ("M-C", 61.0) in elements
    assert run(argparse.Namespace(json=False)) == 0
    table = capsys.readouterr().out
    assert "profile real: max |model/MTM - 1| = 0.137 (within +-15 %)" in table
