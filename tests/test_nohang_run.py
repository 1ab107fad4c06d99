"""No trial outlives its `hrc run`, and a trial that cannot progress ends through the watchdog."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from hrc.service_table import STOP_GRACE_S

from .conftest import HRC, ROOT, gone, wait_until

# Once hrc run has ended (or died), its services are gone within this: each has STOP_GRACE_S
# to write its files after the SIGTERM it gets, and a loaded machine adds seconds (3 s after a
# SIGKILL the orchestrator was once still there). Had they not been stopped they would run on
# (the trials' 10^9 ticks; physics's lease, 10 s, is the soonest the others would leave).
GONE_S = STOP_GRACE_S + 4


def _assert_gone(pids: dict[str, int]) -> None:
    """Every service of the trial is gone within GONE_S; the ones left are named."""
    assert wait_until(lambda: all(gone(p) for p in pids.values()), GONE_S), {
        n: p for n, p in pids.items() if not gone(p)
    }


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP, signal.SIGKILL])
def test_hrc_run_stopped_by_a_signal_leaves_no_service(trial_factory, sig: int) -> None:
    trial = trial_factory(ROOT / "scenarios" / "thesis.toml")
    trial.wait_ticking()
    pids = trial.service_pids()
    assert len(pids) == 5, pids
    os.kill(trial.proc.pid, sig)
    code, _out, err = trial.communicate(timeout=10)
    # SIGKILL cannot be caught: the services go by themselves (they die with their parent)
    assert code == (-sig if sig == signal.SIGKILL else 128 + sig), err
    _assert_gone(pids)
    if sig != signal.SIGKILL:
        assert f"stopped by {signal.Signals(sig).name}" in err


@pytest.mark.slow
def test_ctrl_c_ends_hrc_run_even_when_it_was_started_with_sigint_ignored(trial_factory) -> None:
    """A script's background job, nohup or a CI runner starts a program with SIGINT ignored, and
    Python leaves it so: a Ctrl-C (SIGINT to the process group) was lost and the trial went on
    (issue 41). hrc run takes it as Ctrl-C whatever it inherited."""
    trial = trial_factory(ROOT / "scenarios" / "thesis.toml", sigint_ignored=True)
    trial.wait_ticking()
    pids = trial.service_pids()
    assert len(pids) == 5, pids
    os.killpg(trial.proc.pid, signal.SIGINT)
    code, _out, err = trial.communicate(timeout=30)
    assert code == 130, (code, err[-2000:])
    assert "trial interrupted" in err, err[-2000:]
    metrics = json.loads((trial.out / "metrics.json").read_text())
    assert "interrupted (Ctrl-C)" in metrics["run"]["end_reason"], metrics["run"]
    _assert_gone(pids)


@pytest.mark.slow
def test_an_infeasible_move_at_run_time_ends_the_trial_at_once_naming_it(
    tmp_path: Path, ik_bin: Path
) -> None:
    # RA1 lies far outside r1's reach; validation (which would say so) is bypassed
    text = (ROOT / "scenarios" / "thesis.toml").read_text()
    far = text.replace(
        "start = { xyz = [0.66, 0.30, 0.03], yaw = 0 }",
        "start = { xyz = [1.30, 0.30, 0.03], yaw = 0 }",
    )
    assert far != text
    path = tmp_path / "far.toml"
    path.write_text(far)
    out = tmp_path / "trial"
    t0 = time.monotonic()
    proc = subprocess.run(
        [
            HRC,
            "run",
            str(path),
            "--out",
            str(out),
            "--no-reach-check",
            "--stall-timeout",
            "5",
            "--max-ticks",
            "20000",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    print(f"ended after {time.monotonic() - t0:.1f} s: {proc.stderr.strip().splitlines()[0]}")
    assert proc.returncode != 0
    # at once, naming the move: no robot holds with no way out (not even until the watchdog)
    assert "r1 cannot make its move #1 (to_pick RA1) to (1.300, 0.300" in proc.stderr
    assert "no way for it to go on, the trial ends at once" in proc.stderr
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["run"]["end_reason"] == "stalled" and not metrics["task"]["finished"]
    assert metrics["run"]["stall"].startswith("r1 cannot make its move #1")
    assert metrics["run"]["ticks"] < 5 * 240  # before the 5 s watchdog, far before the cap
    log_txt = (out / "log.txt").read_text()
    assert "r1 cannot make its move #1 (to_pick RA1)" in log_txt.splitlines()[-1]
    events = [json.loads(line) for line in (out / "events.jsonl").read_text().splitlines()]
    assert any(e.get("kind") == "STALLED" for e in events)


@pytest.mark.slow
def test_a_live_trial_whose_terminal_closes_ends_with_its_records(trial_factory) -> None:
    """The experimenter's terminal goes away (SIGHUP to the whole group, then every write to it
    fails): the console must not break the clean-up; the run ends as an interruption, with
    metrics.json, and nothing is left running."""
    trial = trial_factory(
        ROOT / "scenarios" / "minimal.toml", extra=["--input", "vr", "--vr-wait", "0"]
    )
    trial.wait_ticking()
    pids = trial.service_pids()
    assert len(pids) == 5, pids
    assert trial.proc.stdout is not None and trial.proc.stderr is not None
    trial.proc.stdout.close()  # nobody reads the terminal any more
    trial.proc.stderr.close()
    os.killpg(trial.proc.pid, signal.SIGHUP)
    try:
        code = trial.proc.wait(timeout=30)
    except subprocess.TimeoutExpired:
        pytest.fail("hrc run did not end after its terminal closed")
    assert code == 128 + signal.SIGHUP
    _assert_gone(pids)
    m = json.loads((trial.out / "metrics.json").read_text())
    assert "interrupted (SIGHUP)" in m["run"]["end_reason"], m["run"]
