"""Closest-point queries at growing thresholds (hrc_physics.closest) give what one query at the
limit gives: the nearest pair, its distance and its points, or nothing when none is nearer."""

from __future__ import annotations

import random
from collections.abc import Iterator

import pybullet as p
import pytest

from hrc import scenario as sc

from .conftest import ROOT
from hrc_physics.closest import nearest, thresholds
from hrc_physics.world import World

UR5E = ROOT / "scenarios" / "thesis-ur5e.toml"  # two UR5e arms: mesh hulls, 8 links each


@pytest.fixture(scope="module")
def arms() -> Iterator[World]:
    with World(sc.load(UR5E)) as world:
        yield world


def _revolute(world: World, body: int) -> list[int]:
    n = p.getNumJoints(body, physicsClientId=world.c)
    return [
        j
        for j in range(n)
        if p.getJointInfo(body, j, physicsClientId=world.c)[2] == p.JOINT_REVOLUTE
    ]


def test_thresholds_grow_to_the_limit_and_end_with_it() -> None:
    assert list(thresholds(0.1, 2.0)) == pytest.approx([0.1, 0.4, 1.6, 2.0])
    assert list(thresholds(0.5, 0.5)) == [0.5]
    assert list(thresholds(1.0, 0.3)) == [0.3]  # a start beyond the limit: the limit alone
    assert list(thresholds(0.0, 0.3)) == [0.3]  # (0 would never grow)


def test_the_nearest_pair_is_the_one_query_at_the_limit_gives(arms: World) -> None:
    """Two UR5e arms in 150 random poses, limits from 2 cm to 3.5 m: the same nearest distance
    and point as one query at the limit, and nothing exactly where that query finds nothing.
    Both cases occur, and the nearest pair is found at every stage (first and last)."""
    c = arms.c
    a, b = (r.body for r in arms.robots.values())
    joints = {body: _revolute(arms, body) for body in (a, b)}
    rng = random.Random(7)
    found = empty = 0
    stages: set[int] = set()
    for _ in range(150):
        for body, js in joints.items():
            for j in js:
                p.resetJointState(body, j, rng.uniform(-2.5, 2.5), physicsClientId=c)
        for limit in (0.02, 0.3, 1.0, 3.5):
            start = 0.01
            whole = p.getClosestPoints(a, b, limit, physicsClientId=c)
            staged = nearest(c, a, b, limit, start)
            if not whole:
                assert staged == []
                empty += 1
                continue
            found += 1
            best = min(whole, key=lambda pt: pt[8])
            assert min(pt[8] for pt in staged) == best[8]
            assert min(staged, key=lambda pt: pt[8])[5:7] == best[5:7]
            stages.add(next(i for i, t in enumerate(thresholds(start, limit)) if best[8] < t))
    assert found > 100 and empty > 20, (found, empty)
    assert {0, 3} <= stages, stages  # near pairs at the first threshold, far ones at the last
