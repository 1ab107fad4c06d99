"""hrc fit end to end: parameter recovery and held-out prediction (docs/participant-model.md).

20 simulated people with known, varied parameters are each recorded in two real trials (the
five services, `studies/recovery.toml`); `hrc fit` estimates their parameters back from the
recordings and events alone. The same people also run a condition the fit did not see (the
robots at 1.0 m/s instead of 0.5), and so do their twins (`participants.fitted`): each twin's
completion time is compared with its person's. Figures are printed (`-s`); `hrc bench fit`
prints the same.
"""

from __future__ import annotations

import json
import subprocess
import tomllib
from pathlib import Path

import pandas as pd
import pytest

from hrc.cli.bench_fit import bench

from .conftest import HRC

pytestmark = [pytest.mark.slow, pytest.mark.e2e]


@pytest.mark.timeout(2400)
def test_fit_recovers_people_and_their_twins_predict_a_held_out_condition(tmp_path: Path) -> None:
    report = bench(tmp_path, workers=2)
    rec, pred = report["recovery"], report["prediction"]
    print(f"\n{report['trials']} trials in {report['wall_s']} s")
    for key, r in {**rec, **pred}.items():
        bias, mae, worst = (100 * r.get(k, 0) for k in ("bias", "mean_abs_error", "max_abs_error"))
        print(
            f"{key:<20} n {r['n']:>2} bias {bias:+6.1f} % mean |error| {mae:5.1f} % "
            f"max {worst:5.1f} %"
            + (f" ({r['mean_abs_error_s']:.2f} s)" if "mean_abs_error_s" in r else "")
        )
    assert not report["failed"], report["failed"]
    for key in ("reaction_time_s", "peak_hand_speed"):
        assert rec[key]["n"] == 20
        assert abs(rec[key]["bias"]) <= 0.10, (key, rec[key])
        assert rec[key]["mean_abs_error"] <= 0.10, (key, rec[key])
    for key in ("fitts_a_s", "fitts_b_s", "pick_dwell_s", "place_dwell_s"):
        assert rec[key]["n"] == 20 and rec[key]["mean_abs_error"] <= 0.25, (key, rec[key])
    completion = pred["human.completion_s"]
    assert completion["n"] == 20 and completion["mean_abs_error"] <= 0.15, completion

    # the command on the same folder: one table per person, read back by a study
    people = tmp_path / "people"
    out = tmp_path / "cli-fitted.toml"
    proc = subprocess.run(
        [HRC, "fit", str(people), "--out", str(out), "--json"],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    printed = json.loads(proc.stdout)
    written = tomllib.loads(out.read_text())["fitted"]
    assert sorted(written) == [f"P{i:02d}" for i in range(1, 21)]
    assert written == printed["fitted"]
    assert printed["recovery"]["reaction_time_s"]["n"] == 20
    twins = pd.read_csv(tmp_path / "twins" / "trials.csv")
    assert list(twins["participant_kind"]) == ["fitted"] * 20


def test_fit_names_what_is_missing(tmp_path: Path) -> None:
    proc = subprocess.run(
        [HRC, "fit", str(tmp_path), "--participant", "L01"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 1
    assert "no participant-input.jsonl" in proc.stderr
    proc = subprocess.run(
        [HRC, "fit", str(tmp_path)], capture_output=True, text=True, timeout=120, check=False
    )
    assert proc.returncode == 2 and "--participant" in proc.stderr
