"""The scenarios shipped in scenarios/: they load clean, every robot move passes the motion check,
and the thesis task has the shape docs/scenario.md describes."""

from __future__ import annotations

from pathlib import Path

import pytest

from hrc.scenario import HUMAN, Scenario, load, validate

REPO = Path(__file__).resolve().parents[3]
SHIPPED = ["thesis", "minimal", "empty"]
REAL_ARM = REPO / "robots" / "arm5.urdf"


@pytest.mark.parametrize("name", SHIPPED)
def test_loads_clean_with_the_stand_in_arm(name: str, arm_root: Path) -> None:
    # project_root = a folder whose robots/arm5.urdf is the test arm (the scenarios name
    # robots/arm5.urdf relative to the project root)
    scenario = load(REPO / "scenarios" / f"{name}.toml", project_root=arm_root)
    assert validate(scenario, motion_check=True) == []


@pytest.mark.skipif(not REAL_ARM.is_file(), reason="robots/arm5.urdf does not exist yet")
@pytest.mark.parametrize("name", SHIPPED)
def test_loads_clean_with_the_real_arm(name: str) -> None:
    scenario = load(REPO / "scenarios" / f"{name}.toml")
    assert scenario.urdf_path("r1") == REAL_ARM.resolve()


@pytest.fixture(scope="module")
def thesis(arm_root: Path) -> Scenario:
    return load(REPO / "scenarios" / "thesis.toml", project_root=arm_root, motion_check=False)


def test_thesis_has_enough_parts_of_each_agent(thesis: Scenario) -> None:
    assert len(thesis.sequence_of(HUMAN)) >= 6
    transport = next(iter(thesis.robots_by_role("transport")))
    screwing = next(iter(thesis.robots_by_role("screwing")))
    assert (transport, screwing) == ("r1", "r2")
    assert len(thesis.sequence_of("r1")) >= 6
    assert len(thesis.sequence_of("r2")) >= 6
    assert thesis.robot("r1").color == "yellow" and thesis.robot("r2").color == "green"


def _footprint_contains(host, x: float, y: float) -> bool:
    # screws are placed on unrotated (yaw 0 or 180) hosts in the thesis board
    hx, hy, _ = host.target.xyz
    sx, sy, _ = host.size
    return abs(x - hx) <= sx / 2 and abs(y - hy) <= sy / 2


def test_thesis_screws_go_into_holes_on_top_of_human_and_r1_parts(thesis: Scenario) -> None:
    host_owners = set()
    for screw in thesis.parts_in_sequence("r2"):
        assert screw.start is None
        (host_id,) = screw.after
        host = thesis.part(host_id)
        host_owners.add(host.owner)
        assert host.target.yaw % 180 == 0
        x, y, z = screw.target.xyz
        top = host.target.xyz[2] + host.size[2] / 2
        assert z == pytest.approx(top), f"{screw.id} is not on the top face of {host_id}"
        assert _footprint_contains(host, x, y), f"{screw.id} is not over {host_id}"
    assert host_owners == {HUMAN, "r1"}


def test_thesis_has_waits_both_ways(thesis: Scenario) -> None:
    human_waits_for_r1 = [
        p.id for p in thesis.parts_of(HUMAN) if any(thesis.part(d).owner == "r1" for d in p.after)
    ]
    r1_waits_for_human = [
        p.id for p in thesis.parts_of("r1") if any(thesis.part(d).owner == HUMAN for d in p.after)
    ]
    assert human_waits_for_r1 and r1_waits_for_human


def test_thesis_layout_follows_the_world_frame(thesis: Scenario) -> None:
    for p in thesis.parts:
        x, y, z = p.target.xyz
        assert abs(x) <= 0.3 and abs(y) <= 0.2, f"{p.id} target is off the board"
        assert z > 0
    for p in thesis.parts_of(HUMAN):
        assert p.start is not None and p.start.xyz[1] < -0.2  # in front of the participant
    for p in thesis.parts_of("r1"):
        assert p.start is not None and p.start.xyz[0] > 0.3  # r1's picking table, on its side
    for rid, robot in thesis.robots.items():
        assert robot.base.xyz[1] > 0.2, f"{rid} must stand on the far side"


def test_minimal_and_empty(arm_root: Path) -> None:
    minimal = load(REPO / "scenarios" / "minimal.toml", project_root=arm_root, motion_check=False)
    assert [len(minimal.sequence_of(a)) for a in minimal.agents] == [1, 1, 1]
    empty = load(REPO / "scenarios" / "empty.toml", project_root=arm_root, motion_check=False)
    assert empty.parts == [] and all(empty.sequence_of(a) == [] for a in empty.agents)
    assert set(empty.robots) == {"r1", "r2"} and empty.workspace.envelope
