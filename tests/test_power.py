"""`hrc power` end to end on real trials (five services each) of a tiny design on minimal.toml:
robot speed 0.25 vs 1.0 m/s (a large effect on the task's completion, which the robots bound)
crossed with r2's colour (no effect on anything: the null). The pool runs once; the second
question reuses it. Power near 1 for the speed, near alpha for the colour."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pandas as pd
import pytest

from .conftest import HRC
from .goldens import MINIMAL

pytestmark = [pytest.mark.slow, pytest.mark.e2e]

STUDY = f"""
[study]
name = "tiny-power"
scenario = "{MINIMAL}"

[factors]
"robots.*.max_tcp_speed" = [0.25, 1.0]
"robots.r2.color" = ["green", "blue"]

[participants]
n = 2
seed_base = 1000
reaction_time_s = {{ dist = "normal", mean = 0.4, sd = 0.08, min = 0.15, max = 0.9 }}
peak_hand_speed = {{ dist = "normal", mean = 1.0, sd = 0.15, min = 0.5, max = 1.6 }}
"""
POOL = 8


def power(study: Path, out: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, CI="1")  # plain progress lines
    return subprocess.run(
        [HRC, "power", str(study), "--pool", str(POOL), "--out", str(out), *args],
        capture_output=True,
        text=True,
        timeout=400,
        env=env,
    )


def test_power_finds_a_large_effect_always_and_no_effect_about_alpha_of_the_time(
    tmp_path: Path,
) -> None:
    study = tmp_path / "tiny.toml"
    study.write_text(STUDY)
    out = tmp_path / "power"

    big = power(study, out, "--effect", "robots.*.max_tcp_speed", "--n", "2,3,4", "--sims", "60")
    assert big.returncode == 0, big.stderr[-3000:]
    assert f"sweep: {POOL * 4} trials, 0 done before (kept), {POOL * 4} to run" in big.stderr
    saved = json.loads((out / "power.json").read_text())
    assert saved["pool"] == POOL and saved["trials"] == POOL * 4
    by_n = {p["n"]: p for p in saved["points"]}
    assert by_n[3]["power"] >= 0.95 and by_n[4]["power"] >= 0.95, by_n
    # the robots bound the task: 1.0 m/s saves seconds, in every drawn study
    mean, low, high = by_n[4]["effects"]["1.0"]
    assert -3.0 < low <= mean + 1e-9 and mean <= high + 1e-9 and high < -0.5, by_n[4]["effects"]
    assert saved["smallest_n"] in (2, 3)
    assert big.stdout.startswith(f"{saved['smallest_n']} participants see the effect of")
    # every trial with a seed of its own (a person's noise differs between conditions)
    table = pd.read_parquet(out / "pool" / "trials.parquet")
    assert table["seed"].nunique() == len(table) == POOL * 4

    null = power(
        study,
        out,
        "--effect",
        "robots.r2.color",
        "--outcome",
        "human_completion_s",
        "--n",
        "4",
        "--sims",
        "300",
    )
    assert null.returncode == 0, null.stderr[-3000:]
    assert f"{POOL * 4} done before (kept), 0 to run" in null.stderr  # the pool reused
    (point,) = json.loads((out / "power.json").read_text())["points"]
    # no effect: found in about alpha of the studies (the Wald test leans a little above it
    # with four people), far from the speed's
    assert point["power"] <= 0.15, point
    assert point["low"] <= 0.05, point
    assert null.stdout.startswith("No N up to 4 reaches 80% power")
    assert (out / "power.png").stat().st_size > 10_000
    assert "robots.r2.color" in (out / "power.html").read_text()


def test_a_request_the_study_cannot_answer_is_refused_before_any_trial(tmp_path: Path) -> None:
    study = tmp_path / "tiny.toml"
    study.write_text(STUDY)
    out = tmp_path / "power"
    wrong = power(study, out, "--effect", "conditions.anticipation")
    assert wrong.returncode == 2
    assert "--effect 'conditions.anticipation' is not a factor of the study" in wrong.stderr
    assert "robots.*.max_tcp_speed, robots.r2.color" in wrong.stderr
    big = power(study, out, "--effect", "robots.r2.color", "--n", "4,12")
    assert big.returncode == 2
    assert "--n up to 12 needs a pool of at least that many people (the pool has 8" in big.stderr
    bad = power(study, out, "--effect", "robots.r2.color", "--n", "1,x")
    assert bad.returncode == 2 and "--n: a list of whole numbers" in bad.stderr
    assert not (out / "pool").exists()
