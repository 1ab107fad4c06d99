"""The study file: checks naming each problem, seeded participants, trial expansion, the TOML
writer, the table's flattening and the report's models on degenerate data (no services)."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from hrc.paths import project_root
from hrc.study import StudyError, load_study
from hrc.study.report import OUTCOMES, fit_model
from hrc.study.spec import apply_overrides
from hrc.study.table import flatten
from hrc.tomlw import dumps

ROOT = project_root()
MINIMAL = ROOT / "scenarios" / "minimal.toml"

STUDY = f"""
[study]
name = "mini"
scenario = "{MINIMAL}"

[factors]
"robots.*.max_tcp_speed" = [0.5, 1.0]
"conditions.anticipation" = [true, false]

[participants]
n = 2
seed_base = 1000
reaction_time_s = {{ dist = "normal", mean = 0.4, sd = 0.08, min = 0.15, max = 0.9 }}
caution = {{ dist = "uniform", min = 0.0, max = 1.0 }}
place_dwell_s = 0.25
"""


def _write(tmp_path: Path, text: str, name: str = "study.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _problems(tmp_path: Path, text: str) -> list[str]:
    with pytest.raises(StudyError) as err:
        load_study(_write(tmp_path, text), motion_check=False)
    return err.value.problems


def test_a_factorial_study_gives_every_combination_for_every_participant(tmp_path: Path) -> None:
    study = load_study(_write(tmp_path, STUDY), motion_check=False)
    assert len(study.trials) == 8
    ids = [t.id for t in study.trials]
    assert len(set(ids)) == 8
    assert "speed0.5_antTrue_P01_r1" in ids
    trial = next(t for t in study.trials if t.id == "speed1_antFalse_P02_r1")
    scen = tomllib.loads(trial.scenario_text)
    assert [r["max_tcp_speed"] for r in scen["robots"].values()] == [1.0, 1.0]
    assert scen["conditions"]["anticipation"] is False
    assert scen["participant"]["name"] == "P02"
    assert scen["participant"]["place_dwell_s"] == 0.25
    assert trial.seed == 1002
    # only the varied keys differ from the base scenario
    base = tomllib.loads(MINIMAL.read_text())
    assert scen["parts"] == base["parts"] and scen["workspace"] == base["workspace"]


def test_participants_are_drawn_from_their_seed_within_bounds(tmp_path: Path) -> None:
    a = load_study(_write(tmp_path, STUDY, "a.toml"), motion_check=False)
    b = load_study(_write(tmp_path, STUDY, "b.toml"), motion_check=False)
    c = load_study(
        _write(tmp_path, STUDY.replace("seed_base = 1000", "seed_base = 7"), "c.toml"),
        motion_check=False,
    )
    assert [p.params for p in a.people] == [p.params for p in b.people]
    assert [p.params for p in a.people] != [p.params for p in c.people]
    assert a.people[0].params != a.people[1].params
    for p in a.people:
        assert 0.15 <= p.params["reaction_time_s"] <= 0.9
        assert 0.0 <= p.params["caution"] <= 1.0
    assert [t.input_hash for t in a.trials] == [t.input_hash for t in b.trials]
    assert len({t.input_hash for t in a.trials}) == 8


def test_every_bad_factor_path_and_value_is_named(tmp_path: Path) -> None:
    text = STUDY.replace(
        '"conditions.anticipation" = [true, false]',
        '"conditions.anticipation" = [true, "maybe"]\n'
        '"robots.r9.max_tcp_speed" = [0.5]\n'
        '"participant.cautoin" = [0.5]\n'
        '"robots.*.max_tcp_speed" = [2.5]\n',
    ).replace('"robots.*.max_tcp_speed" = [0.5, 1.0]\n', "")
    problems = _problems(tmp_path, text)
    joined = "\n".join(problems)
    assert "factors.robots.r9.max_tcp_speed: the scenario has no table robots.r9" in joined
    # the rest is found on the resolved scenarios, by the scenario checks
    text = text.replace('"robots.r9.max_tcp_speed" = [0.5]\n', "")
    joined = "\n".join(_problems(tmp_path, text))
    assert "conditions.anticipation: should be a valid boolean" in joined, joined
    assert "participant.cautoin: unknown key" in joined, joined
    assert "robots.r1.max_tcp_speed: should be less than or equal to 1.5" in joined, joined
    assert "robots.r2.max_tcp_speed" in joined


def test_study_level_problems_are_all_listed(tmp_path: Path) -> None:
    text = (
        STUDY.replace('name = "mini"', 'name = "mini"\nrepetitions = 0\ncolour = 1')
        .replace("n = 2", "n = -1")
        .replace('dist = "uniform"', 'dist = "beta"')
        .replace("place_dwell_s = 0.25", "hand_speed = 2")
    )
    joined = "\n".join(_problems(tmp_path, text))
    for expected in (
        "study.colour: unknown key",
        "study.repetitions: should be an integer >= 1",
        "participants.n: should be an integer >= 0",
        "participants.caution.dist: should be one of normal, uniform",
        "participants.hand_speed: not a participant parameter",
    ):
        assert expected in joined, joined
    missing = _problems(tmp_path, STUDY.replace(str(MINIMAL), "nowhere.toml"))
    assert missing == ["study.scenario: no such scenario file 'nowhere.toml'"]


def test_a_list_design_runs_the_listed_conditions(tmp_path: Path) -> None:
    text = (
        STUDY.replace('name = "mini"', 'name = "mini"\ndesign = "list"').split("[factors]")[0]
        + '[[conditions]]\n"conditions.anticipation" = true\n"scenario.stall_timeout_s" = 5.0\n'
        + '[[conditions]]\n"conditions.anticipation" = false\n"scenario.stall_timeout_s" = 9.0\n'
        + "[participants]\nn = 1\n"
    )
    study = load_study(_write(tmp_path, text), motion_check=False)
    assert [t.id for t in study.trials] == ["antTrue_stall5_P01_r1", "antFalse_stall9_P01_r1"]
    assert study.factors == {
        "conditions.anticipation": [True, False],
        "scenario.stall_timeout_s": [5.0, 9.0],
    }


def test_repetitions_get_their_own_seed(tmp_path: Path) -> None:
    text = STUDY.replace('name = "mini"', 'name = "mini"\nrepetitions = 2')
    study = load_study(_write(tmp_path, text), motion_check=False)
    assert len(study.trials) == 16
    seeds = {(t.person.id, t.repetition): t.seed for t in study.trials}
    assert seeds[("P01", 1)] != seeds[("P01", 2)]


def test_the_toml_writer_round_trips_every_shipped_scenario() -> None:
    for path in sorted((ROOT / "scenarios").glob("[!.]*.toml")):  # (not an editor's temp file)
        doc = tomllib.loads(path.read_text())
        assert tomllib.loads(dumps(doc)) == doc, path


def test_overrides_with_a_star_set_every_robot() -> None:
    doc = tomllib.loads(MINIMAL.read_text())
    out = apply_overrides(doc, {"robots.*.near_margin": 0.1, "scenario.seed": 4})
    assert [r["near_margin"] for r in out["robots"].values()] == [0.1, 0.1]
    assert out["scenario"]["seed"] == 4 and "near_margin" not in doc["robots"]["r1"]


def test_flatten_names_nested_fields_with_dots_and_counts_lists() -> None:
    flat = flatten({"task": {"completion_s": 3.0}, "collisions": {"near": [{"t_s": 1}]}})
    assert flat == {"task.completion_s": 3.0, "collisions.near": 1}


def _frame(y: list[float], people: list[str]) -> pd.DataFrame:
    n = len(y)
    return pd.DataFrame(
        {
            "task_completion_s": y,
            "participant": people,
            "speed": ["0.5", "1"] * (n // 2),
        }
    )


def test_the_model_notes_degenerate_data_instead_of_failing() -> None:
    outcome = OUTCOMES[0]
    levels = {"speed": ["0.5", "1"]}
    const = fit_model(_frame([5.0] * 8, ["P1", "P1", "P2", "P2"] * 2), outcome, ["speed"], levels)
    assert const.rows == [] and "same value (5) in every trial" in const.notes[-1]
    one = fit_model(_frame([5.0, 3.0, 5.5, 3.2], ["P1"] * 4), outcome, ["speed"], levels)
    assert "one participant" in one.notes[0]
    assert one.rows and one.rows[1][1] == pytest.approx(-2.15)
    rng = np.random.default_rng(1)
    y = list(10 - 4 * np.tile([0, 1], 10) + rng.normal(0, 0.5, 20))
    fit = fit_model(_frame(y, [f"P{i // 2}" for i in range(20)]), outcome, ["speed"], levels)
    effect = fit.rows[1]
    assert effect[0] == "speed = 1 (vs 0.5)"
    assert effect[2] < -4 + 1 and effect[3] > -4 - 1 and effect[2] < effect[1] < effect[3]


def test_a_report_of_a_sweep_in_which_every_trial_failed_lists_them(tmp_path: Path) -> None:
    from hrc.study.report import write_report

    rows = [
        {"study": "s", "trial": f"speed{v}_P01_r1", "robots.*.max_tcp_speed": v,
         "participant": "P01", "outcome": "failed", "reason": f"hrc run exited with code 3 ({v})"}
        for v in (0.5, 1.0)
    ]  # fmt: skip
    pd.DataFrame(rows).to_parquet(tmp_path / "trials.parquet")
    (tmp_path / "study.json").write_text(
        '{"name": "s", "factors": {"robots.*.max_tcp_speed": [0.5, 1.0]}}'
    )
    page = write_report(tmp_path).read_text()
    assert "speed0.5_P01_r1" in page and "exited with code 3 (1.0)" in page
    assert "Statistics use the 0 trials that ended ok" in page


def test_the_shipped_studies_load() -> None:
    for path, trials in (("thesis-speed-anticipation", 60), ("retreat-vs-ssm", 40)):
        study = load_study(ROOT / "studies" / f"{path}.toml", motion_check=False)
        assert len(study.trials) == trials, path


FITTED = """# hrc fit
[fitted]
L01 = { reaction_time_s = 0.33, peak_hand_speed = 0.9, fitts_a_s = 0.12, stop_above = false }
L02 = { reaction_time_s = 0.51, peak_hand_speed = 1.3 }

