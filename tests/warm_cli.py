"""`hrc ARGS...` for the tests that run many trials, each forked from this test process's warm
worker (hrc.study.warm), as a sweep's trials are: no trial pays a new interpreter's start (0.2-0.4
CPU-s). tests/test_sweep.py shows that a trial started so writes the files of a fresh `hrc
run`; the tests of the command itself (its start-up, its signals, its console script) run
the console script."""

from __future__ import annotations

import atexit
import subprocess
import sys
import threading
from pathlib import Path

from hrc.study.trial import stop_process
from hrc.study.warm import WarmError, WarmStarter

# the console script (tests import it from conftest)
HRC = str(Path(sys.executable).with_name("hrc"))

_lock = threading.Lock()
_starter: WarmStarter | None = None
_failed = False  # the worker could not start here: the console script from then on


def _warm() -> WarmStarter | None:
    global _starter, _failed
    with _lock:
        if _failed:
            return None
        if _starter is None or not _starter.alive():
            try:
                _starter = WarmStarter()
            except (WarmError, OSError) as exc:
                print(f"warm worker unavailable ({exc}): hrc runs as its console script")
                _failed = True
                return None
            atexit.register(_starter.close)
        return _starter


def hrc(
    *args: str, timeout: float, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess[str]:
    """`hrc ARGS...` to its end (stdin empty, stdout and stderr kept): as subprocess.run would
    give it, TimeoutExpired past ``timeout`` (after stopping it and all it started)."""
    starter = _warm()
    argv = [sys.executable, "-m", "hrc.cli.main", *args]
    try:
        if starter is None:
            raise WarmError("no warm worker here")
        proc = starter.popen(argv, env=env)
    except WarmError:
        return subprocess.run(
            [HRC, *args],
            capture_output=True,
            text=True,
            timeout=timeout,
            stdin=subprocess.DEVNULL,
            env=env,
        )
    try:
        out, err = proc.communicate(timeout=timeout)
    except BaseException:  # the timeout, or the test's own (as subprocess.run, it goes too)
        stop_process(proc)
        raise
    return subprocess.CompletedProcess(argv, proc.wait(), out, err)
