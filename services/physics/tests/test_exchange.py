"""The exchange step's arm speed bounds: the URDF's per joint, scaled by what the arm's motion
source declares for the coming ticks."""

from __future__ import annotations

import math

import pybullet as p

from hrc_physics.exchange import SpanPlanner, arm_speed_terms
from hrc_physics.world import World


def test_each_joint_term_bounds_the_speed_it_gives_the_arm(world: World) -> None:
    robot = next(iter(world.robots.values()))
    terms = arm_speed_terms(robot)
    movable = [
        p.getJointInfo(robot.body, j, physicsClientId=world.c)
        for j in range(p.getNumJoints(robot.body, physicsClientId=world.c))
    ]
    names = {i[1].decode() for i in movable if i[2] != p.JOINT_FIXED}
    assert set(terms) == names
    assert all(t > 0 for t in terms.values())
    # the base joint swings the whole arm, the last joint only what is beyond it
    values = list(terms.values())
    first, last = values[0], values[-1]
    assert first > last


def _planner() -> SpanPlanner:
    terms = {"r1": {"a": 2.0, "b": 1.0}, "r2": {"a": 3.0}}
    return SpanPlanner(dt=1 / 240, arm_terms=terms, max_span=16)


def test_an_arm_counts_what_its_source_declares_else_its_full_bound() -> None:
    planner = _planner()
    assert planner.bound("r1") == (3.0, 0)  # nothing declared yet
    planner.declare("r1", ["a", "b"], [0.5, 0.25], 32)
    bound, window = planner.bound("r1")
    assert math.isclose(bound, 0.5 * 2.0 + 0.25 * 1.0) and window == 32
    planner.declare("r1", ["a", "b"], [0.0, 0.0])
    assert planner.bound("r1") == (0.0, 0)  # at rest
    planner.declare("r1", ["a"], [0.0])
    assert planner.bound("r1") == (1.0, 0)  # a joint it does not name counts in full
    planner.declare("r1", ["a", "b"], [])
    assert planner.bound("r1") == (3.0, 0)  # no longer declared (e.g. under a speed scale)
    planner.declare("r9", ["a"], [0.0])  # an unknown robot changes nothing
    assert planner.bound("r2") == (3.0, 0)


def test_a_commanded_arm_counts_in_full_for_one_exchange(world: World) -> None:
    planner = _planner()
    planner.arm_terms = {rid: {"x": 1.0} for rid in world.robots}
    planner.arm_bounds = {rid: 1.0 for rid in world.robots}
    rid = next(iter(world.robots))
    planner.declare(rid, ["x"], [0.0], 8)
    planner.commanded(rid)
    assert planner.bound(rid) == (1.0, 0)  # its new motion starts at the next exchange's first tick
    assert planner.span(world.c, [], world.robots) == 16  # the full bound, far from everything
    assert planner.bound(rid) == (0.0, 8)  # then its declaration holds again (one exchange only)
    assert planner.span(world.c, [], world.robots) == 8  # and only for the ticks it covers
