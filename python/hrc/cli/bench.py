"""``hrc bench``: benchmarks that print their figures (never asserted in tests)."""

from __future__ import annotations

import argparse
import importlib

_MODULES = {
    "bus": "hrc.cli.bench_bus",
    "physics": "hrc.cli.bench_physics",
    "ik": "hrc.cli.bench_ik",
    "client": "hrc.cli.bench_client",
    "trial": "hrc.cli.bench_trial",
    "participant": "hrc.cli.bench_participant",
    "fit": "hrc.cli.bench_fit",
}


def main(args: argparse.Namespace) -> int:
    module = importlib.import_module(_MODULES[args.what])
    return int(module.run(args))
