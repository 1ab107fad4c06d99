"""The one mapping between the scenario file's strings and the wire enums."""

from __future__ import annotations

from typing import Any

import pytest

from hrc.paths import project_root
from hrc.scenario import InputSource, RobotRole, SafetyPolicy, ScenarioError, loads
from hrc.scenario.enums import WireEnum
from hrc.wire import pb
from hrc.wire.jsonmap import enum_number, enum_text

# Every string a scenario file may write, and the wire value it stands for.
TABLE: list[tuple[type[WireEnum], str, int]] = [
    (SafetyPolicy, "retreat", pb.SAFETY_POLICY_RETREAT),
    (SafetyPolicy, "retreat_button", pb.SAFETY_POLICY_RETREAT_BUTTON),
    (SafetyPolicy, "stop_colliding", pb.SAFETY_POLICY_STOP_COLLIDING),
    (SafetyPolicy, "ssm", pb.SAFETY_POLICY_SSM),
    (RobotRole, "transport", pb.ROBOT_ROLE_TRANSPORT),
    (RobotRole, "screwing", pb.ROBOT_ROLE_SCREWING),
    (InputSource, "scripted", pb.INPUT_SOURCE_SCRIPTED),
    (InputSource, "replay", pb.INPUT_SOURCE_REPLAY),
    (InputSource, "vr", pb.INPUT_SOURCE_VR),
]
WIRE = {SafetyPolicy: pb.SafetyPolicy, RobotRole: pb.RobotRole, InputSource: pb.InputSource}


@pytest.mark.parametrize(("enum", "text", "number"), TABLE)
def test_every_string_maps_to_its_wire_value_and_back(
    enum: type[WireEnum], text: str, number: int
) -> None:
    member = enum(text)
    assert member.to_proto() == number
    assert enum.from_proto(number) is member
    assert enum.parse(text) is member and member == text
    assert enum_text(WIRE[enum].DESCRIPTOR, number) == text  # the JSON form agrees
    assert enum_number(WIRE[enum].DESCRIPTOR, text) == number


def test_the_table_covers_every_member_and_every_wire_value() -> None:
    for enum, wire in WIRE.items():
        assert {m.value for m in enum} == {t for e, t, _ in TABLE if e is enum}
        assert set(wire.values()) - {0} == {n for e, _, n in TABLE if e is enum}


def test_unset_and_unknown_wire_values() -> None:
    with pytest.raises(ValueError, match="not set"):
        SafetyPolicy.from_proto(pb.SAFETY_POLICY_UNSPECIFIED)
    assert RobotRole.from_proto(0, RobotRole.TRANSPORT) is RobotRole.TRANSPORT
    with pytest.raises(ValueError, match="no value 99"):
        InputSource.from_proto(99)
    assert SafetyPolicy.parse("pray") is None and SafetyPolicy.parse(None) is None
    with pytest.raises(ValueError, match="use one of retreat, retreat_button, stop_colliding, ssm"):
        enum_number(pb.SafetyPolicy.DESCRIPTOR, "pray")
    with pytest.raises(ValueError):
        enum_number(pb.SafetyPolicy.DESCRIPTOR, "RETREAT")  # the text is lower case


MINIMAL = """
[scenario]
name = "enums"
[participant]
name = "P"
input = "{input}"
[conditions]
safety_policy = "{policy}"
[robots.r1]
role = "{role}"
urdf = "robots/arm5.urdf"
base = {{ xyz = [0.4, 0.5, 0.0] }}
max_tcp_speed = 0.5
home = [0.3, 0.3, 0.3]
intermediate = [0.3, 0.3, 0.3]
retreat = [0.3, 0.3, 0.3]
[workspace]
envelope = [{{ min = [-1, -1, -1], max = [1, 1, 1] }}]
continue_button = [0.0, 0.0, 0.0]
"""


def _load(**values: Any):
    text = MINIMAL.format(
        **{"input": "scripted", "policy": "retreat", "role": "transport", **values}
    )
    return loads(text, project_root=project_root())


def test_the_scenario_file_gives_members() -> None:
    s = _load(input="vr", policy="stop_colliding", role="transport")
    assert s.participant.input is InputSource.VR
    assert s.conditions.safety_policy is SafetyPolicy.STOP_COLLIDING
    assert s.robots["r1"].role is RobotRole.TRANSPORT


@pytest.mark.parametrize(
    ("key", "value", "name"),
    [
        ("input", "keyboard", "participant.input"),
        ("policy", "pray", "conditions.safety_policy"),
        ("policy", "RETREAT", "conditions.safety_policy"),
        ("role", "welding", "robots.r1.role"),
    ],
)
def test_an_unknown_string_is_rejected_naming_the_key(key: str, value: str, name: str) -> None:
    with pytest.raises(ScenarioError) as err:
        _load(**{key: value})
    problems = [p for p in err.value.problems if p.key == name]
    assert len(problems) == 1, err.value
    assert repr(value) in problems[0].message and "should be" in problems[0].message
