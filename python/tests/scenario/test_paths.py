"""Relative paths in a scenario: the bundled robot models resolve from any folder."""

from __future__ import annotations

from pathlib import Path

import pytest

from hrc import scenario as sc
from hrc.paths import project_root
from hrc.scenario.paths import resolve_path

THESIS = project_root() / "scenarios" / "thesis.toml"


@pytest.fixture
def study(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A study folder with its own scenarios/ (so it looks like a project root) and no robots/."""
    monkeypatch.delenv("HRC_ROOT", raising=False)
    (tmp_path / "study" / "scenarios").mkdir(parents=True)
    path = tmp_path / "study" / "scenarios" / "mine.toml"
    path.write_text(THESIS.read_text())
    return path


def test_a_scenario_in_a_study_folder_finds_the_bundled_robot_model(study: Path) -> None:
    s = sc.load(study, motion_check=False)
    assert s.robots["r1"].urdf == "robots/arm5.urdf"
    root = sc.find_project_root(study.parent)
    assert root == study.parent.parent  # the study folder: it has scenarios/
    assert (
        resolve_path("robots/arm5.urdf", study.parent, root)
        == (project_root() / "robots" / "arm5.urdf").resolve()
    )


def test_a_model_beside_the_scenario_wins(study: Path) -> None:
    own = study.parent / "robots" / "arm5.urdf"
    own.parent.mkdir()
    own.write_text((project_root() / "robots" / "arm5.urdf").read_text())
    assert resolve_path("robots/arm5.urdf", study.parent, None) == own.resolve()


def test_a_missing_model_is_reported_with_where_it_looked(study: Path) -> None:
    study.write_text(study.read_text().replace("robots/arm5.urdf", "robots/nope.urdf"))
    with pytest.raises(sc.ScenarioError) as exc:
        sc.load(study, motion_check=False)
    assert "file not found: robots/nope.urdf" in str(exc.value)
    assert str(project_root()) in str(exc.value)
