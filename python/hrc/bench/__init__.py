"""``hrc bench``: benchmarks that print their figures (never asserted in tests)."""

from __future__ import annotations

import argparse
import importlib

_MODULES = {
    "bus": "hrc.bench.bus",
    "physics": "hrc.bench.physics",
    "ik": "hrc.bench.ik",
    "client": "hrc.bench.client",
    "trial": "hrc.bench.trial",
    "participant": "hrc.bench.participant",
    "fit": "hrc.bench.fit",
    "aligned": "hrc.bench.aligned",
}


def main(args: argparse.Namespace) -> int:
    module = importlib.import_module(_MODULES[args.what])
    return int(module.run(args))
