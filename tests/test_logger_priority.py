"""The logger's priority during a real lockstep run (services/logger/README.md, `--sched`).

In lockstep the clock waits for the observer's acks within a window, so the observer must get
some CPU whatever else the machine does: niceness, never SCHED_IDLE (beside one busy process
per core the SCHED_IDLE logger held the thesis run to 0.8x real time instead of 6.6x:
`hrc bench trial`, figure `busy`). Realtime runs keep SCHED_IDLE (the logger's unit tests).
"""

from __future__ import annotations

import os
import subprocess
import time
from pathlib import Path

import pytest

from hrc.priority import thread_ids

from .conftest import HRC, ROOT, SERVICE_MARKERS, _children, _cmdline

pytestmark = pytest.mark.skipif(not hasattr(os, "SCHED_IDLE"), reason="Linux scheduling")


def test_a_lockstep_runs_logger_is_lowered_by_niceness_never_to_sched_idle(tmp_path: Path) -> None:
    proc = subprocess.Popen(
        [HRC, "run", str(ROOT / "scenarios" / "minimal.toml"), "--out", str(tmp_path / "t")],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        stdin=subprocess.DEVNULL,
        text=True,
    )
    marker = SERVICE_MARKERS["logger"]
    seen_nice: set[int] = set()
    seen_idle: set[int] = set()  # threads seen under SCHED_IDLE
    deadline = time.monotonic() + 300
    while proc.poll() is None and time.monotonic() < deadline:
        for pid in _children(proc.pid):
            if marker not in _cmdline(pid):
                continue
            for tid in thread_ids(pid):
                try:
                    if os.sched_getscheduler(tid) == os.SCHED_IDLE:
                        seen_idle.add(tid)
                    seen_nice.add(os.getpriority(os.PRIO_PROCESS, tid))
                except OSError:  # the thread (or the logger) just ended
                    pass
        time.sleep(0.01)
    if proc.poll() is None:
        proc.kill()
    out = proc.communicate(timeout=60)[0]
    assert proc.returncode == 0, out
    base = os.getpriority(os.PRIO_PROCESS, 0)
    assert min(base + 10, 19) in seen_nice, (
        f"the logger's threads were never lowered by niceness 10 (seen: {sorted(seen_nice)})"
    )
    assert not seen_idle, f"{len(seen_idle)} logger thread(s) under SCHED_IDLE in a lockstep run"
