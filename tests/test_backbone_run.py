"""hrc run on the empty scenario: five processes, lockstep ticks, metrics.json (issue 2)."""

from __future__ import annotations

import json
import subprocess

from .conftest import HRC, ROOT


def test_hrc_run_empty_runs_2000_lockstep_ticks_and_writes_metrics(tmp_path, ik_bin) -> None:
    out = tmp_path / "trial"
    proc = subprocess.run([HRC, "run", str(ROOT / "scenarios" / "empty.toml"), "--out", str(out),
                           "--ticks", "2000"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    m = json.loads((out / "metrics.json").read_text())
    assert m["run"]["ticks"] == 2000
    assert m["run"]["mode"] == "lockstep"
    assert m["run"]["wall_s"] > 0
    assert m["scenario"] == "empty"
    # every service ran as its own process and left its own log
    for name in ("physics", "orchestrator", "ik_cpp", "human_input", "logger"):
        assert (out / "services" / f"{name}.log").exists(), name
    assert "2000 ticks" in proc.stdout


def test_the_five_services_are_separate_processes_that_all_take_part(trial_factory) -> None:
    trial = trial_factory()
    trial.wait_ticking()
    pids = trial.service_pids()
    assert sorted(pids) == sorted(["physics", "orchestrator", "ik_cpp", "human_input", "logger"])
    assert len(set(pids.values())) == 5
    for name in pids:
        s = trial.stats(name)
        assert s.service == name
        assert s.ticks_seen > 0 or name == "physics", name
    trial.stop()
    code, out, err = trial.communicate()
    assert code == 0, err
    m = json.loads((trial.out / "metrics.json").read_text())
    assert m["run"]["ticks"] > 0 and "stopped by tester" in m["run"]["end_reason"]


def test_realtime_mode_is_paced_by_the_wall_clock(tmp_path, ik_bin) -> None:
    out = tmp_path / "rt"
    proc = subprocess.run([HRC, "run", str(ROOT / "scenarios" / "empty.toml"), "--out", str(out),
                           "--ticks", "480", "--mode", "realtime"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    run = json.loads((out / "metrics.json").read_text())["run"]
    assert run["mode"] == "realtime" and run["ticks"] == 480
    assert run["wall_s"] >= 479 / 240  # never ahead of the wall clock
    assert "deadline_misses" in run


def test_a_bad_scenario_starts_nothing_and_names_the_problem(tmp_path, ik_bin) -> None:
    bad = tmp_path / "bad.toml"
    text = (ROOT / "scenarios" / "empty.toml").read_text().replace("tick_hz = 240", "tick_hz = -5")
    assert "tick_hz = -5" in text
    bad.write_text(text)
    out = tmp_path / "never"
    proc = subprocess.run([HRC, "run", str(bad), "--out", str(out)], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 2
    assert "tick_hz" in proc.stderr
    assert not out.exists()
