"""Free space where trials write: ``hrc run`` and ``hrc sweep`` warn before they start."""

from __future__ import annotations

import shutil
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
