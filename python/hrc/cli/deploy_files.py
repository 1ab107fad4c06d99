"""``hrc deploy-files``: write ``deploy/process-compose.yaml`` and ``deploy/compose.yaml`` from the
service table (rendered by ``hrc.deploy_files``); ``--check`` only says whether the committed
files are current."""

from __future__ import annotations

import argparse
import sys

from hrc.deploy_files import files
from hrc.paths import project_root


def main(args: argparse.Namespace) -> int:
    stale = []
    for path, text in files(project_root()).items():
        current = path.read_text() if path.exists() else None
        if current == text:
            continue
        stale.append(path)
        if not args.check:
            path.write_text(text)
            print(f"wrote {path}")
    if args.check and stale:
        names = ", ".join(str(p) for p in stale)
        print(
            f"out of date with the service table: {names} (run `hrc deploy-files`)", file=sys.stderr
        )
        return 1
    if not stale:
        print("deploy files are up to date")
    return 0
