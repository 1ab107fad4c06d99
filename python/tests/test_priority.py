"""A process started in a session of its own keeps the niceness of whoever started it
(hrc.priority.carry_niceness): `nice hrc sweep` leaves the machine to everything else."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from hrc.priority import carry_niceness

# The starter runs at niceness 7, starts `sleep` in a session of its own (as hrc sweep starts
# each trial) and prints that session's autogroup line before and after carry_niceness.
STARTER = """
import subprocess
from hrc.priority import carry_niceness
child = subprocess.Popen(["sleep", "30"], start_new_session=True)
try:
    path = f"/proc/{child.pid}/autogroup"
    before = open(path).read().strip()
    carry_niceness(child.pid)
    print(before)
    print(open(path).read().strip())
finally:
    child.kill()
"""


# `nice -n 7` from this process's niceness (the whole test run may be nice already)
NICE = min(19, os.getpriority(os.PRIO_PROCESS, 0) + 7)


@pytest.mark.skipif(not Path("/proc/self/autogroup").exists(), reason="no autogroups here")
def test_a_trials_session_gets_the_niceness_of_whoever_started_it() -> None:
    out = subprocess.run(
        ["nice", "-n", "7", sys.executable, "-c", STARTER],
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    ).stdout.split("\n")
    # a new session's autogroup starts at nice 0 whatever its leader's niceness: the CPU is
    # shared out between sessions first, so the niceness alone would count for nothing
    assert out[0].endswith("nice 0"), out
    assert out[1].endswith(f"nice {NICE}"), out


def test_at_niceness_0_nothing_changes() -> None:
    child = subprocess.Popen(["sleep", "30"], start_new_session=True)
    try:
        carry_niceness(child.pid)  # no error, and no niceness given where there is none
        path = Path(f"/proc/{child.pid}/autogroup")
        if path.exists() and os.getpriority(os.PRIO_PROCESS, 0) == 0:
            assert path.read_text().strip().endswith("nice 0")
    finally:
        child.kill()


# As the sweep (hrc.study.trial.start) and the tests' `hrc` (tests/warm_cli.py) start a trial.
SWEEP_STARTER = """
from hrc.study.trial import start, stop_process
proc = start(["sleep", "30"], None)
try:
    print(open(f"/proc/{proc.pid}/autogroup").read().strip())
finally:
    stop_process(proc, grace_s=5)
"""


@pytest.mark.skipif(not Path("/proc/self/autogroup").exists(), reason="no autogroups here")
def test_a_sweeps_trial_gets_the_niceness_of_the_sweep() -> None:
    out = subprocess.run(
        ["nice", "-n", "7", sys.executable, "-c", SWEEP_STARTER],
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    ).stdout.strip()
    assert out.endswith(f"nice {NICE}"), out
