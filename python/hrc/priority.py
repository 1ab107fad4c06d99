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


class CpuListError(ValueError):
    """A CPU list that names no CPU this process may use, or is not a list."""


def parse_cpus(text: str) -> set[int]:
    """The CPUs of a list as taskset and /proc/*/status write it ("0", "0-3", "0,2,5-7"), each
    one this process may run on (os.sched_getaffinity)."""
    cpus: set[int] = set()
    for part in text.split(","):
        lo, sep, hi = part.strip().partition("-")
        try:
            first, last = int(lo), int(hi) if sep else int(lo)
        except ValueError:
            raise CpuListError(f"--cpus {text!r}: not a CPU list (e.g. 0, 0-3 or 0,2)") from None
        if first < 0 or last < first:
            raise CpuListError(f"--cpus {text!r}: {part.strip()!r} is not a CPU range")
        cpus.update(range(first, last + 1))
    allowed = os.sched_getaffinity(0)
    if not cpus <= allowed:
        raise CpuListError(
            f"--cpus {text!r}: CPU {min(cpus - allowed)} is not one this process may use "
            f"(it may use {format_cpus(allowed)})"
        )
    return cpus


def format_cpus(cpus: Collection[int]) -> str:
    """The list form parse_cpus reads ("0-3,6")."""
    out: list[str] = []
    for c in sorted(cpus):
        if out and out[-1].split("-")[-1] == str(c - 1):
            out[-1] = f"{out[-1].split('-')[0]}-{c}"
        else:
            out.append(str(c))
    return ",".join(out)


def cpu_slots(workers: int) -> list[set[int]] | None:
    """The CPUs this process may use, cut into ``workers`` sets as even as they go, one for
    each of a study's parallel trials; None where there is nothing to cut (one worker, or more
    workers than CPUs). A lockstep trial mostly hands the turn from process to process: on one
    CPU each hand-over is a local wake-up, while spread over all, its processes wake each
    other across CPUs (an interrupt between the CPUs each time, a VM exit on a virtual machine)
    and the two trials' processes crowd each other's caches (bench/README.md, "Trials on
    their own CPUs": two thesis trials at once on 2 cores, a fifth less wall time). Only on a
    machine that runs nothing else: beside other work a trial held to one CPU waits for it
    (`hrc sweep --pin` is not the default)."""
    cpus = sorted(os.sched_getaffinity(0))
    if workers < 2 or workers > len(cpus):
        return None
    n = len(cpus)
    return [set(cpus[i * n // workers : (i + 1) * n // workers]) for i in range(workers)]
