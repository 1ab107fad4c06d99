"""The scripted participant's profiles (docs/participant-model.md): a profile fills the keys a
file leaves unset, a written key wins, the choice travels on the wire and into the records."""

from __future__ import annotations

from pathlib import Path

import pytest

from hrc import metrics
from hrc.scenario import (
    ParticipantProfile,
    ScenarioError,
    ScriptedParams,
    loads,
    scripted_params_from_proto,
    scripted_params_to_proto,
)
from hrc.scenario.profiles import PROFILES

MINIMAL = (Path(__file__).resolve().parents[3] / "scenarios" / "minimal.toml").read_text()


def _with(line: str) -> str:
    """minimal.toml with a line added to its [participant] table."""
    return MINIMAL.replace('input = "scripted"\n', f'input = "scripted"\n{line}\n', 1)


def test_the_default_is_the_baseline_and_its_values_are_the_fields_defaults() -> None:
    p = ScriptedParams()
    assert p.profile == ParticipantProfile.BASELINE
    assert (p.reaction_time_s, p.fitts_a_s, p.fitts_b_s, p.fitts_c_s_per_m) == (0.4, 0.1, 0.15, 0)
    assert p.stop_above and p.collision_reaction == pytest.approx(0.2)
    assert PROFILES[ParticipantProfile.BASELINE] == {}


@pytest.mark.parametrize("profile", [ParticipantProfile.REAL, ParticipantProfile.VR])
def test_a_profile_fills_what_is_unset_and_a_written_key_wins(profile: ParticipantProfile) -> None:
    p = ScriptedParams.model_validate({"profile": profile.value})
    for key, value in PROFILES[profile].items():
        assert getattr(p, key) == value, key
    q = ScriptedParams.model_validate({"profile": profile.value, "reaction_time_s": 0.9})
    assert q.reaction_time_s == 0.9 and q.fitts_a_s == PROFILES[profile]["fitts_a_s"]
    assert q.collision_reaction == PROFILES[profile]["collision_reaction_s"]


def test_a_scenario_file_picks_a_profile_and_a_wrong_one_is_named(arm_root) -> None:
    s = loads(_with('profile = "real"'), project_root=arm_root)
    assert s.participant.profile == ParticipantProfile.REAL
    assert (
        s.participant.scripted_params().fitts_c_s_per_m
        == PROFILES[ParticipantProfile.REAL]["fitts_c_s_per_m"]
    )
    with pytest.raises(ScenarioError) as err:
        loads(_with('profile = "fast"'), project_root=arm_root)
    text = str(err.value)
    assert "participant.profile" in text and "'baseline', 'real' or 'vr'" in text


@pytest.mark.parametrize("profile", list(ParticipantProfile))
def test_the_wire_carries_the_profile_and_its_values(profile: ParticipantProfile) -> None:
    p = ScriptedParams.model_validate({"profile": profile.value, "caution": 0.2})
    assert scripted_params_from_proto(scripted_params_to_proto(p)) == p


def test_the_records_name_the_profile(arm_root) -> None:
    s = loads(_with('profile = "vr"'), project_root=arm_root)
    c = metrics.conditions(s)
    assert c.participant.fitts_a_s == 0.5 and c.participant.collision_reaction_s == 0.25
    line = metrics.settings_line("P01", 1, c)
    assert "profile vr" in line and "stop_above false" in line
