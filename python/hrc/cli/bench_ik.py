"""``hrc bench ik``: the C++ IK benchmark ``hrc-ik-bench`` (services/ik_cpp/kin/bench/README.md).

10,000 random reachable targets per chain (arm5, UR5, Panda; fixed seed) for the service's solver,
KDL NR_JL, KDL LMA and the thesis's gradient descent, plus the 1 kHz two-arm tick figure. This
module only runs the binary and passes its output through: a table, or with ``--json`` one JSON
object ``{"chains": {CHAIN: {SOLVER: {"success", "mean_us", "p99_us", ...}}}, "tick_p99_us": x}``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

from hrc.paths import ik_bench_binary, project_root


def bench_argv(args: argparse.Namespace) -> list[str]:
    """The command line of the benchmark for ``hrc bench ik`` arguments (``json``, ``n``)."""
    argv = [str(ik_bench_binary()), "--robots-dir", str(project_root() / "robots")]
    if getattr(args, "n", 0):
        argv += ["--n", str(args.n)]  # the (slow) gradient descent runs on min(n, 1000) of them
    if getattr(args, "json", False):
        argv.append("--json")
    return argv


def run(args: argparse.Namespace) -> int:
    binary = ik_bench_binary()
    if not binary.exists():
        print(f"{binary} is missing: build services/ik_cpp (scripts/setup.sh)", file=sys.stderr)
        return 2
    if getattr(args, "n", 0) < 0:
        print(f"--n must be >= 0, got {args.n}", file=sys.stderr)
        return 2
    # The benchmark's progress lines go to stderr (passed through); its result to stdout.
    proc = subprocess.run(bench_argv(args), stdout=subprocess.PIPE, text=True, check=False)
    if proc.returncode != 0:
        print(f"{binary.name} failed with exit code {proc.returncode}", file=sys.stderr)
        sys.stdout.write(proc.stdout)
        return proc.returncode
    out = proc.stdout
    if getattr(args, "json", False):
        try:
            json.loads(out)  # one JSON object, as documented; anything else is a broken build
        except json.JSONDecodeError as exc:
            print(f"{binary.name} --json printed no valid JSON: {exc}", file=sys.stderr)
            sys.stdout.write(out)
            return 1
    sys.stdout.write(out)
    return 0
