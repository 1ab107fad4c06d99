"""The nearest pair of colliders asked pair by pair (hrc_physics.closest) is what one query of the
two whole bodies gives: the same distance and points, or nothing when no pair is nearer than the
limit; interpenetrating arms included."""

from __future__ import annotations

import random
from collections.abc import Iterator

import pybullet as p
import pytest

from hrc import scenario as sc

from .conftest import ROOT
from hrc_physics.closest import box_gap, nearest
from hrc_physics.robots import BASE, KinematicRobot
from hrc_physics.world import World

UR5E = ROOT / "scenarios" / "thesis-ur5e.toml"  # two UR5e arms: mesh hulls, 8 colliders each
POSES = 150


@pytest.fixture(scope="module")
def arms() -> Iterator[World]:
    with World(sc.load(UR5E)) as world:
        yield world


def _random_pose(world: World, robot: KinematicRobot, rng: random.Random) -> None:
    for j in range(p.getNumJoints(robot.body, physicsClientId=world.c)):
        if p.getJointInfo(robot.body, j, physicsClientId=world.c)[2] == p.JOINT_REVOLUTE:
            p.resetJointState(robot.body, j, rng.uniform(-2.5, 2.5), physicsClientId=world.c)
    robot.stepped()  # its link boxes are those of the new pose


def _whole(world: World, a: int, b: int, limit: float, skip_base: bool = False) -> list:
    pts = p.getClosestPoints(a, b, limit, physicsClientId=world.c)
    return [pt for pt in pts if not (skip_base and pt[4] == BASE)]


def test_box_gap_is_the_distance_between_boxes() -> None:
    a = ((0.0, 0.0, 0.0), (1.0, 1.0, 1.0))
    assert box_gap(a, ((2.0, 0.5, 0.5), (3.0, 1.0, 1.0))) == 1.0
    assert box_gap(a, ((4.0, 5.0, 0.0), (5.0, 6.0, 1.0))) == 5.0  # 3, 4: the diagonal
    assert box_gap(a, ((0.5, 0.5, 0.5), (2.0, 2.0, 2.0))) == 0.0


def test_two_arms_nearest_pair_is_the_one_query_of_both_arms(arms: World) -> None:
    """Two UR5e arms in random poses, limits from 2 cm to 3.5 m: the same nearest distance and
    points as one query of both bodies, nothing exactly where it finds nothing. Poses where the
    arms interpenetrate, where they are apart and within the limit, and beyond it all occur."""
    r1, r2 = arms.robots.values()
    rng = random.Random(7)
    inside = apart = beyond = 0
    for _ in range(POSES):
        _random_pose(arms, r1, rng)
        _random_pose(arms, r2, rng)
        for limit in (0.02, 0.3, 1.0, 3.5):
            whole = _whole(arms, r1.body, r2.body, limit)
            got = nearest(arms.c, r1.body, r1.link_boxes(), r2.body, r2.link_boxes(), limit)
            if not whole:
                assert got is None
                beyond += 1
                continue
            best = min(whole, key=lambda pt: pt[8])
            assert got is not None and got[8] == best[8], (got, best)
            assert got[3:7] == best[3:7]  # the same links, the same points
            inside += best[8] < 0
            apart += best[8] >= 0
    assert inside > 10 and apart > 100 and beyond > 20, (inside, apart, beyond)


def test_a_hand_and_an_arm_without_its_base(arms: World) -> None:
    """A hand box anywhere around an arm: its nearest moving link (the base left out, as the
    separation does), as one query of both bodies would give."""
    robot = next(iter(arms.robots.values()))
    hand = arms.hands["right"]
    rng = random.Random(3)
    found = 0
    for _ in range(POSES):
        _random_pose(arms, robot, rng)
        xyz = [rng.uniform(-1.0, 1.0), rng.uniform(-0.5, 1.2), rng.uniform(0.0, 1.2)]
        p.resetBasePositionAndOrientation(hand.body, xyz, [0, 0, 0, 1], physicsClientId=arms.c)
        box = p.getAABB(hand.body, -1, physicsClientId=arms.c)
        moving = [(link, b) for link, b in robot.link_boxes() if link != BASE]
        whole = _whole(arms, hand.body, robot.body, 2.0, skip_base=True)
        got = nearest(arms.c, hand.body, [(-1, box)], robot.body, moving, 2.0)
        if not whole:
            assert got is None
            continue
        found += 1
        best = min(whole, key=lambda pt: pt[8])
        assert got is not None and got[8] == best[8] and got[4:7] == best[4:7], (got, best)
    assert found > 100, found
