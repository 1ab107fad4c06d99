"""Contact classification: hand-robot, robot-robot near collision, envelope, continue button."""

from __future__ import annotations

import pybullet as p
import pytest

from hrc.wire import pb

from hrc_physics.contacts import ContactKey, ContactTracker, Touch
from hrc_physics.world import World

HR, RR = pb.CONTACT_KIND_HAND_ROBOT, pb.CONTACT_KIND_ROBOT_ROBOT
ENV, BUTTON = pb.CONTACT_KIND_HAND_ENVELOPE, pb.CONTACT_KIND_HAND_BUTTON
AWAY = (0.0, -0.7, 0.3)  # in front of the participant's table: outside every box


def _events(world: World, helpers, left, right=AWAY, kinds=None) -> list[tuple]:
    world.set_human(helpers.human(left=left, right=right))
    world.step()
    return [
        (c.kind, c.begin, c.a, c.b, c.link)
        for c in world.contact_events()
        if kinds is None or c.kind in kinds
    ]


def test_hand_touching_a_robot_link_begins_and_ends_once(world: World, helpers) -> None:
    # r1 stands at (0.45, 0.55) pointing straight up (no state yet); its upper arm is a
    # 5 cm radius cylinder from z = 0.20 to 0.62. The hand (0.18 m long along y) comes along +y,
    # so its finger tips touch when its centre is at y = 0.55 - 0.05 - 0.09 = 0.41.
    assert _events(world, helpers, (0.45, 0.40, 0.40), kinds={HR}) == []
    assert _events(world, helpers, (0.45, 0.42, 0.40), kinds={HR}) == [
        (HR, True, "left", "r1", "link2_upper_arm")
    ]
    assert _events(world, helpers, (0.45, 0.45, 0.45), kinds={HR}) == []  # still touching
    assert _events(world, helpers, (0.45, 0.30, 0.45), kinds={HR}) == [
        (HR, False, "left", "r1", "link2_upper_arm")
    ]
    # The right hand on r2's forearm (z 0.62..1.02), from the side (-x).
    r2_x = -0.45
    assert _events(world, helpers, AWAY, (r2_x + 0.04 + 0.045 - 0.005, 0.55, 0.8), {HR}) == [
        (HR, True, "right", "r2", "link3_forearm")
    ]


def test_contact_follows_the_robot_pose(world: World, helpers) -> None:
    hand = (0.45, 0.42, 0.40)
    assert _events(world, helpers, hand, kinds={HR})[0][1] is True
    world.set_robot_state("r1", ["j1_base_yaw", "j2_shoulder"], [0.0, 1.2])  # leans away (-x)
    assert _events(world, helpers, hand, kinds={HR}) == [
        (HR, False, "left", "r1", "link2_upper_arm")
    ]


def test_envelope_enter_and_leave(world: World, helpers) -> None:
    assert _events(world, helpers, AWAY, kinds={ENV}) == []
    assert _events(world, helpers, (0.0, 0.0, 0.2), kinds={ENV}) == [(ENV, True, "left", "0", "")]
    assert _events(world, helpers, (0.0, -0.3, 0.2), kinds={ENV}) == [
        (ENV, False, "left", "0", ""),
        (ENV, True, "left", "1", ""),
    ]
    assert _events(world, helpers, AWAY, kinds={ENV}) == [(ENV, False, "left", "1", "")]


def test_hand_on_the_continue_button(world: World, helpers) -> None:
    # Button: 4 cm radius, 2 cm high, centred at (0.40, -0.30, 0.02): top at z = 0.03.
    assert _events(world, helpers, AWAY, (0.40, -0.30, 0.06), {BUTTON}) == []
    assert _events(world, helpers, AWAY, (0.40, -0.30, 0.04), {BUTTON}) == [
        (BUTTON, True, "right", "continue_button", "")
    ]
    assert _events(world, helpers, AWAY, (0.40, -0.30, 0.06), {BUTTON}) == [
        (BUTTON, False, "right", "continue_button", "")
    ]


def _link_distance(world: World) -> float:
    r1, r2 = world.robots["r1"].body, world.robots["r2"].body
    pts = p.getClosestPoints(r1, r2, 10.0, physicsClientId=world.c)
    return min(pt[8] for pt in pts)


def test_robots_leaning_together_near_collide_before_they_touch(world: World) -> None:
    """r1 (at x = +0.45, turned 180 degrees) leans towards -x with a positive shoulder angle,
    r2 towards +x with a negative one; the near collision begins as soon as the links are within
    the two margins (5 cm each) and well before they intersect."""
    margins = world.robots["r1"].near_margin + world.robots["r2"].near_margin
    assert margins == pytest.approx(0.10)
    began_at = touched_at = None
    for i in range(200):
        a = 0.01 * i
        world.set_robot_state("r1", ["j2_shoulder", "j3_elbow"], [a, 0.3])
        world.set_robot_state("r2", ["j2_shoulder", "j3_elbow"], [-a, -0.3])
        world.step()
        d = _link_distance(world)
        events = [c for c in world.contact_events() if c.kind == RR]
        if events:
            assert (
                began_at is None and events[0].begin and (events[0].a, events[0].b) == ("r1", "r2")
            )
            assert events[0].distance == pytest.approx(d, abs=1e-6)
            began_at = i
            assert d <= margins
        elif began_at is None:
            assert d > margins
        if d <= 0.0:
            touched_at = i
            break
    assert began_at is not None and touched_at is not None and began_at < touched_at
    # Back apart: the near collision ends.
    for r in ("r1", "r2"):
        world.set_robot_state(r, ["j2_shoulder", "j3_elbow"], [0.0, 0.0])
    world.step()
    ended = [c for c in world.contact_events() if c.kind == RR]
    assert len(ended) == 1 and not ended[0].begin


def test_tracker_reports_each_change_once() -> None:
    t = ContactTracker()
    key = ContactKey(HR, "left", "r1")
    assert [(e.begin, e.link) for e in t.update({key: Touch("link3_forearm")})] == [
        (True, "link3_forearm")
    ]
    assert t.update({key: Touch("link4_wrist")}) == []  # same contact, other link: no event
    env = ContactKey(ENV, "left", "0")
    assert [(e.kind, e.begin) for e in t.update({env: Touch()})] == [(HR, False), (ENV, True)]
    ended = t.update({})
    assert [(e.kind, e.begin, e.a, e.b) for e in ended] == [(ENV, False, "left", "0")]
    assert t.update({}) == []


def _fresh_aabb(robot) -> tuple:
    """The robot's AABB computed now, past its cache."""
    robot._aabb = None
    return robot.aabb()


def test_a_robot_aabb_is_reused_only_while_its_links_stay_put(world: World) -> None:
    robot = next(iter(world.robots.values()))
    before = robot.aabb()
    assert robot.aabb() is before  # asked again, nothing moved: the same box
    robot.set_state([], [0.4] * len(robot.movable))
    world.step()  # the arm moves in this step
    moved = robot.aabb()
    assert moved != before
    assert moved == _fresh_aabb(robot)
    for _ in range(3):  # a step alone may still nudge the links: the box is looked at anew
        world.step()
        assert robot.aabb() == _fresh_aabb(robot)
