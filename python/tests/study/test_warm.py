"""The sweep's warm worker (hrc.study.warm): a trial forked from it runs as `hrc run` in a new
interpreter would (command line, stdout and stderr apart, exit code, a session of its own), and
a worker that ends mid-trial ends the trial with words that say so, never a wait."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hrc.study.warm import WarmError, WarmStarter

MAIN = [sys.executable, "-m", "hrc.cli.main"]


def _gone(pid: int, within_s: float) -> bool:
    """Has process ``pid`` ended (a zombie not yet reaped by its new parent counts)?"""
    deadline = time.monotonic() + within_s
    while time.monotonic() < deadline:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except (OSError, IndexError):
            return True
        if state == "Z":
            return True
        time.sleep(0.1)
    return False


def test_a_forked_command_has_its_own_output_exit_code_and_session(tmp_path: Path) -> None:
    with WarmStarter() as ws:
        # a scenario that does not exist: hrc run's own message on stderr, its exit code
        proc = ws.popen([*MAIN, "run", str(tmp_path / "nowhere.toml")])
        out, err = proc.communicate(timeout=60)
        fresh = subprocess.run(
            [*MAIN, "run", str(tmp_path / "nowhere.toml")], capture_output=True, text=True
        )
        assert proc.returncode == fresh.returncode != 0, (proc.returncode, err)
        assert err == fresh.stderr and out == fresh.stdout
        assert "nowhere.toml" in err
        # its own session (killpg stops it and all it started), not the worker's
        proc = ws.popen([*MAIN, "--help"])
        out, _ = proc.communicate(timeout=60)
        assert proc.returncode == 0 and "usage" in out
        assert proc.cpu_s > 0


def test_the_worker_runs_hrc_only(tmp_path: Path) -> None:
    with WarmStarter() as ws, pytest.raises(WarmError, match=r"hrc\.cli\.main only"):
        ws.popen([sys.executable, "-c", "print(1)"])


def test_a_worker_that_ends_mid_trial_ends_the_trial_and_says_so(tmp_path: Path) -> None:
    root = Path(__file__).resolve().parents[3]
    scenario = root / "scenarios" / "minimal.toml"
    with WarmStarter() as ws:
        # realtime: the trial takes ~10 s of wall time, long enough to kill its worker
        argv = [*MAIN, "run", str(scenario), "--out", str(tmp_path / "t"), "--mode", "realtime"]
        proc = ws.popen(argv)
        assert os.getpgid(proc.pid) == proc.pid  # a session leader, as start_new_session
        time.sleep(1.0)  # it has started (not waiting on anything: a worker can die any time)
        os.kill(ws._proc.pid, signal.SIGKILL)
        t0 = time.monotonic()
        _out, err = proc.communicate(timeout=60)
        assert time.monotonic() - t0 < 30
        assert proc.returncode != 0
        assert "warm worker ended during the trial" in err
        # hrc run follows its parent (the worker): it stops its services and leaves
        assert _gone(proc.pid, 30), f"hrc run {proc.pid} outlived its warm worker"
        assert not ws.alive()
