"""The test session's order and its two phases (scripts/test-all.sh).

- Order: the longest modules first, so that in parallel workers (pytest-xdist, one test at a
  time) the short tests fill the gaps at the end instead of one long test running alone while
  the other worker idles. The order changes no test: each is independent.
- Phases: `HRC_TEST_PHASE=alone` keeps only the tests that must not share the machine with
  another test: live trials paced by the wall clock with a browser page in software WebGL (a
  page a few frames a second late, a realtime trial that misses its deadlines, and the test
  reads a person's view of something else). `HRC_TEST_PHASE=beside` keeps the tests that mostly
  wait for a timeout (a watchdog, a lease, a lost message's deadline): they take little CPU and
  run at the same time as the `alone` phase, which leaves a core partly idle (in a worker of
  their own they left it idle too). `HRC_TEST_PHASE=parallel` keeps the rest, which run in
  parallel workers: lockstep trials give the same results at any load. Unset: every test.
- `HRC_TEST_PHASE=fill` takes the parallel phase's tests (but `NOT_FILL`) from its end (the
  shortest first), one at a time, while the live trials run (at nice 15: it takes only the CPU
  they and the waiting tests leave idle), until the file `HRC_TEST_FILL_STOP` names exists: each
  test it starts is listed in the file `HRC_TEST_FILL_LIST` names (under a lock, so that a test
  is started here or listed for the parallel phase, never both nor neither), and the parallel
  phase, given the same `HRC_TEST_FILL_LIST`, leaves those out.
"""

from __future__ import annotations

import fcntl
import os
from pathlib import Path

import pytest

# Modules whose tests take minutes (pytest --durations on 2 cores), longest first. The mixed
# session design (a minute of realtime trials, left to the parallel phase: NOT_FILL) was handed
# out last among the e2e tests and ran alone at the phase's end, the other worker idle.
LONGEST_FIRST = (
    "tests/test_live_trial.py",
    "tests/test_headset_view.py",
    "tests/test_fit_recovery.py",
    "tests/test_session_design.py",
    "tests/test_fuzz.py",
    "tests/test_session.py",
    "tests/test_every_trial_finishes.py",
    "tests/test_real_robots.py",
    "tests/test_faults.py",
    "tests/test_participant_client.py",
)
# Live trials with a browser page: run one at a time, alone (HRC_TEST_PHASE=alone).
ALONE = (
    "tests/test_live_trial.py",
    "tests/test_headset_view.py",
    "tests/test_session.py",
    "tests/test_participant_client.py",
    "tests/test_rerun_web_view.py",
    "tests/test_participant_zone.py",
    "tests/test_vr_stream.py",
    "tests/test_real_robot_page.py",
    "tests/test_vr_physics.py",
    "tests/test_human_input_vr.py",
)
# Tests that mostly wait for a timeout or for real time (measured 2026-11-30 in the parallel
# phase: 300 s of a worker's time at 5-30 % of a core): run beside the alone phase
# (HRC_TEST_PHASE=beside).
BESIDE = (
    "tests/test_faults.py",
    "python/tests/bus/test_clock.py",
    "python/tests/bus/test_access.py",
    "python/tests/bus/test_replay.py",
    "tests/test_intruders.py",
    "services/human_input/tests/test_vr_bridge.py",
)
# Tests the fill phase leaves to the parallel phase: at nice 15 beside a live trial drawing
# pictures they get a few percent of a core, and these hold a wall-clock bound of seconds (a run
# ended within 4 s of a kill, 2 s of a cut link) or run a realtime trial or a live session at
# that niceness (2026-12-02: test_kill took 4.8 s, a session's realtime trial failed)
NOT_FILL = (
    "tests/test_abort.py",
    "tests/test_full_disk.py",
    "tests/test_kill.py",
    "tests/test_multi_host.py",
    "tests/test_nohang_run.py",
    "tests/test_session_design.py",
    "tests/test_session_console.py",
    "tests/test_deploy_session.py",
    "tests/test_backbone_run.py",
    "deploy/tests/test_deploy_files.py",
    "python/tests/bus/test_config.py",
    "python/tests/test_runner.py",
    "python/tests/study/test_warm.py",
)
PHASES = ("alone", "beside", "parallel", "fill")
FILL_STOP = "HRC_TEST_FILL_STOP"  # a file: once it exists, the fill phase starts no more tests
FILL_LIST = "HRC_TEST_FILL_LIST"  # a file: the tests the fill phase started, a node id a line
_STOPPED = pytest.StashKey[bool]()  # the fill phase found the stop file: it starts nothing more


def _module(item: pytest.Item) -> str:
    return item.nodeid.split("::", 1)[0]


def _rank(item: pytest.Item) -> tuple[int, int]:
    path = _module(item)
    if path in LONGEST_FIRST:
        return (0, LONGEST_FIRST.index(path))
    if item.get_closest_marker("e2e") is not None:
        return (1, 0)
    if item.get_closest_marker("slow") is not None:
        return (2, 0)
    return (3, 0)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    phase = os.environ.get("HRC_TEST_PHASE", "")
    if phase:
        if phase not in PHASES:
            raise pytest.UsageError(f"HRC_TEST_PHASE: one of {', '.join(PHASES)} (got {phase!r})")
        if phase == "fill" and not (os.environ.get(FILL_STOP) and os.environ.get(FILL_LIST)):
            raise pytest.UsageError(f"HRC_TEST_PHASE=fill needs {FILL_STOP} and {FILL_LIST}")
        filled = _filled() if phase == "parallel" else set()
        keep: list[pytest.Item] = []
        dropped: list[pytest.Item] = []
        for it in items:
            module = _module(it)
            its = "alone" if module in ALONE else "beside" if module in BESIDE else "parallel"
            if its == "parallel" and phase == "fill" and module not in NOT_FILL:
                its = "fill"
            ok = its == phase and it.nodeid not in filled
            (keep if ok else dropped).append(it)
        if dropped:
            config.hook.pytest_deselected(items=dropped)
        items[:] = keep
    items.sort(key=_rank)  # stable: a module's tests keep their order
    if phase == "fill":
        items.reverse()  # the shortest first: the one under way when the live trials end is short


def _filled() -> set[str]:
    """The tests the fill phase started (none without HRC_TEST_FILL_LIST)."""
    path = os.environ.get(FILL_LIST)
    if not path or not Path(path).exists():
        return set()
    return set(Path(path).read_text().splitlines())


def _claim(nodeid: str) -> bool:
    """Fill phase: lists the test as started here, unless the stop file exists (then False)."""
    with open(os.environ[FILL_LIST], "a") as f:
        fcntl.flock(f, fcntl.LOCK_EX)  # scripts/test-all.sh creates the stop file under it
        if os.path.exists(os.environ[FILL_STOP]):
            return False
        f.write(nodeid + "\n")
        f.flush()
        return True


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> bool | None:
    """Fill phase: a test not claimed is not run here (nor reported: the parallel phase runs
    it)."""
    if os.environ.get("HRC_TEST_PHASE") != "fill":
        return None
    if item.config.stash.get(_STOPPED, False) or not _claim(item.nodeid):
        item.config.stash[_STOPPED] = True
        return True
    return None


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    if os.environ.get("HRC_TEST_PHASE") == "fill":
        n = len(_filled())
        terminalreporter.write_line(
            f"fill: {n} tests run here while the live trials ran; the rest in the parallel phase"
        )
