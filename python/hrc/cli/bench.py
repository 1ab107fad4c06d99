"""``hrc bench``: benchmarks that print their figures (never asserted in tests)."""

from __future__ import annotations

import argparse


def main(args: argparse.Namespace) -> int:
    if args.what == "bus":
        from hrc.cli.bench_bus import run as run_bus

        return run_bus(args)
    raise SystemExit(f"hrc bench {args.what}: not available yet")
