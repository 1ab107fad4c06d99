"""A trial's folder (docs/task-semantics.md#outputs): named after its conditions and a hash of
the resolved scenario, holding that scenario as it ran (overrides applied) and recording every
varied condition in metrics.json and log.txt."""

from __future__ import annotations

import datetime as dt
import json
import re
import subprocess
from pathlib import Path

import pytest

from hrc import scenario as sc

from .conftest import HRC, ROOT

pytestmark = [pytest.mark.e2e, pytest.mark.slow]


def test_a_default_trial_folder_holds_the_scenario_as_it_ran(tmp_path: Path, ik_bin: Path) -> None:
    proc = subprocess.run(
        [HRC, "run", str(ROOT / "scenarios" / "minimal.toml"), "--seed", "3"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=240,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    (trial,) = (tmp_path / "runs" / dt.date.today().isoformat() / "P00").iterdir()
    # the non-default condition (the seed) and the hash of the resolved scenario
    assert re.fullmatch(r"minimal_Anticipation_seed3_[0-9a-f]{8}", trial.name), trial.name

    ran = sc.load(trial / "scenario.toml", motion_check=False)
    assert ran.scenario.seed == 3  # --seed applied
    source = sc.load(ROOT / "scenarios" / "minimal.toml", motion_check=False)
    assert ran.robots["r1"].max_tcp_speed == source.robots["r1"].max_tcp_speed
    assert "# override: scenario.seed = 3 (--seed)" in (trial / "scenario.toml").read_text()

    m = json.loads((trial / "metrics.json").read_text())
    assert m["seed"] == 3
    c = m["conditions"]
    assert c["robots"] == {"r1": {"max_tcp_speed": 0.5}, "r2": {"max_tcp_speed": 0.5}}
    assert c["participant"]["input"] == "scripted" and c["participant"]["caution"] == 0.5
    for r in m["robots"].values():
        assert r["completion_s"] < r["completion_home_s"]
        assert r["avg_tcp_speed_over_time_mps"] < r["avg_tcp_speed_mps"] <= 0.5
    assert m["task"]["completion_s"] < m["task"]["completion_home_s"]
    # physics checked every link, and nobody from outside tried one
    assert m["access"] == {
        "refused_links": 0,
        "no_credentials": 0,
        "unknown_user": 0,
        "wrong_password": 0,
    }

    log = (trial / "log.txt").read_text().splitlines()
    assert log[0].startswith("SETTINGS: anticipation on, safety policy retreat, seed 3; ")
    assert "r1 max TCP speed 0.5 m/s" in log[0]
    assert log[-2].endswith("TASK FINISHED. 0 total collisions.")
    assert log[-1].endswith("0 total near-collisions between the robots.")
    assert f"{trial.relative_to(tmp_path)}" in proc.stdout

    # where the wall time went (hrc bench trial reads it): every phase, every service's exit
    t = json.loads((trial / "services" / "timing.json").read_text())
    assert t["run_s"] == pytest.approx(m["run"]["wall_s"], abs=2e-3)
    assert all(t[k] is not None and t[k] >= 0 for k in ("prepare_s", "start_s", "end_s"))
    services = {"physics", "ik_cpp", "orchestrator", "human_input", "logger"}
    assert set(t["exit_by_service_s"]) == services
    assert max(t["exit_by_service_s"].values()) == pytest.approx(t["end_s"])
