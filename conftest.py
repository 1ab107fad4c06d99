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
"""

from __future__ import annotations

import os

import pytest

# Modules whose tests take minutes (pytest --durations on 2 cores), longest first.
LONGEST_FIRST = (
    "tests/test_live_trial.py",
    "tests/test_headset_view.py",
    "tests/test_fit_recovery.py",
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
PHASES = ("alone", "beside", "parallel")


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
        keep: list[pytest.Item] = []
        dropped: list[pytest.Item] = []
        for it in items:
            module = _module(it)
            its = "alone" if module in ALONE else "beside" if module in BESIDE else "parallel"
            (keep if its == phase else dropped).append(it)
        if dropped:
            config.hook.pytest_deselected(items=dropped)
        items[:] = keep
    items.sort(key=_rank)  # stable: a module's tests keep their order
