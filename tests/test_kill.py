"""SIGKILL of any one service during a lockstep run ends the run promptly, naming it: within
2 s on a quiet machine; the test allows 4 s for a loaded one, still below every timeout a missed
death would fall back on (the 5 s the others get to leave, the 10 s barrier timeout)."""

from __future__ import annotations

import os
import signal
import time

import pytest


@pytest.mark.parametrize("victim", ["physics", "orchestrator", "ik_cpp", "human_input", "logger"])
def test_killing_a_service_ends_the_run_naming_it(trial_factory, victim: str) -> None:
    trial = trial_factory()
    trial.wait_ticking()
    pid = trial.service_pids()[victim]
    t0 = time.monotonic()
    os.kill(pid, signal.SIGKILL)
    code, _out, err = trial.communicate(timeout=30)
    elapsed = time.monotonic() - t0
    print(f"{victim}: run ended {elapsed:.2f} s after SIGKILL")
    assert code != 0
    assert f"'{victim}'" in err and "SIGKILL" in err, err
    assert elapsed < 4.0, f"took {elapsed:.2f} s"
