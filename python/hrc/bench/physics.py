"""``hrc bench physics``: the physics service's own bench, ``python -m hrc_physics.bench``
(services/physics/README.md), run as a process: the library never imports a service.

It prints a table, or with ``--json`` one JSON object ``{"us_per_tick": x}``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

from hrc import service_table


def bench_argv(args: argparse.Namespace) -> list[str]:
    """The command line of the bench for ``hrc bench physics`` arguments (``json``, ``n``)."""
    argv = [sys.executable, "-m", f"{service_table.service('physics').module}.bench"]
    if getattr(args, "n", 0):
        argv += ["--n", str(args.n)]
    if getattr(args, "json", False):
        argv.append("--json")
    return argv


def run(args: argparse.Namespace) -> int:
    if getattr(args, "n", 0) < 0:
        print(f"--n must be >= 0, got {args.n}", file=sys.stderr)
        return 2
    proc = subprocess.run(bench_argv(args), stdout=subprocess.PIPE, text=True, check=False)
    sys.stdout.write(proc.stdout)
    if proc.returncode != 0:
        print(f"the physics bench failed with exit code {proc.returncode}", file=sys.stderr)
        return proc.returncode
    if getattr(args, "json", False):
        try:
            json.loads(proc.stdout)  # one JSON object, as documented
        except json.JSONDecodeError as exc:
            print(f"the physics bench printed no valid JSON: {exc}", file=sys.stderr)
            return 1
    return 0
