"""What the participant publishes per tick is built in place (one HumanState, hand poses kept
while a hand stands still): it must carry exactly what freshly built ones would."""

from __future__ import annotations

import math

import numpy as np
from test_scripted import make_world

from hrc.geometry import Pose, yaw_quat_rad
from hrc.participant.hand import Hand, Move
from hrc.participant.motor import MotorParams
from hrc.participant.sample import Sample
from hrc.scenario import InputSource
from hrc.wire import pb


def test_a_message_filled_again_serializes_like_a_fresh_one() -> None:
    # the second sample has zeros where the first had values: nothing of the first may stay
    first = Sample(
        0.1,
        Pose((0.1, -0.7, 0.6), (0.0, 0.0, 0.6, 0.8)),
        Pose((-0.2, -0.5, 0.1), (0.0, 0.0, 0.0, 1.0)),
        Pose((0.2, -0.5, 0.1), (0.0, 0.0, 0.6, 0.8)),
        1.0,
        0.4,
    )
    second = Sample(0.2, Pose(), Pose((0.0, 0.0, 0.0)), Pose((0.3, 0.0, 0.0)), 0.0, 0.0)
    msg = pb.HumanState(hand_speed_bound=2.0)
    for sample in (first, second, first):
        sample.into_proto(msg, InputSource.SCRIPTED)
        fresh = sample.to_proto(InputSource.SCRIPTED)
        fresh.hand_speed_bound = 2.0
        assert msg.SerializeToString() == fresh.SerializeToString()


def test_a_hand_turning_on_the_spot_gets_a_new_pose() -> None:
    hand = Hand("right", (0.2, -0.5, 0.1), 0.0, MotorParams(), np.random.default_rng(1))
    still = hand.pose()
    hand.advance(0.0)
    assert hand.pose() is still  # nothing moved: the same pose
    hand.do(Move((0.2, -0.5, 0.1), math.pi / 2))  # a pure turn of the wrist
    for k in range(1, 241):
        hand.advance(k / 240.0)
        assert hand.pose() == Pose(hand.pos, yaw_quat_rad(hand.yaw_rad))
    assert hand.pose().orientation == yaw_quat_rad(math.pi / 2)


def test_the_scripted_participant_samples_what_its_hands_and_head_say() -> None:
    world = make_world("thesis")
    p = world.participant
    for _ in range(2400):  # 10 s: reaches, grips, turns and head motion
        s = world.step()
        for name in ("left", "right"):
            hand = p.hands[name]
            assert s.hand(name) == Pose(hand.pos, yaw_quat_rad(hand.yaw_rad))
        assert s.head.orientation == p.head_q
