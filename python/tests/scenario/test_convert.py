"""Scenario <-> pb.Scenario."""

from __future__ import annotations

from pathlib import Path

import pytest

from hrc.scenario import ScenarioError, from_proto, load, to_proto
from hrc.wire import pb

SCENARIOS = Path(__file__).resolve().parents[3] / "scenarios"


@pytest.fixture
def thesis(arm_root: Path):
    return load(SCENARIOS / "thesis.toml", project_root=arm_root, motion_check=False)


def test_every_field_is_filled(thesis, arm_root: Path) -> None:
    msg = to_proto(thesis)
    assert msg.info.name == "thesis-board" and msg.info.tick_hz == 240 and msg.info.seed == 1
    assert msg.participant.name == "P01" and msg.participant.input == pb.INPUT_SOURCE_SCRIPTED
    assert msg.participant.scripted.caution == 0.5
    # every parameter is set, defaults applied (an unset collision reaction: half the reaction)
    assert {f.name for f, _ in msg.participant.scripted.ListFields()} == set(
        pb.ScriptedParams.DESCRIPTOR.fields_by_name
    ) - {"collision_reaction_s"}
    assert msg.conditions.anticipation
    assert msg.conditions.safety_policy == pb.SAFETY_POLICY_RETREAT
    assert [r.id for r in msg.robots] == ["r1", "r2"]
    r1, r2 = msg.robots
    for r in (r1, r2):
        assert Path(r.urdf_path).is_absolute() and Path(r.urdf_path).is_file()
        assert r.near_margin == pytest.approx(0.05)  # default
    assert r1.role == pb.ROBOT_ROLE_TRANSPORT and r1.color == "yellow"
    assert not r1.HasField("feeder")
    assert r2.role == pb.ROBOT_ROLE_SCREWING and r2.HasField("feeder") and r2.screw_time_s == 1.0
    assert r1.base.yaw_deg == 180 and r1.base.xyz.x == pytest.approx(0.45)
    assert len(msg.parts) == 18
    s1 = next(p for p in msg.parts if p.id == "S1")
    assert not s1.start_given and list(s1.after) == ["H1"]
    h1 = next(p for p in msg.parts if p.id == "H1")
    assert h1.start_given and h1.size.x == pytest.approx(0.10)
    assert {s.agent: list(s.parts) for s in msg.sequences}["r2"][0] == "S1"
    assert len(msg.workspace.envelope) == 2 and msg.workspace.HasField("continue_button")
    assert msg.place_tolerance_m == pytest.approx(0.02)
    assert msg.place_tolerance_deg == pytest.approx(20)
    assert msg.source_path == str((SCENARIOS / "thesis.toml").resolve())
    assert msg.source_toml == (SCENARIOS / "thesis.toml").read_text(encoding="utf-8")


def test_defaults_reach_the_wire(minimal_raw, write_scenario, arm_root) -> None:
    del minimal_raw["robots"]["r1"]["color"]
    del minimal_raw["robots"]["r2"]["screw_time_s"]
    del minimal_raw["conditions"]
    msg = to_proto(load(write_scenario(minimal_raw), project_root=arm_root, motion_check=False))
    assert msg.robots[0].color == "yellow" and msg.robots[1].screw_time_s == 1.0
    assert msg.conditions.anticipation
    assert msg.conditions.safety_policy == pb.SAFETY_POLICY_RETREAT
    assert msg.place_tolerance_m == pytest.approx(0.02)
    assert msg.participant.provoke_probability == 0.0 and not msg.participant.provoke_times_s


def test_round_trip(thesis) -> None:
    msg = to_proto(thesis)
    wire = pb.Scenario.FromString(msg.SerializeToString())
    back = from_proto(wire)
    assert to_proto(back) == msg
    # the model itself comes back equal, URDF paths now absolute
    expected = thesis.model_copy(deep=True)
    for rid, robot in expected.robots.items():
        robot.urdf = str(thesis.urdf_path(rid))
    assert back.model_dump() == expected.model_dump()
    assert back.source_text == thesis.source_text
    assert back.sequence_of("r1") == thesis.sequence_of("r1")
    assert back.robot("r2").id == "r2"


def test_round_trip_keeps_provoke_times_and_absent_button(
    minimal_raw, write_scenario, arm_root
) -> None:
    minimal_raw["participant"]["provoke_collisions"] = [4.0, 1.5]
    del minimal_raw["workspace"]["continue_button"]
    scenario = load(write_scenario(minimal_raw), project_root=arm_root, motion_check=False)
    back = from_proto(to_proto(scenario))
    assert back.participant.provoke_collisions == [1.5, 4.0]
    assert back.workspace.continue_button is None


def test_from_proto_rejects_out_of_range_fields(thesis) -> None:
    msg = to_proto(thesis)
    msg.robots[0].max_tcp_speed = 9.0
    with pytest.raises(ScenarioError) as info:
        from_proto(msg)
    assert "max_tcp_speed" in str(info.value)


def test_from_proto_names_the_key_of_an_unset_enum_or_parameter(thesis) -> None:
    msg = to_proto(thesis)
    msg.robots[1].role = pb.ROBOT_ROLE_UNSPECIFIED
    with pytest.raises(ScenarioError) as info:
        from_proto(msg)
    assert [p.key for p in info.value.problems] == ["robots.r2.role"]
    msg = to_proto(thesis)
    msg.participant.scripted.fitts_b_s = -1.0
    with pytest.raises(ScenarioError) as info:
        from_proto(msg)
    assert [p.key for p in info.value.problems] == ["participant.fitts_b_s"]
