"""Separations under safety_policy = "ssm": the closest hand or head to each robot's moving
links, capped at the sensing range, published only on change, and none under other policies."""

from __future__ import annotations

import pytest

from hrc import scenario as sc
from hrc.wire import pb

from hrc_physics.world import World

AWAY = (0.0, -0.7, 0.3)


@pytest.fixture
def ssm_world(minimal: sc.Scenario):
    scenario = minimal.model_copy(deep=True)
    scenario.conditions.safety_policy = sc.SafetyPolicy.SSM
    with World(scenario) as w:
        yield w


def _seps(world: World, helpers, left, right=AWAY) -> dict[str, pb.Separation] | None:
    world.set_human(helpers.human(left=left, right=right))
    world.step()
    seps = world.separations()
    return None if seps is None else {s.robot: s for s in seps}


def test_closest_hand_to_the_upper_arm(ssm_world: World, helpers) -> None:
    # r1 stands at (0.45, 0.55) pointing up; its upper arm is a 5 cm radius cylinder (z 0.20 to
    # 0.62). The left hand's finger tips (centre + 0.09 along y) at y = 0.30 + 0.09 = 0.39 are
    # 0.55 - 0.05 - 0.39 = 0.11 m from it.
    seps = _seps(ssm_world, helpers, (0.45, 0.30, 0.40))
    assert seps is not None
    r1 = seps["r1"]
    assert r1.body == "left" and r1.link == "link2_upper_arm"
    assert r1.distance_m == pytest.approx(0.11, abs=3e-3)  # pybullet margins: mm
    assert r1.robot_point.y == pytest.approx(0.50, abs=3e-3)
    # Closer: the distance follows; touching: 0.
    assert _seps(ssm_world, helpers, (0.45, 0.35, 0.40))["r1"].distance_m == pytest.approx(  # type: ignore[index]
        0.06, abs=3e-3
    )
    assert _seps(ssm_world, helpers, (0.45, 0.45, 0.40))["r1"].distance_m == 0.0  # type: ignore[index]


def test_nothing_new_when_nothing_moved(ssm_world: World, helpers) -> None:
    assert _seps(ssm_world, helpers, (0.45, 0.30, 0.40)) is not None
    ssm_world.step()  # the same HumanState object: nothing moved
    assert ssm_world.separations() is None


def test_far_is_the_sensing_range_and_the_base_does_not_count(ssm_world: World, helpers) -> None:
    rng = ssm_world.scenario.ssm_of("r1").sensing_range_m
    helpers_far = helpers.human(left=(5.0, -5.0, 0.3), right=(5.0, -5.0, 0.3))
    helpers_far.head.position.x = 5.0
    ssm_world.set_human(helpers_far)
    ssm_world.step()
    seps = {s.robot: s for s in ssm_world.separations() or []}
    assert seps["r1"].distance_m == rng and seps["r1"].body == ""
    # A hand right next to r1's base (z 0 to 0.2) but far from its moving links: the base is
    # ignored, so the distance is to the turret or upper arm above it, not 0.
    seps2 = _seps(ssm_world, helpers, (0.45, 0.38, 0.05))
    assert seps2 is not None and seps2["r1"].distance_m > 0.03
    assert seps2["r1"].link != "base_link"


def test_other_policies_compute_nothing(world: World, helpers) -> None:
    world.set_human(helpers.human(left=(0.45, 0.30, 0.40)))
    world.step()
    assert world.separation is None and world.separations() is None
