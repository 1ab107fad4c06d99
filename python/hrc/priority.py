"""Scheduling policy per thread (on Linux policy and niceness belong to each thread, not to the
process): the logger lowers itself to SCHED_IDLE during a run, and it, or whoever stops it,
lifts it again. A process started in a session of its own keeps the niceness of whoever
started it (`carry_niceness`)."""

from __future__ import annotations

import logging
import os
from collections.abc import Collection

log = logging.getLogger(__name__)


def thread_ids(pid: int | None = None, exclude: Collection[int] = ()) -> list[int]:
    """The threads of process ``pid`` (None: this one) but ``exclude``, from /proc. Where that
    is not known: for this process [0] (the calling thread), for another none."""
    where = "self" if pid is None else str(pid)
    try:
        tids = [int(t) for t in os.listdir(f"/proc/{where}/task")]
    except (OSError, ValueError):
        return [0] if pid is None else []
    return [t for t in tids if t not in exclude]


def leave_idle(pid: int | None = None) -> None:
    """Every SCHED_IDLE thread of process ``pid`` (None: this one) back to the normal policy:
    under SCHED_IDLE a thread gets no CPU while anything else wants it, not even to act on a
    stop."""
    if not hasattr(os, "SCHED_IDLE"):
        return
    for tid in thread_ids(pid):
        try:
            if os.sched_getscheduler(tid) == os.SCHED_IDLE:
                os.sched_setscheduler(tid, os.SCHED_OTHER, os.sched_param(0))
        except ProcessLookupError:
            pass  # a thread (or the process) that just ended
        except OSError as exc:
            log.debug("thread %d stays under SCHED_IDLE: %s", tid, exc)


def carry_niceness(pid: int) -> None:
    """Gives the session that process ``pid`` leads (started with ``start_new_session``) this
    process's niceness. With Linux's autogroups (on by default) the CPU is first shared out
    between sessions, each as one, and a niceness counts only within its own session: a trial
    started in a session of its own by `nice hrc sweep` would otherwise take as much CPU as
    anything else on the machine. No-op at niceness 0 or where autogroups are off."""
    nice = os.getpriority(os.PRIO_PROCESS, 0)
    if nice <= 0:
        return
    try:
        with open(f"/proc/{pid}/autogroup", "w") as f:
            f.write(str(nice))
    except OSError as exc:  # no autogroups, or the process already gone
        log.debug("session of %d keeps its niceness: %s", pid, exc)
