"""The resolved scenario of a trial (hrc.scenario.resolved): scenario.toml loads back into the
same settings, overrides are applied and listed, and folder names tell trials apart."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from hrc import scenario as sc
from hrc.paths import project_root
from hrc.scenario.resolved import resolve

SCENARIOS = project_root() / "scenarios"


@pytest.mark.parametrize("path", sorted(SCENARIOS.glob("[!.]*.toml")), ids=lambda p: p.stem)
def test_the_copy_loads_back_into_the_same_settings_from_any_folder(
    path: Path, tmp_path: Path
) -> None:
    s = sc.load(path, motion_check=False)
    run = resolve(s)
    copy = tmp_path / "elsewhere" / "scenario.toml"
    copy.parent.mkdir()
    copy.write_text(run.toml(), encoding="utf-8")
    back = sc.load(copy, motion_check=False)  # URDFs found: the copy's paths are absolute
    settings = run.settings()
    for rid in settings["robots"]:
        assert Path(back.robots[rid].urdf) == s.urdf_path(rid)
        settings["robots"][rid]["urdf"] = back.robots[rid].urdf
    assert resolve(back).settings() == settings
    assert "# overrides: none" in run.toml()


def test_overrides_are_applied_listed_and_leave_the_loaded_scenario_alone(tmp_path: Path) -> None:
    s = sc.load(SCENARIOS / "minimal.toml", motion_check=False)
    rec = tmp_path / "p01.jsonl"
    rec.write_text("")
    run = resolve(s, seed=7, replay=rec)
    data = tomllib.loads(run.toml())
    assert data["scenario"]["seed"] == 7
    assert data["participant"]["input"] == "replay"
    assert data["participant"]["replay_file"] == str(rec.resolve())
    assert data["participant"]["caution"] == 0.5  # defaults written out
    assert "# override: scenario.seed = 7 (--seed)" in run.toml()
    assert "(--replay)" in run.toml()
    assert s.scenario.seed == 1 and s.participant.input == sc.InputSource.SCRIPTED


def test_folder_names_differ_in_any_varied_factor_and_name_the_non_default_ones() -> None:
    s = sc.load(SCENARIOS / "minimal.toml", motion_check=False)
    base = resolve(s).folder_name()
    assert base.startswith("minimal_Anticipation_") and len(base.split("_")[-1]) == 8
    assert resolve(s).folder_name() == base  # the same settings: the same name
    seeded = resolve(s, seed=4).folder_name()
    assert seeded.startswith("minimal_Anticipation_seed4_") and seeded != base
    variants = []
    for change in (
        lambda x: setattr(x.robots["r1"], "max_tcp_speed", 0.25),
        lambda x: setattr(x.participant, "caution", 0.9),
        lambda x: setattr(x.conditions, "safety_policy", sc.SafetyPolicy.STOP_COLLIDING),
        lambda x: setattr(x.conditions, "anticipation", False),
    ):
        other = s.model_copy(deep=True)
        change(other)
        variants.append(resolve(other).folder_name())
    assert len({base, *variants}) == 1 + len(variants)
    assert "_stop_colliding_" in variants[2] and variants[3].startswith("minimal_Normal_")
