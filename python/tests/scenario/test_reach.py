"""The pybullet reach checker, on the stand-in arm (robots/arm5.urdf when it exists, see
test_shipped.py)."""

from __future__ import annotations

from pathlib import Path

import pytest

from hrc.scenario import (
    APPROACH_HEIGHT_M,
    DEFAULT_REACH,
    PybulletReachChecker,
    ReachItem,
    Robot,
    load,
    reach_items,
    validate,
)


def robot(urdf: Path, base=(0.0, 0.0, 0.0), yaw: float = 0.0) -> Robot:
    r = Robot(role="transport", urdf=str(urdf), base={"xyz": list(base), "yaw": yaw},
              max_tcp_speed=0.5, home=[0.3, 0.0, 0.3], intermediate=[0.3, 0.0, 0.3],
              retreat=[0.3, 0.0, 0.3])
    r._id = "r"
    return r


@pytest.fixture(scope="module")
def checker():
    with PybulletReachChecker() as c:
        yield c


def test_near_points_are_reachable_and_far_ones_are_not(arm_root: Path, checker) -> None:
    urdf = arm_root / "robots" / "arm5.urdf"
    near = [(0.5, 0.0, 0.03), (0.0, -0.4, 0.08), (-0.3, 0.3, 0.2)]
    far = [(1.2, 0.0, 0.03), (0.0, 0.0, 1.5), (0.05, 0.0, 0.0)]  # too far, too high, inside base
    results = checker.check(robot(urdf), urdf, [ReachItem(str(p), "r", p, None) for p in near + far])
    assert [r.reachable for r in results] == [True] * 3 + [False] * 3
    assert all(r.position_error_m <= 0.005 for r in results[:3])
    assert all("mm away" in r.detail for r in results[3:])


def test_the_base_pose_is_used(arm_root: Path, checker) -> None:
    urdf = arm_root / "robots" / "arm5.urdf"
    point = (1.0, 0.0, 0.03)  # 1 m from the origin: out of reach, but 0.5 m from a base at x=0.5
    item = [ReachItem("p", "r", point, None)]
    assert not checker.check(robot(urdf), urdf, item)[0].reachable
    assert checker.check(robot(urdf, base=(0.5, 0.0, 0.0), yaw=180), urdf, item)[0].reachable


def test_an_arm_without_a_tool_link_is_reported(tmp_path: Path, arm_root: Path, checker) -> None:
    urdf = tmp_path / "notool.urdf"
    urdf.write_text((arm_root / "robots" / "arm5.urdf").read_text().replace('"tool"', '"flange"'))
    (result,) = checker.check(robot(urdf), urdf, [ReachItem("p", "r", (0.5, 0, 0.1), None)])
    assert not result.reachable and "no link named 'tool'" in result.detail


def test_reach_items_cover_poses_picks_places_and_approaches(minimal_raw, write_scenario,
                                                              arm_root) -> None:
    scenario = load(write_scenario(minimal_raw), project_root=arm_root, reach_checker=None)
    r1 = reach_items(scenario.robot("r1"), scenario.parts)
    keys = [i.key for i in r1]
    assert keys == ["robots.r1.home", "robots.r1.intermediate", "robots.r1.retreat",
                    "parts.RA1.start", "parts.RA1.start", "parts.RA1.target", "parts.RA1.target"]
    start, above = r1[3], r1[4]
    assert above.position[2] == pytest.approx(start.position[2] + APPROACH_HEIGHT_M)
    r2 = [i.key for i in reach_items(scenario.robot("r2"), scenario.parts)]
    assert r2.count("robots.r2.feeder") == 2 and r2.count("parts.S1.target") == 2
    assert "parts.H1.target" not in keys + r2  # the human's parts are not the robots' business


def test_validate_runs_the_reach_check_only_when_asked(minimal_raw, write_scenario,
                                                       arm_root) -> None:
    minimal_raw["robots"]["r1"]["retreat"] = [0.45, 0.55, 1.6]  # straight above, out of reach
    scenario = load(write_scenario(minimal_raw), project_root=arm_root, reach_checker=None)
    assert validate(scenario) == []
    problems = validate(scenario, reach_checker=DEFAULT_REACH)
    assert [p.key for p in problems] == ["robots.r1.retreat"]
    assert "robot r1 cannot reach [0.450, 0.550, 1.600]" in problems[0].message


def test_load_checks_reach_by_default(minimal_raw, write_scenario, arm_root) -> None:
    for p in minimal_raw["parts"]:
        if p["id"] == "S1":
            p["target"]["xyz"] = [0.30, -0.20, 0.04]  # 0.95 m from r2's base
    from hrc.scenario import ScenarioError

    with pytest.raises(ScenarioError) as info:
        load(write_scenario(minimal_raw), project_root=arm_root)
    assert {p.key for p in info.value.problems} == {"parts.S1.target"}
