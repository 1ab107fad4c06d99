"""`hrc ARGS...` for the tests that run many trials, each forked from this test process's warm
worker (hrc.study.warm), as a sweep's trials are: no trial pays a new interpreter's start (0.2-0.4
CPU-s). tests/test_sweep.py shows that a trial started so writes the files of a fresh `hrc
run`; the tests of the command itself (its start-up, its signals, its console script) run
the console script. Where the worker cannot start (or `HRC_SWEEP_START=exec`), each call is a
new interpreter, as in a sweep (hrc.study.trial.start)."""

from __future__ import annotations

import atexit
import subprocess
import sys
import threading

from hrc.study.trial import start, stop_process
from hrc.study.warm import WarmStarter, start_worker

_lock = threading.Lock()
_worker: list[WarmStarter | None] = []  # this process's, once asked for (None: there is none)


def _warm() -> WarmStarter | None:
    with _lock:
        if not _worker:
            _worker.append(start_worker())
            if _worker[0] is not None:
                atexit.register(_worker[0].close)
        return _worker[0]


def hrc(*args: str, timeout: float) -> subprocess.CompletedProcess[str]:
    """`hrc ARGS...` to its end (stdin empty, stdout and stderr kept): as subprocess.run would
    give it, TimeoutExpired past ``timeout`` (after stopping it and all it started)."""
    argv = [sys.executable, "-m", "hrc.cli.main", *args]
    proc = start(argv, _warm())
    try:
        out, err = proc.communicate(timeout=timeout)
    except BaseException:  # the timeout, or the test's own (as subprocess.run, it goes too)
        stop_process(proc)
        raise
    return subprocess.CompletedProcess(argv, proc.wait(), out, err)
