"""A process started in a session of its own keeps the niceness of whoever started it
(hrc.priority.carry_niceness): `nice hrc sweep` leaves the machine to everything else."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from hrc.priority import CpuListError, carry_niceness, cpu_slots, format_cpus, parse_cpus

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


# ------------------------------------------------------------------ CPUs (hrc run --cpus)
def test_a_cpu_list_reads_as_taskset_writes_it_and_back() -> None:
    allowed = os.sched_getaffinity(0)
    one = min(allowed)
    assert parse_cpus(str(one)) == {one}
    assert parse_cpus(format_cpus(allowed)) == allowed
    assert format_cpus({0, 1, 2, 5, 7, 8}) == "0-2,5,7-8"


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("x", "not a CPU list"),
        ("", "not a CPU list"),
        ("1-0", "'1-0' is not a CPU range"),
        ("4096", "CPU 4096 is not one this process may use"),
    ],
)
def test_a_bad_cpu_list_is_refused_naming_what_is_wrong(text: str, says: str) -> None:
    with pytest.raises(CpuListError, match=says):
        parse_cpus(text)


def test_the_cpus_are_cut_into_one_set_per_worker_when_there_are_enough() -> None:
    cpus = sorted(os.sched_getaffinity(0))
    assert cpu_slots(1) is None  # a lone trial keeps them all
    assert cpu_slots(len(cpus) + 1) is None  # more trials than CPUs: they share
    if len(cpus) < 2:
        pytest.skip("one CPU")
    slots = cpu_slots(2)
    assert slots is not None and len(slots) == 2
    assert slots[0].isdisjoint(slots[1]) and slots[0] | slots[1] == set(cpus)
    assert abs(len(slots[0]) - len(slots[1])) <= 1


def test_hrc_run_refuses_cpus_it_may_not_use_and_starts_nothing(tmp_path: Path) -> None:
    out = tmp_path / "trial"
    run = subprocess.run(
        [sys.executable, "-m", "hrc.cli.main", "run", "scenarios/minimal.toml", "--out", str(out),
         "--cpus", "4096"],
        capture_output=True, text=True, timeout=60, cwd=Path(__file__).resolve().parents[2],
    )  # fmt: skip
    assert run.returncode == 2, run.stderr
    assert "--cpus '4096': CPU 4096 is not one this process may use" in run.stderr
    assert "nothing was started" in run.stderr
    assert not out.exists()
