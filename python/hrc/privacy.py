"""Participant data is private by default: who may read what hrc and its services write.

Trial, study and session folders hold human-subject records (metrics, events, recordings,
answers). Every process of the project (``hrc`` and each Python service) sets its file-creation
mask at start, so each folder it makes is mode 0700 and each file 0600: only the user who ran
it reads them. A lab whose members share a Unix group sets ``HRC_DATA_ACCESS=group``: folders
0750 and files 0640, readable by the group, never by other users. The mask is inherited by
everything a process starts (the services of a trial, the C++ one included).

What the mask cannot cover is a folder that already exists: :func:`exposed` says when an output
folder is open to other users, and the commands that write participant data warn about it.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

ENV = "HRC_DATA_ACCESS"
# the file-creation mask of each setting: "private" keeps everything to the user
UMASKS = {"private": 0o077, "group": 0o027}
DEFAULT = "private"


def setting() -> str:
    """The setting asked for (``HRC_DATA_ACCESS``, default private); ValueError naming the
    variable and its values if it holds something else."""
    value = os.environ.get(ENV, "").strip().lower() or DEFAULT
    if value not in UMASKS:
        raise ValueError(
            f"{ENV}={os.environ.get(ENV)!r}: use one of {', '.join(sorted(UMASKS))} "
            f"(default {DEFAULT}: only you read trial data; group: your Unix group too)"
        )
    return value


def apply() -> str:
    """Sets this process's file-creation mask from :func:`setting` (and so that of every
    process it starts); returns the setting."""
    value = setting()
    os.umask(UMASKS[value])
    return value


def exposed(folder: Path) -> str | None:
    """Why participant data written into ``folder`` would be open to other users, or None:
    the folder exists and others may list or enter it (a folder hrc makes is private)."""
    try:
        st = folder.stat()
    except OSError:
        return None  # made by hrc with the mask: private
    mode = stat.S_IMODE(st.st_mode)
    if not stat.S_ISDIR(st.st_mode) or not mode & 0o007:
        return None
    return (
        f"{folder} is open to other users (mode {mode:04o}): participant data in it may be "
        f"read by them; make it private with `chmod o-rwx {folder}` (files hrc writes there "
        f"are private anyway, {ENV})"
    )
