"""``hrc bench ik``: the C++ IK benchmark ``hrc-ik-bench`` (services/ik_cpp/kin/bench/README.md).

10,000 random reachable targets per chain (arm5, UR5, Panda; fixed seed) for the service's solver,
KDL NR_JL, KDL LMA and the thesis's gradient descent, plus the 1 kHz two-arm tick figure. This
module only runs the binary and passes its output through: a table, or with ``--json`` one JSON
object ``{"chains": {CHAIN: {SOLVER: {"success", "mean_us", "p99_us", ...}}}, "tick_p99_us": x}``.
``--urdf FILE --base LINK --tip LINK`` benchmarks that chain alone (a lab's own arm: 1,000
targets by default, no tick figure: ``tick_p99_us`` null).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

from hrc.paths import ik_bench_binary, project_root
from hrc.scenario import ScenarioError, load


def shipped_chains(root: Path) -> list[str]:
    """``NAME=URDF:BASE:TIP`` of every robot description the shipped scenarios use besides the
    benchmark's own three (the real arms: scenarios/thesis-panda.toml, thesis-ur5e.toml), named
    after the URDF file, with its folder in front when the name is taken (franka_panda/panda:
    pybullet's Panda, beside the benchmark's kinematic stand-in panda)."""
    own = {root / "robots" / f"{n}.urdf" for n in ("arm5", "ur5", "panda")}
    chains: dict[tuple[str, str, str], str] = {}
    for path in sorted((root / "scenarios").glob("*.toml")):
        try:
            s = load(path, root, motion_check=False)
        except ScenarioError:
            continue  # hrc validate names it; the benchmark runs what it can
        for rid, robot in s.robots.items():
            urdf = s.urdf_path(rid)
            if urdf is None or urdf in own:
                continue
            key = (str(urdf), robot.base_link, robot.tip_link)
            taken = {"arm5", "ur5", "panda", *chains.values()}
            name = urdf.stem if urdf.stem not in taken else f"{urdf.parent.name}/{urdf.stem}"
            chains.setdefault(key, name)
    return [f"{name}={u}:{b}:{t}" for (u, b, t), name in chains.items()]


USER_N = 1000  # targets for a lab's own chain (--urdf) by default: seconds, not minutes
USER_GD_N = 100  # of them for the gradient descent (about 14 ms a target on a 7-DOF arm)


class BenchInputError(ValueError):
    """A bad --urdf/--base/--tip, named before the benchmark starts."""


def user_chain(args: argparse.Namespace) -> str:
    """``NAME=URDF:BASE:TIP`` for ``--urdf FILE --base LINK --tip LINK``, checked first: the
    file a URDF (xacro said so), both links in it, a chain of joints from one to the other."""
    from hrc.scenario import urdf

    if not args.base or not args.tip:
        raise BenchInputError("--urdf needs --base LINK and --tip LINK (the chain to benchmark)")
    path = Path(args.urdf).expanduser().resolve()
    try:
        info = urdf.read_urdf(path)
    except urdf.UrdfError as exc:
        raise BenchInputError(str(exc)) from exc
    for flag, link in (("--base", args.base), ("--tip", args.tip)):
        if link not in info.links:
            raise BenchInputError(
                f"{flag}: {path.name} has no link named {link!r}; its links: "
                + ", ".join(info.links)
            )
    if info.chain(args.base, args.tip) is None:
        raise BenchInputError(
            f"--tip: {args.tip!r} is not below {args.base!r} in {path.name}: no chain of joints "
            "leads from one to the other"
        )
    if ":" in str(path) or "=" in path.stem:
        raise BenchInputError(f"--urdf: {path}: a path with ':' or '=' cannot be passed on")
    return f"{path.stem}={path}:{args.base}:{args.tip}"


def bench_argv(args: argparse.Namespace) -> list[str]:
    """The command line of the benchmark for ``hrc bench ik`` arguments (``json``, ``n``, and
    ``urdf``/``base``/``tip`` for a lab's own chain alone)."""
    root = project_root()
    argv = [str(ik_bench_binary())]
    if getattr(args, "urdf", None):
        argv += ["--only", "--chain", user_chain(args)]
        n = getattr(args, "n", 0) or USER_N
        argv += ["--n", str(n), "--gd-n", str(min(n, USER_GD_N))]
    else:
        argv += ["--robots-dir", str(root / "robots")]
        for chain in shipped_chains(root):
            argv += ["--chain", chain]
        if getattr(args, "n", 0):
            argv += ["--n", str(args.n)]  # the (slow) gradient descent runs on min(n, 1000)
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
    if (getattr(args, "base", None) or getattr(args, "tip", None)) and not getattr(
        args, "urdf", None
    ):
        print("--base and --tip go with --urdf FILE", file=sys.stderr)
        return 2
    try:
        argv = bench_argv(args)
    except BenchInputError as exc:
        print(f"hrc bench ik: {exc}", file=sys.stderr)
        return 2
    # The benchmark's progress lines go to stderr (passed through); its result to stdout.
    proc = subprocess.run(argv, stdout=subprocess.PIPE, text=True, check=False)
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
