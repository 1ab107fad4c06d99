"""``hrc deploy-access``: the Zenoh credentials of a session started from ``deploy/`` (process-
compose or compose), as ``hrc run`` writes them for its own trials (``hrc.bus.access``).

It writes, into a folder only this user may enter, a random password for every service of the
table and for ``experimenter`` (the readiness probes, the tools), their dictionary, and one Zenoh
configuration file per name; each service is then started with ``--zenoh-config
<folder>/<service>.json5``. Physics, the router, checks every link against the dictionary and lets
only a key's own publisher put on it, exactly as in a trial of ``hrc run``. ``router.json5`` does
the same for a separate router (``hrc router --config <folder>/router.json5``) when the services
are spread over several hosts (docs/multi-host.md). Run again, it writes new passwords (the
session's services must all be restarted with them).

Every file but the logger's sets Zenoh's link lease to ``--lease-s`` (default 0.5 s; Zenoh's own
is 10 s): a host whose cable is pulled is gone for the router within it, and physics ends the run
naming a service on it a second later (docs/multi-host.md).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hrc import service_table
from hrc.bus.access import make_private, write_credentials


def main(args: argparse.Namespace) -> int:
    folder = Path(args.out)
    try:
        make_private(folder, parents=True)
        write_credentials(
            folder, args.session, service_table.names(), router=True, lease_s=args.lease_s
        )
    except (OSError, ValueError) as exc:
        print(f"hrc deploy-access: no credentials written: {exc}", file=sys.stderr)
        return 2
    print(
        f"credentials of session {args.session!r} for {', '.join(service_table.names())} and the "
        f"experimenter, and a router's configuration, written to {folder}/ (mode 0700)"
    )
    return 0
