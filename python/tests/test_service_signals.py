"""SIGTERM or SIGINT to a service ends its run through the role's stop() and never hangs it,
whenever the signal comes: also while the main thread holds the role's lock (the handler runs
on the main thread, between two of its bytecodes). A logger SIGTERMed mid-trial hung so until
it was killed (tests/test_logger_bus.py, 2026-12-01)."""

from __future__ import annotations

import subprocess
import sys
import textwrap

# A role whose stop() takes a plain lock, as LockstepParticipant's does; the main thread holds
# that lock when the signal comes, and lets go of it only after the handler has returned.
SCRIPT = textwrap.dedent(
    """
    import os, signal, sys, threading, time
    from hrc.service import _stop_on_signals

    class Role:
        def __init__(self):
            self.lock = threading.Lock()
            self.stopped = threading.Event()
            self.reason = ""

        def stop(self, reason):
            with self.lock:
                self.reason = reason
                self.stopped.set()

    role = Role()
    _stop_on_signals(role)
    with role.lock:
        os.kill(os.getpid(), signal.SIGTERM)
        for _ in range(1000):  # bytecodes: the handler runs here, the lock held
            pass
        print("handler returned", flush=True)
    ok = role.stopped.wait(10)
    print(f"stopped: {ok} {role.reason}", flush=True)
    os._exit(0 if ok else 3)  # before the grace timer ends the process
    """
)


def test_a_stop_signal_while_the_main_thread_holds_the_roles_lock_still_stops_it() -> None:
    try:
        proc = subprocess.run(
            [sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=30
        )
    except subprocess.TimeoutExpired as exc:
        raise AssertionError(f"the service hung on SIGTERM: {exc.stdout!r}") from None
    assert proc.returncode == 0, (proc.returncode, proc.stdout, proc.stderr[-2000:])
    assert proc.stdout.splitlines() == [
        "handler returned",
        "stopped: True terminated by SIGTERM",
    ], proc.stdout
