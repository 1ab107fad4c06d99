"""What the scripted hand declares for the exchange step: the earliest time a grip may cross
GRIP_CLOSED (a lower bound, exact once the moves before it have started), and its speed bound
(no point of the hand faster than 2 x peak_hand_speed, turns included)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hrc.geometry import Pose, distance, rotate_z_rad, yaw_quat_rad
from hrc.participant.hand import Dwell, Grip, Hand, Move
from hrc.participant.motor import MotorParams
from hrc.participant.recording import Recording
from hrc.participant.sample import Sample
from hrc.scenario.conventions import GRIP_CLOSED, HAND_RADIUS_M

from hrc_human_input.replay import Replayer

HZ = 240.0
DT = 1.0 / HZ


def _hand(seed: int = 3) -> Hand:
    return Hand("right", (0.2, -0.5, 0.1), 0.0, MotorParams(), np.random.default_rng(seed))


def _crossing_ticks(hand: Hand, ticks: int) -> tuple[list[int], list[float | None]]:
    """The ticks at which the grip crosses GRIP_CLOSED, and the prediction after each tick."""
    crossings: list[int] = []
    predicted: list[float | None] = []
    before = hand.grip
    for k in range(ticks):
        hand.advance(k * DT)
        if (before < GRIP_CLOSED) != (hand.grip < GRIP_CLOSED):
            crossings.append(k)
        before = hand.grip
        predicted.append(hand.grip_crossing_not_before(k * DT, GRIP_CLOSED))
    return crossings, predicted


def test_the_declared_grip_crossing_is_a_lower_bound_and_exact_once_the_moves_run() -> None:
    hand = _hand()
    hand.do(
        Move((0.0, -0.3, 0.1), math.pi / 2, 0.06),
        Move((0.0, -0.3, 0.02), None, 0.06),
        Grip(1.0),
        Dwell(0.2),
        Move((0.1, -0.2, 0.15), None, 0.1),
        Grip(0.0),
    )
    crossings, predicted = _crossing_ticks(hand, 1200)
    assert len(crossings) == 2, "the grip closes, then opens"
    for k, at in enumerate(predicted):
        upcoming = [c for c in crossings if c > k]
        if not upcoming:
            assert at is None or at / DT > 1200
            continue
        tick = math.ceil(at / DT - 1e-6) if at is not None else None
        assert tick is not None and tick <= upcoming[0], (k, tick, upcoming[0])
    # once the grip ramp runs the prediction is the crossing's tick (or the one before: the
    # ramp's sum of steps may round below the threshold; a later ack declares again)
    for c in crossings:
        at = predicted[c - 2]
        assert at is not None and c - 1 <= math.ceil(at / DT - 1e-6) <= c


def _fastest_corner(hand: Hand, ticks: int) -> float:
    """The fastest a corner of the hand box (at HAND_RADIUS_M from its centre) moved."""
    corner = (HAND_RADIUS_M, 0.0, 0.0)
    last = None
    fastest = 0.0
    for k in range(ticks):
        hand.advance(k * DT)
        c = rotate_z_rad(corner, hand.yaw_rad)
        point = (hand.pos[0] + c[0], hand.pos[1] + c[1], hand.pos[2] + c[2])
        if last is not None:
            fastest = max(fastest, distance(point, last) / DT)
        last = point
    return fastest


def test_no_point_of_the_hand_moves_faster_than_twice_the_peak_speed() -> None:
    motor = MotorParams(peak_hand_speed=1.0)
    # a pure half turn of the wrist: the turn's own cap binds (without it: about 3 m/s)
    hand = Hand("left", (0.0, 0.0, 0.1), 0.0, motor, np.random.default_rng(1))
    hand.do(Move((0.0, 0.0, 0.1), math.pi, 0.2))
    assert 0.9 < _fastest_corner(hand, 600) <= 1.0 + 1e-6
    # a reach with a half turn: centre and turn each at most the peak speed
    for seed in range(5):
        hand = Hand("left", (0.0, 0.0, 0.1), 0.0, motor, np.random.default_rng(seed))
        hand.do(Move((0.1, 0.05, 0.1), math.pi, 0.02), Move((0.5, 0.0, 0.1), 0.0, 0.2))
        assert _fastest_corner(hand, 1200) <= 2.0 * motor.peak_hand_speed


def test_a_replay_declares_its_grip_crossings_and_its_fastest_hand() -> None:
    def sample(t: float, x: float, yaw: float, grip: float) -> Sample:
        return Sample(t, Pose(), Pose((x, 0.0, 0.1), yaw_quat_rad(yaw)), Pose(), grip, 0.0)

    samples = [
        sample(0.0, 0.0, 0.0, 0.0),
        sample(0.5, 0.2, 0.0, 0.0),  # 0.4 m/s
        sample(1.0, 0.2, math.pi / 2, 1.0),  # a quarter turn in 0.5 s, the grip closes
        sample(2.0, 0.2, math.pi / 2, 0.0),  # opens
    ]
    player = Replayer(Recording(header={}, samples=samples))
    assert player.grip_crossing_after(0.0, GRIP_CLOSED) == pytest.approx(0.75)
    assert player.grip_crossing_after(0.75, GRIP_CLOSED) == pytest.approx(1.5)
    assert player.grip_crossing_after(1.5, GRIP_CLOSED) is None
    turn = (math.pi / 2) * HAND_RADIUS_M / 0.5
    assert player.hand_speed_bound() == pytest.approx(max(0.4, turn))
