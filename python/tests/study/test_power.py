"""`hrc power`'s statistics (hrc.study.power) on pools made here, where the truth is known: a
large effect is found in nearly every study, no effect in about alpha of them, an outcome that
the factor sets exactly (a robot-bound task time) counts as found; bad requests are named.
`tests/test_power.py` runs the whole command on simulated trials."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from hrc.study.power import (
    PowerError,
    PowerSettings,
    analyse,
    answer,
    effect_test,
    power_curve,
    wilson,
    write_outputs,
)

SPEED, CUE = "robots.*.max_tcp_speed", "conditions.anticipation"
FACTORS = [SPEED, CUE]
LEVELS = {SPEED: ["0.25", "0.5"], CUE: ["True", "False"]}


def pool(people: int, cue_effect_s: float, seed: int = 3, noise_s: float = 1.0) -> pd.DataFrame:
    """Each person does the four cells once: task time 40 s, 6 s more at the slow speed,
    `cue_effect_s` more without cues, a person's own offset (sd 2 s) and trial noise."""
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(people):
        offset = rng.normal(0, 2.0)
        for speed in LEVELS[SPEED]:
            for cue in LEVELS[CUE]:
                t = 40.0 + 6.0 * (speed == "0.25") + cue_effect_s * (cue == "False") + offset
                rows.append(
                    {
                        "participant": f"P{i:03d}",
                        SPEED: speed,
                        CUE: cue,
                        "task_completion_s": t + rng.normal(0, noise_s),
                    }
                )
    return pd.DataFrame(rows)


def test_the_wilson_interval_brackets_the_share() -> None:
    low, high = wilson(8, 10)
    assert low < 0.8 < high and 0.45 < low < 0.5 and 0.94 < high < 0.96
    assert wilson(0, 50)[0] == 0.0 and 0.0 < wilson(0, 50)[1] < 0.08
    assert wilson(50, 50)[1] == 1.0


def test_a_large_effect_is_found_in_nearly_every_study() -> None:
    settings = PowerSettings(CUE, ns=(4, 8), sims=60)
    points, whole = power_curve(pool(60, 3.0), FACTORS, LEVELS, settings)
    assert [p.n for p in points] == [4, 8]
    assert points[1].power >= 0.95, points
    assert points[0].power <= points[1].power
    # the estimate is the effect put in: no cues, 3 s slower
    mean, low, high = points[1].effects["False"]
    assert 2.5 < mean < 3.5 and low < 3.0 < high
    assert whole is not None and whole[0] < 1e-6 and abs(whole[1]["False"] - 3.0) < 0.4


def test_no_effect_is_found_in_about_alpha_of_the_studies() -> None:
    settings = PowerSettings(CUE, ns=(8,), sims=200, seed=7)
    (point,), _ = power_curve(pool(200, 0.0), FACTORS, LEVELS, settings)
    assert point.not_fitted == 0
    assert point.low <= 0.05 <= point.high or 0.02 <= point.power <= 0.1, point
    # and the speed effect in the same studies: found every time
    speed = PowerSettings(SPEED, ns=(8,), sims=50, seed=7)
    (found,), _ = power_curve(pool(200, 0.0), FACTORS, LEVELS, speed)
    assert found.power == 1.0


def test_an_outcome_the_factor_sets_exactly_counts_as_found() -> None:
    """A robot-bound task time: the same in every trial of a speed, whoever the person. The
    mixed model is degenerate there; the difference is certain, not unfittable."""
    exact = pool(6, 0.0, noise_s=0.0)
    exact["task_completion_s"] = np.where(exact[SPEED] == "0.25", 6.575, 4.696)
    result = effect_test(exact, "task_completion_s", FACTORS, LEVELS, SPEED)
    assert result is not None and result[0] == 0.0 and abs(result[1]["0.5"] + 1.879) < 1e-9
    # ... and the factor that changes nothing there is not found
    result = effect_test(exact, "task_completion_s", FACTORS, LEVELS, CUE)
    assert result is not None and result[0] == 1.0


def sweep_folder(folder: Path, data: pd.DataFrame) -> Path:
    """A pool's sweep folder as `hrc sweep` leaves it (the table and study.json)."""
    folder.mkdir(parents=True)
    table = data.rename(columns={"task_completion_s": "task.completion_s"})
    table["outcome"] = "ok"
    table["study"] = "synthetic"
    table.to_parquet(folder / "trials.parquet")
    meta = {"name": "synthetic", "factors": {SPEED: [0.25, 0.5], CUE: [True, False]}}
    (folder / "study.json").write_text(json.dumps(meta))
    return folder


def test_the_outputs_give_the_answer_the_curve_and_the_table(tmp_path: Path) -> None:
    folder = sweep_folder(tmp_path / "pool", pool(16, 3.0))
    result = analyse(folder, PowerSettings(CUE, ns=(2, 4, 10), sims=40))
    assert result.pool == 16 and result.trials == 64 and result.reference == "True"
    assert result.smallest_n in (2, 4)
    assert any("half the pool" in n for n in result.notes)  # N = 10 of 16 shares people
    text = answer(result)
    assert text.startswith(f"{result.smallest_n} participants see the effect of {CUE}")
    page = write_outputs(result, tmp_path)
    saved = json.loads((tmp_path / "power.json").read_text())  # strict JSON: no NaN
    assert [p["n"] for p in saved["points"]] == [2, 4, 10]
    assert saved["smallest_n"] == result.smallest_n
    csv = (tmp_path / "power.csv").read_text().splitlines()
    assert csv[0].startswith("n,sims,significant,power") and len(csv) == 4
    assert (tmp_path / "power.png").stat().st_size > 10_000
    assert "power.png" in page.read_text() and text in page.read_text()


def test_no_n_reaching_the_target_is_said(tmp_path: Path) -> None:
    folder = sweep_folder(tmp_path / "pool", pool(20, 0.0))
    result = analyse(folder, PowerSettings(CUE, ns=(4, 6), sims=30))
    assert result.smallest_n is None
    assert answer(result).startswith("No N up to 6 reaches 80% power")


@pytest.mark.parametrize(
    ("settings", "said"),
    [
        (PowerSettings("conditions.nope", ns=(4,)), "is not a factor of the study"),
        (PowerSettings(CUE, outcome="happiness", ns=(4,)), "--outcome 'happiness': one of"),
        (PowerSettings(CUE, ns=(4, 40)), "N = 40 is more than the pool's 16 participants"),
    ],
)
def test_what_cannot_be_answered_is_named(
    tmp_path: Path, settings: PowerSettings, said: str
) -> None:
    folder = sweep_folder(tmp_path / "pool", pool(16, 3.0))
    with pytest.raises(PowerError) as err:
        analyse(folder, settings)
    assert said in str(err.value)


def test_power_is_reproducible_from_its_seed() -> None:
    data = pool(30, 1.0)
    a, _ = power_curve(data, FACTORS, LEVELS, PowerSettings(CUE, ns=(4,), sims=40, seed=5))
    b, _ = power_curve(data, FACTORS, LEVELS, PowerSettings(CUE, ns=(4,), sims=40, seed=5))
    assert a == b and not math.isnan(a[0].power)
