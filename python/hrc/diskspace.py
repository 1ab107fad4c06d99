"""Free space where trials write: ``hrc run`` and ``hrc sweep`` warn before they start."""

from __future__ import annotations

import contextlib
import os
import shutil
import threading
from pathlib import Path

# What one trial writes, for the warning: a thesis trial about 2.5 MB, a live one of ten minutes
# some 30 MB; the margin covers longer runs and a rerun web viewer's recording.
TRIAL_MB = 100
# A simulated trial of a sweep (a scripted participant): the thesis trial about 2.5 MB, the
# minimal one 0.63 MB (bench/README.md, "Many trials on one machine"); four times the thesis's.
SIMULATED_TRIAL_MB = 10
NO_SPACE = "No space left on device"  # strerror(ENOSPC), as a service's log shows it


def low_space(folder: Path, trials: int = 1, trial_mb: int = TRIAL_MB) -> str | None:
    """A warning when the file system of ``folder`` (or its nearest existing parent) has less
    free than ``trials`` trials of ``trial_mb`` need; None when there is enough (or it cannot be
    told)."""
    probe = folder
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    try:
        free = shutil.disk_usage(probe).free
    except OSError:
        return None
    need_mb = trial_mb * max(1, trials)
    if free >= need_mb * 1024**2:
        return None
    what = "a trial writes" if trials <= 1 else f"{trials} trials write"
    return (
        f"only {free / 1024**2:.1f} MiB free on {probe}: {what} up to about {need_mb} MiB, "
        "and a full disk ends a trial"
    )


# A trial's last files (metrics.json, the logs' closing lines, the end of the recording, hrc
# run's figures) need room when the disk is full: a file of this size is kept aside in the
# trial folder from the start and given back when the run is stopped for want of space.
RESERVE_BYTES = 512 * 1024
# Below this much free (beside the reserve), the run is stopped: a thesis trial writes about
# 50 KB per simulated second, but the recording goes out in bursts (rerun's chunks, the logger's
# series every 5 simulated seconds: some 250 KB), and the services go on for a moment after the
# stop is asked for.
LOW_BYTES = 1024 * 1024
# The least free space a trial starts with: its reserve, the margin, and 1 MiB to run on.
START_BYTES = RESERVE_BYTES + LOW_BYTES + 1024 * 1024
RESERVE_FILE = ".space-reserve"


def _mib(n: float) -> str:
    return f"{n / 1024**2:.1f} MiB"


class SpaceGuard:
    """The disk of one trial folder: checked before the start, watched during the run, with
    room kept aside for the last files (docs/access.md, "A full disk")."""

    CHECK_S = 0.05

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.reserve = folder / RESERVE_FILE
        self.released = False
        self.full: str | None = None  # why the disk reached its margin, once it has
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def watch(self) -> None:
        """Checks the disk every CHECK_S on a thread of its own, through the run and the
        services' last writes: at the margin it gives the reserve back and sets :attr:`full`
        (the caller ends the run). Start it after the services are forked."""

        def loop() -> None:
            while not self._stop.wait(self.CHECK_S):
                if (why := self.low()) is not None:
                    self.full = why
                    self.release()
                    return

        self._thread = threading.Thread(target=loop, name="space-guard", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)

    def start(self) -> str | None:
        """Refuses a folder with too little room (why, naming the figures), else keeps the
        reserve aside; None when the trial may start."""
        free = self.free()
        if free is not None and free < START_BYTES:
            return (
                f"only {_mib(free)} free on {self.folder}: a trial needs at least "
                f"{_mib(START_BYTES)} to start ({_mib(RESERVE_BYTES)} of it kept aside for "
                "its last files; a thesis trial writes about 2.5 MB)"
            )
        try:
            fd = os.open(self.reserve, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
            try:
                os.posix_fallocate(fd, 0, RESERVE_BYTES)
            finally:
                os.close(fd)
        except OSError as exc:
            self.release()
            return f"cannot keep room aside on {self.folder}: {exc.strerror}"
        return None

    def free(self) -> int | None:
        try:
            return shutil.disk_usage(self.folder).free
        except OSError:
            return None

    def low(self) -> str | None:
        """Why the run must stop now (the disk is all but full), or None. Called often: one
        statvfs."""
        if self.released:
            return None
        free = self.free()
        if free is None or free >= LOW_BYTES:
            return None
        return (
            f"no space left on {self.folder} ({free // 1024} KiB free): the trial was stopped "
            f"and its last files written in the room kept aside"
        )

    def release(self) -> None:
        """Gives the reserve back (at the stop, and at the end of every trial)."""
        self.released = True
        with contextlib.suppress(OSError):
            self.reserve.unlink()
