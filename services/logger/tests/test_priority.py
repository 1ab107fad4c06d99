"""The logger's CPU priority: every thread lowered once the run is on (zenoh's included),
the view's set-up spared, all back to normal for the catch-up after the run."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

# In a child process: the policy must not leak into the test runner.
CHILD = """
import json, os, threading
from hrc.priority import leave_idle
from hrc_logger.service import lower_priority
stop = threading.Event()
other = threading.Thread(target=stop.wait); other.start()
spared = threading.Thread(target=stop.wait); spared.start()
tids = {"main": threading.get_native_id(), "other": other.native_id, "spared": spared.native_id}
def policies():
    return {n: os.sched_getscheduler(t) for n, t in tids.items()}
before = policies()
lowered = lower_priority("idle", 10, {spared.native_id})
during = policies()
leave_idle()
after = policies()
stop.set()
print(json.dumps({"lowered": lowered, "before": before, "during": during, "after": after}))
"""


@pytest.mark.skipif(not hasattr(os, "SCHED_IDLE"), reason="Linux scheduling policies")
def test_every_thread_but_the_spared_one_goes_idle_and_comes_back() -> None:
    out = subprocess.run(
        [sys.executable, "-c", CHILD], capture_output=True, text=True, check=True, timeout=60
    ).stdout
    r = json.loads(out)
    normal, idle = os.SCHED_OTHER, os.SCHED_IDLE
    assert r["before"] == {"main": normal, "other": normal, "spared": normal}
    assert r["lowered"] is True
    assert r["during"] == {"main": idle, "other": idle, "spared": normal}
    assert r["after"] == {"main": normal, "other": normal, "spared": normal}
