"""safety_policy = "ssm": [conditions.ssm] defaults, [robots.<id>.ssm] overrides, validation
naming the key, and the round trip through the wire."""

from __future__ import annotations

from pathlib import Path

import pytest

from hrc.scenario import SafetyPolicy, ScenarioError, Ssm, from_proto, loads, to_proto

REPO = Path(__file__).resolve().parents[3]


def _thesis(extra_conditions: str = "", r1_ssm: str = "", policy: str = "ssm") -> str:
    text = (REPO / "scenarios" / "thesis.toml").read_text()
    text = text.replace(
        'safety_policy = "retreat"', f'safety_policy = "{policy}"\n{extra_conditions}'
    )
    if r1_ssm:
        text = text.replace("[robots.r2]", f"[robots.r1.ssm]\n{r1_ssm}\n\n[robots.r2]")
    return text


def _load(text: str):
    return loads(text, REPO / "scenarios", REPO)


def test_defaults_and_per_robot_overrides() -> None:
    s = _load(_thesis("\n[conditions.ssm]\nhuman_speed = 2.0", "reaction_time_s = 0.2"))
    assert s.conditions.safety_policy == SafetyPolicy.SSM
    assert s.ssm_of("r1") == Ssm(human_speed=2.0, reaction_time_s=0.2)
    assert s.ssm_of("r2") == Ssm(human_speed=2.0)
    assert Ssm().human_speed == 1.6 and Ssm().deceleration == 2.0


def test_wire_round_trip_keeps_every_value() -> None:
    s = _load(_thesis("\n[conditions.ssm]\nintrusion_distance_m = 0.0", "min_speed = 0.0"))
    msg = to_proto(s)
    assert msg.conditions.safety_policy == 100
    back = from_proto(msg)
    assert back.ssm_of("r1") == s.ssm_of("r1")
    assert back.ssm_of("r2") == s.ssm_of("r2")
    assert back.ssm_of("r1").intrusion_distance_m == 0.0  # a zero is a value, not "unset"


def test_other_policies_leave_the_conditions_as_they_were() -> None:
    msg = to_proto(_load(_thesis(policy="retreat")))
    assert not msg.conditions.HasField("ssm")


@pytest.mark.parametrize(
    ("line", "key", "why"),
    [
        ("reaction_time_s = -1", "robots.r1.ssm.reaction_time_s", "greater than 0"),
        # no real system reacts in no time
        ("reaction_time_s = 0", "robots.r1.ssm.reaction_time_s", "greater than 0"),
        ("deceleration = 3.0", "robots.r1.ssm.deceleration", "less than or equal to 2"),
        ("human_speed = 'fast'", "robots.r1.ssm.human_speed", "valid number"),
        ("speed = 1", "robots.r1.ssm.speed", "unknown key"),
    ],
)
def test_bad_values_name_the_key(line: str, key: str, why: str) -> None:
    with pytest.raises(ScenarioError) as exc:
        _load(_thesis(r1_ssm=line))
    assert key in str(exc.value) and why in str(exc.value)


def test_unknown_policy_lists_ssm() -> None:
    with pytest.raises(ScenarioError, match="ssm"):
        _load(_thesis(policy="slow_down"))
