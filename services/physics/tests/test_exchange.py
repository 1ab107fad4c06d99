"""The exchange step's arm speed bounds: the URDF's per joint, scaled by what the arm's motion
source declares for the coming ticks."""

from __future__ import annotations

import math

import numpy as np
import pybullet as p
import pytest

from hrc import scenario as sc

from .conftest import ROOT, human
from hrc_physics.exchange import Lever, SpanPlanner, arm_levers, arm_speed_terms, link_speed_bound
from hrc_physics.robots import KinematicRobot
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


def _frame(robot: KinematicRobot, link: int) -> tuple[np.ndarray, np.ndarray]:
    s = p.getLinkState(robot.body, link, physicsClientId=robot._c)
    return np.array(s[4]), np.array(p.getMatrixFromQuaternion(s[5])).reshape(3, 3)


@pytest.mark.parametrize("scenario", ["thesis.toml", "thesis-panda.toml"])
def test_declared_link_speeds_bound_every_collider_of_the_arm(scenario: str) -> None:
    """From the arm's pose at start, random joint steps (the fingers too): the corners of each
    collider's box, carried with their link, move no farther than the bound computed from how
    far the links' frames moved and turned (what ik_cpp declares) and the fingers' fractions;
    and that bound is below the sum of the joints' terms."""
    rng = np.random.default_rng(7)
    with World(sc.load(ROOT / "scenarios" / scenario)) as world:
        robot = next(iter(world.robots.values()))
        c, body = world.c, robot.body
        n = p.getNumJoints(body, physicsClientId=c)
        info = [p.getJointInfo(body, j, physicsClientId=c) for j in range(n)]
        movable = [j for j in range(n) if info[j][2] != p.JOINT_FIXED]
        names = {j: info[j][1].decode() for j in movable}
        fingers = {j for j in movable if info[j][2] == p.JOINT_PRISMATIC}
        chain = [j for j in movable if j not in fingers]
        levers = arm_levers(robot)
        terms = arm_speed_terms(robot)
        q0 = [p.getJointState(body, j, physicsClientId=c)[0] for j in movable]
        colliders = [j for j in range(n) if p.getCollisionShapeData(body, j, physicsClientId=c)]
        corners = {}
        for link in colliders:
            lo, hi = p.getAABB(body, link, physicsClientId=c)
            o, r = _frame(robot, link)
            corners[link] = [
                r.T @ (np.array([x, y, z]) - o) for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                for z in (lo[2], hi[2])
            ]  # fmt: skip
        start = {link: _frame(robot, link) for link in range(n)}
        for _ in range(20):
            dq = rng.uniform(-0.05, 0.05, len(movable))
            for j, q, d in zip(movable, q0, dq, strict=True):
                p.resetJointState(body, j, q + (d * 0.2 if j in fingers else d), physicsClientId=c)
            moved = {link: _frame(robot, link) for link in range(n)}
            links = {}
            for j in chain:  # what the motion source declares: how far each child frame went
                (o0, r0), (o1, r1) = start[j], moved[j]
                angle = math.acos(min(1.0, max(-1.0, (np.trace(r0.T @ r1) - 1) / 2)))
                links[names[j]] = (float(np.linalg.norm(o1 - o0)), angle)
            # each joint's step as a fraction of its limit (a "tick" of 1 s: speeds are steps)
            fractions = {
                names[j]: abs(d * 0.2 if j in fingers else d) / (info[j][11] or 2 * math.pi)
                for j, d in zip(movable, dq, strict=True)
            }
            bound = link_speed_bound(levers, links, fractions)
            worst = 0.0
            for link in colliders:
                (o0, r0), (o1, r1) = start[link], moved[link]
                for x in corners[link]:
                    worst = max(worst, float(np.linalg.norm((o1 + r1 @ x) - (o0 + r0 @ x))))
            assert worst <= bound + 1e-9, (scenario, worst, bound)
            assert bound < sum(terms[name] * f for name, f in fractions.items()), scenario
        for j, q in zip(movable, q0, strict=True):
            p.resetJointState(body, j, q, physicsClientId=c)


def test_declared_link_speeds_lower_the_bound_only_where_they_are_lower() -> None:
    levers = {"r1": [(Lever("a", 2.0, False, 0.5), Lever("base", 1.0, False, 1.0))]}
    planner = SpanPlanner(
        dt=1 / 240, arm_terms={"r1": {"a": 1.0, "base": 1.0}}, max_span=16, arm_levers=levers
    )
    planner.declare("r1", ["a", "base"], [1.0, 1.0], 32, [0.2, 0.0], [0.4, 0.1])
    assert math.isclose(planner.bound("r1")[0], 0.2 + 0.4 * 0.5)  # a's link: v + w r
    planner.declare("r1", ["a", "base"], [0.1, 0.1], 32, [0.2, 0.0], [0.4, 0.1])
    assert math.isclose(planner.bound("r1")[0], 0.2)  # the fractions' sum is lower here
    # only the base's link declared: joint a (not declared) adds its term at its fraction
    planner.declare("r1", ["base", "a"], [1.0, 0.5], 32, [0.0], [0.1])
    assert math.isclose(planner.bound("r1")[0], 0.5 * 2.0 * 0.5 + 0.1 * 1.0)
    # without levers (another arm model), the fractions alone
    planner.arm_levers = {}
    assert math.isclose(planner.bound("r1")[0], 1.5)


def test_a_hand_may_press_the_button_only_where_an_exchange_ends(world: World) -> None:
    """Under retreat_button a press after a collision is acted on (the robots go on): from a
    hand-arm contact to the next press (``button_armed``), a hand may reach the button only at
    an exchange's last tick, as it may reach an arm; a hand already on it sets no bound (its
    press has begun)."""
    button = world.button_bounds()
    assert button is not None
    hand_speed = 1.0  # m/s
    planner = SpanPlanner(
        dt=1 / 240, arm_terms={}, max_span=32, hand_bound=hand_speed, button=button
    )
    bx, by, bz = world.scenario.workspace.continue_button
    world.set_human(human(left=(-0.3, -0.6, 0.3), right=(bx, by, bz + 0.07)))
    world.step()
    assert planner.span(world.c, list(world.hands.values()), {}) == 32  # no collision yet
    planner.button_armed = True
    right = world.hands["right"]
    left_far = (-0.3, -0.6, 0.3)
    for gap_m in (0.30, 0.05, 0.02, 0.001):
        # the hand (a box) straight above the button's top face, its lowest point gap_m above
        world.set_human(human(left=left_far, right=(bx, by, bz + 0.01 + gap_m + 0.05)))
        world.step()
        low = p.getAABB(right.body, -1, physicsClientId=world.c)[0][2]
        gap = low - (bz + 0.01)
        n = planner.span(world.c, list(world.hands.values()), {})
        assert n == 32 or n * hand_speed / 240 < gap, (gap_m, gap, n)  # never reaches it
        if gap < 32 * hand_speed / 240:
            assert n < 32, (gap_m, gap, n)  # and is bound where it could
    world.set_human(human(left=left_far, right=(bx, by, bz)))  # pressing
    world.step()
    assert planner.span(world.c, list(world.hands.values()), {}) == 32
    without = SpanPlanner(dt=1 / 240, arm_terms={}, max_span=32, hand_bound=hand_speed)
    without.button_armed = True
    world.set_human(human(left=left_far, right=(bx, by, bz + 0.06)))
    world.step()
    assert planner.span(world.c, list(world.hands.values()), {}) < 32
    assert without.span(world.c, list(world.hands.values()), {}) == 32  # (no rule without it)
