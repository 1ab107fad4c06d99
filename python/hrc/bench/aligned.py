"""``hrc bench aligned``: do the exchanges keep the timing of one-tick exchanges, over many
conditions? (docs/ARCHITECTURE.md, "Exchange step".)

Each variant (a shipped scenario under a safety policy, with or without provoked collisions) runs
twice with ``hrc run --no-view``: with its default exchanges, and with ``max_exchange_ticks = 1``.
The two must give the same events and cues at the same ticks, the same metrics and log lines
(``hrc.trial.aligned``: what the rules leave unaligned on purpose is left out). Prints a line per
variant: the exchanges and ticks of each run and the first differences; exits 1 if a variant is
not aligned. ``--n N``: the first N variants only (0: all, about 15 minutes on 2 cores).

A test runs one such pair (tests/test_event_aligned.py); this runs them all. The three
misalignments such runs found on 2026-12-02 (under ``ssm``, robots scanning at other periods and
a near-collision hold passed over on a scan's tick; under ``retreat_button``, the press seen at
its exchange's end) are fixed, each with a test of its own (bench/README.md).
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hrc.bench.trial import hrc_run, one_tick_toml
from hrc.bus.clock import exchange_counts
from hrc.paths import project_root
from hrc.trial.aligned import compare

POLICIES = ("retreat", "retreat_button", "stop_colliding", "ssm")
PROVOKE = "provoke_collisions = [3.0, 12.0]"
MAX_TICKS = 240 * 600  # ten simulated minutes: every shipped scenario ends long before


@dataclass(frozen=True)
class Variant:
    name: str
    scenario: str  # under scenarios/
    edits: tuple[tuple[str, str], ...]  # (old, new) text replacements, each must apply


def variants() -> list[Variant]:
    out = []
    policy = 'safety_policy = "retreat"'
    for scen, provokes in (("thesis", (False, True)), ("dense-4x4", (True,))):
        for p in POLICIES:
            for provoke in provokes:
                edits: list[tuple[str, str]] = [(policy, f'safety_policy = "{p}"')]
                if provoke:
                    edits.append(("provoke_collisions = false", PROVOKE))
                name = f"{scen}-{p}" + ("-provoked" if provoke else "")
                out.append(Variant(name, scen, tuple(edits)))
    out += [
        Variant(f"minimal-{p}", "minimal", ((policy, f'safety_policy = "{p}"'),)) for p in POLICIES
    ]
    for scen in ("thesis-ur5e", "thesis-panda"):
        for p in ("retreat", "ssm"):
            both = ((policy, f'safety_policy = "{p}"'), ("provoke_collisions = false", PROVOKE))
            out.append(Variant(f"{scen}-{p}-provoked", scen, both))
    # two robots whose separation sensors scan at other periods (7 and 12 ticks)
    out.append(
        Variant(
            "thesis-ssm-two-scan-periods",
            "thesis",
            (
                (policy, 'safety_policy = "ssm"'),
                ("provoke_collisions = false", PROVOKE),
                ("\n[robots.r2]\n", "\n[robots.r2.ssm]\nscan_period_s = 0.05\n\n[robots.r2]\n"),
            ),
        )
    )
    return out


def scenario_text(v: Variant, root: Path, one_tick: bool) -> str:
    text = (root / "scenarios" / f"{v.scenario}.toml").read_text()
    for old, new in v.edits:
        if old not in text:
            raise ValueError(f"{v.name}: {v.scenario}.toml has no {old!r}")
        text = text.replace(old, new, 1)
    return one_tick_toml(text, f"{v.scenario}.toml") if one_tick else text


def _run(scenario: Path, out: Path) -> tuple[int, int]:
    """``hrc run`` of ``scenario`` without the view: (ticks, exchanges)."""
    hrc_run(scenario, out, ["--no-view", "--max-ticks", str(MAX_TICKS)])
    counts = exchange_counts((out / "services" / "physics.log").read_text())
    if counts is None:
        raise RuntimeError(f"{out}: physics.log does not say its exchanges")
    return counts


def measure(v: Variant, root: Path, tmp: Path, pool: ThreadPoolExecutor) -> dict[str, Any]:
    # the scenario files sit in the project root's scenarios/ folder's stead: their relative
    # paths (robots/...) resolve against the project root
    runs = {}
    for one_tick in (False, True):
        tag = "one-tick" if one_tick else "default"
        path = tmp / f"{v.name}-{tag}.toml"
        path.write_text(scenario_text(v, root, one_tick))
        runs[tag] = (path, tmp / v.name / tag)
    futures = {tag: pool.submit(_run, path, out) for tag, (path, out) in runs.items()}
    counts = {tag: f.result() for tag, f in futures.items()}
    c = compare(runs["default"][1], runs["one-tick"][1])
    return {
        "variant": v.name,
        "ticks": counts["default"][0],
        "exchanges": counts["default"][1],
        "one_tick_exchanges": counts["one-tick"][1],
        "records": c.records,
        "aligned": c.aligned,
        "differences": [str(d) for d in c.differences],
    }


def run(args: argparse.Namespace) -> int:
    root = project_root()
    todo = variants()
    n = getattr(args, "n", 0)
    if n:
        todo = todo[:n]
    workers = max(1, min(4, os.cpu_count() or 1))
    results = []
    with (
        tempfile.TemporaryDirectory(prefix="hrc-bench-aligned-") as tmp,
        ThreadPoolExecutor(workers) as pool,
    ):
        # a variant's two runs side by side; variants one after another
        for v in todo:
            r = measure(v, root, Path(tmp), pool)
            results.append(r)
            if not getattr(args, "json", False):
                state = "aligned" if r["aligned"] else "NOT ALIGNED"
                print(
                    f"{r['variant']:32s} {r['ticks']:6d} ticks, {r['exchanges']:5d} exchanges "
                    f"(one-tick {r['one_tick_exchanges']}), {r['records']} records: {state}",
                    flush=True,
                )
                for d in r["differences"]:
                    print(f"    {d[:300]}", flush=True)
    bad = [r["variant"] for r in results if not r["aligned"]]
    if getattr(args, "json", False):
        print(json.dumps({"variants": results, "not_aligned": bad}))
    else:
        print(
            f"{len(results) - len(bad)} of {len(results)} variants aligned"
            + (f"; not: {', '.join(bad)}" if bad else "")
        )
    return 1 if bad else 0
