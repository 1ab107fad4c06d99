"""``hrc deploy-access``: the Zenoh credentials of a session started from ``deploy/`` (process-
compose or compose), as ``hrc run`` writes them for its own trials (``hrc.bus.access``).

It writes, into a folder only this user may enter, a random password for every service of the
table and for ``experimenter`` (the readiness probes, the tools), their dictionary, and one Zenoh
configuration file per name; each service is then started with ``--zenoh-config
<folder>/<service>.json5``. Physics, the router, checks every link against the dictionary and lets
only a key's own publisher put on it, exactly as in a trial of ``hrc run``. Run again, it writes
new passwords (the session's services must all be restarted with them).
"""

from __future__ import annotations

import argparse
import logging
import os
import stat
import sys
from pathlib import Path

from hrc import services
from hrc.bus.access import write_credentials

log = logging.getLogger(__name__)


def private_folder(path: Path) -> None:
    """``path`` made, or checked, as a folder of this user's that nobody else may enter
    (mode 0700). ValueError naming what is wrong."""
    path.mkdir(mode=0o700, parents=True, exist_ok=True)
    st = path.lstat()
    if not stat.S_ISDIR(st.st_mode):
        raise ValueError(f"{path} is not a folder")
    if st.st_uid != os.getuid():
        raise ValueError(f"{path} belongs to another user (uid {st.st_uid})")
    if stat.S_IMODE(st.st_mode) != 0o700:
        path.chmod(0o700)


def main(args: argparse.Namespace) -> int:
    folder = Path(args.out)
    try:
        private_folder(folder)
        write_credentials(folder, args.session, services.names())
    except (OSError, ValueError) as exc:
        print(f"hrc deploy-access: no credentials written: {exc}", file=sys.stderr)
        return 2
    print(
        f"credentials of session {args.session!r} for {', '.join(services.names())} and the "
        f"experimenter written to {folder}/ (mode 0700)"
    )
    return 0
