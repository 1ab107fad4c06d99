"""hrc fit end to end: parameter recovery and held-out prediction (docs/participant-model.md).

The first PEOPLE of the 20 simulated people of `studies/recovery.toml` (known, varied
parameters: reaction 0.23-0.38 s, peak speed 0.68-1.06 m/s, Fitts a 0.06-0.13 s, b 0.11-0.19
s/bit, dwells 0.22-0.43 s) are each recorded in two real trials (the five services); `hrc fit`
estimates their parameters back from the recordings and events alone. The same people also run a
condition the fit did not see (the robots at 1.0 m/s instead of 0.5), and so do their twins
(`participants.fitted`): each twin's completion time is compared with its person's. Figures are
printed (`-s`). `hrc bench fit` runs all 20 people (80 trials; its figures in bench/README.md):
the test runs 16 trials, enough to see a fit that is biased or a twin that does not predict.
"""

from __future__ import annotations

import json
import subprocess
import tomllib
from pathlib import Path

import pandas as pd
import pytest

from hrc.bench.fit import bench

from .conftest import HRC

pytestmark = [pytest.mark.slow, pytest.mark.e2e]
PEOPLE = 4


@pytest.mark.timeout(900)
def test_fit_recovers_people_and_their_twins_predict_a_held_out_condition(tmp_path: Path) -> None:
    report = bench(tmp_path, workers=2, people=PEOPLE)
    assert report["trials"] == 4 * PEOPLE  # two recorded, one held out, one twin each
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
        assert rec[key]["n"] == PEOPLE
        assert abs(rec[key]["bias"]) <= 0.10, (key, rec[key])
        assert rec[key]["mean_abs_error"] <= 0.10, (key, rec[key])
    for key in ("fitts_a_s", "fitts_b_s", "pick_dwell_s", "place_dwell_s"):
        assert rec[key]["n"] == PEOPLE and rec[key]["mean_abs_error"] <= 0.25, (key, rec[key])
    completion = pred["human.completion_s"]
    assert completion["n"] == PEOPLE and completion["mean_abs_error"] <= 0.15, completion

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
    assert sorted(written) == [f"P{i:02d}" for i in range(1, PEOPLE + 1)]
    assert written == printed["fitted"]
    assert printed["recovery"]["reaction_time_s"]["n"] == PEOPLE
    twins = pd.read_csv(tmp_path / "twins" / "trials.csv")
    assert list(twins["participant_kind"]) == ["fitted"] * PEOPLE
    # each estimate with its uncertainty; the true values within two standard errors
    sure = printed["info"]["P01"]["uncertainty"]
    assert 0.03 < sure["reaction_time_s_rel_se"] < 0.2 and 0 < sure["mt_heldout_error"] < 0.2
    within = printed["recovery"]["reaction_time_s"]["within_2se"]
    assert within[1] == PEOPLE and within[0] >= PEOPLE - 1, within

    # P01's second trial lost its recording, P02's are unreadable: P01 is fitted from one
    # trial (said so), P02 is named, and the others are fitted all the same
    trials = pd.read_csv(people / "trials.csv")
    mine = trials[trials["participant"] == "P01"]["trial"].tolist()
    (people / "trials" / mine[1] / "participant-input.jsonl").unlink()
    for t in trials[trials["participant"] == "P02"]["trial"]:
        (people / "trials" / t / "participant-input.jsonl").write_text("not a recording\n")
    proc = subprocess.run(
        [HRC, "fit", str(people), "--out", str(out), "--json"],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert proc.returncode == 1, proc.stderr
    printed = json.loads(proc.stdout)
    assert "P02" in printed["not_fitted"] and "hrc fit: P02: not fitted: " in proc.stderr
    assert sorted(printed["fitted"]) == ["P01", "P03", "P04"][: PEOPLE - 1]
    assert printed["info"]["P01"]["trials"] == [mine[0]]
    assert any(n.startswith("rests on one trial") for n in printed["info"]["P01"]["notes"])


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