[fit_info]
L01 = { trials = ["a"], moves = 40 }
"""


def test_fitted_participants_become_twins_with_their_parameters(tmp_path: Path) -> None:
    (tmp_path / "fitted.toml").write_text(FITTED)
    text = STUDY.replace("n = 2\n", 'n = 1\nfitted = "fitted.toml"\n').replace(
        "[study]\n", "[study]\nrecord = true\n"
    )
    study = load_study(_write(tmp_path, text), motion_check=False)
    assert study.record
    twins = [p for p in study.people if p.fitted_from is not None]
    assert [(p.id, p.fitted_from) for p in twins] == [("L01-twin", "L01"), ("L02-twin", "L02")]
    # the fitted values, and the study's fixed values for what the fit does not estimate
    assert twins[0].params == {
        "place_dwell_s": 0.25,
        "reaction_time_s": 0.33,
        "peak_hand_speed": 0.9,
        "fitts_a_s": 0.12,
        "stop_above": False,
    }
    trial = next(t for t in study.trials if t.person.id == "L02-twin")
    scen = tomllib.loads(trial.scenario_text)["participant"]
    assert scen["name"] == "L02-twin" and scen["reaction_time_s"] == 0.51
    assert scen["peak_hand_speed"] == 1.3
    from hrc.study.table import rows
    from hrc.study.trial import Record

    kinds = {
        r["participant"]: r["participant_kind"]
        for r in rows(study, [Record(t.id, t.input_hash, "ok") for t in study.trials])
    }
    assert kinds == {"P01": "simulated", "L01-twin": "fitted", "L02-twin": "fitted"}


@pytest.mark.parametrize(
    ("fitted", "content", "expected"),
    [
        ('"nope.toml"', None, "participants.fitted: no such file 'nope.toml'"),
        ('"fitted.toml"', "[other]\nx = 1\n", "has no [fitted.<participant>] table"),
        ("3", None, "participants.fitted: should be the path of a fitted.toml"),
    ],
)
def test_a_bad_fitted_table_is_named(
    tmp_path: Path, fitted: str, content: str | None, expected: str
) -> None:
    if content is not None:
        (tmp_path / "fitted.toml").write_text(content)
    problems = _problems(tmp_path, STUDY.replace("n = 2\n", f"n = 1\nfitted = {fitted}\n"))
    assert any(expected in p for p in problems), problems


def test_seeds_per_trial_differ_between_conditions_and_not_with_the_study_size(
    tmp_path: Path,
) -> None:
    """`study.seeds = "trial"` (hrc power's pools): a person's trials each with a seed of its
    own; a trial's seed is the same in a larger pool (its trials are reused)."""
    path = _write(tmp_path, STUDY)
    shared = load_study(path, motion_check=False)
    assert {t.seed for t in shared.trials if t.person.id == "P01"} == {1001}
    own = load_study(path, motion_check=False, seeds="trial")
    mine = [t for t in own.trials if t.person.id == "P01"]
    assert len({t.seed for t in mine}) == len(mine) == 4
    larger = load_study(path, motion_check=False, seeds="trial", participants=5)
    assert len({t.person.id for t in larger.trials}) == 5
    again = {t.id: (t.seed, t.input_hash) for t in larger.trials}
    assert all(again[t.id] == (t.seed, t.input_hash) for t in own.trials)
    in_file = load_study(
        _write(tmp_path, STUDY.replace("[study]\n", '[study]\nseeds = "trial"\n'), "b.toml"),
        motion_check=False,
    )
    assert [t.seed for t in in_file.trials] == [t.seed for t in own.trials]
    problems = _problems(tmp_path, STUDY.replace("[study]\n", '[study]\nseeds = "each"\n'))
    assert "study.seeds: should be one of participant, trial (got 'each')" in problems


def test_record_must_be_a_bool(tmp_path: Path) -> None:
    problems = _problems(tmp_path, STUDY.replace("[study]\n", '[study]\nrecord = "yes"\n'))
    assert any(p.startswith("study.record: should be true or false") for p in problems), problems


def test_hrc_validate_checks_a_study_file_as_a_study(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`hrc validate` of a study file checks the study (it said the file lacked a scenario's
    keys: "scenario: missing required key", "study: unknown key", ...)."""
    from hrc.cli.main import main

    shipped = project_root() / "studies" / "people-speed-anticipation.toml"
    assert main(["validate", "--no-reach", str(shipped)]) == 0
    said = capsys.readouterr().out
    assert "ok (study people-speed-anticipation: 6 conditions" in said, said
    assert "12 live participants" in said
    bad = tmp_path / "bad.toml"
    minimal = project_root() / "scenarios" / "minimal.toml"
    bad.write_text(
        f'[study]\nname = "s"\nscenario = "{minimal}"\n'
        '[factors]\n"conditions.anticipaton" = [true]\n[participants]\nn = 1\n'
    )
    assert main(["validate", "--no-reach", str(bad)]) == 1
    err = capsys.readouterr().err
    assert "anticipaton" in err and "missing required key" not in err, err
