"""A condition and layout fuzz test: variants of the kind a study makes, of scenarios/thesis.toml
and of the dense layout scenarios/dense-4x4.toml. What the thesis names as parameters is varied:
object counts (parts dropped; a screw whose host part is dropped goes too), the placement order
(each agent's sequence shuffled: an order that deadlocks must be refused by `hrc validate`,
naming the cycle), all four safety policies, robot speeds 0.1-1.5 m/s; and with them
anticipation, provoked collisions, caution, reaction time, seeds, target shifts, robot bases
shifted up to 10 cm and the screwing robot's feeder up to 5 cm. Every variant is either refused
by `hrc validate` with its reasons or finishes; none stalls, none fails, none reaches the tick
cap (issue 24: everything validate accepts must finish).

The test runs a fixed set of the generator's variants (seed 12): v00-v07, which cover each safety
policy on each base layout, and v16 (every agent's order shuffled, four parts dropped: with v06,
the variants this file's docs named to run again), plus
one fresh variant drawn from a new generator seed at each run (its seed and index are printed:
`HRC_FUZZ_SEED=S HRC_FUZZ_ONLY=I` runs it again). `HRC_FUZZ_N=32` (or more) runs the first N
variants instead, as the test did before; `HRC_FUZZ_SEED` sets the generator's seed,
`HRC_FUZZ_ONLY` (e.g. "6,16") runs only those variants. Each variant is a test of its own
(`test_a_variant_is_refused_or_finishes[v06]`, `[fresh]`), so that parallel workers share them;
each prints its verdict (finished / refused / stalled / failed) and why.
"""

from __future__ import annotations

import copy
import json
import math
import os
import random
import re
import subprocess
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from .conftest import ROOT
from .warm_cli import hrc

N_VARIANTS = int(os.environ.get("HRC_FUZZ_N", "0"))  # 0: the fixed set and a fresh one
GENERATOR_SEED = int(os.environ.get("HRC_FUZZ_SEED", "12"))
ONLY = [int(x) for x in os.environ.get("HRC_FUZZ_ONLY", "").split(",") if x.strip()]
# v00-v07: each policy on each base; v16: shuffled orders, parts dropped
FIXED = [*range(8), 16]
GENERATED = 32  # the fixed set's indices are of the first GENERATED variants
MAX_TICKS = 150_000  # 625 s of simulated time at 240 Hz: a safety cap, never reached by a pass
RUN_TIMEOUT_S = 900
POLICIES = ("retreat", "retreat_button", "stop_colliding", "ssm")
BASES = ("thesis", "dense-4x4")


# ---------------------------------------------------------------- a small TOML writer
def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int | float):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {v!r}")


def _table(header: str, body: dict[str, Any]) -> list[str]:
    lines = [header]
    lines += [f"{k} = {_value(v)}" for k, v in body.items()]
    return [*lines, ""]


def dump_toml(doc: dict[str, Any]) -> str:
    """The scenario subset of TOML: tables of scalars, lists and inline tables, `robots.<id>`
    tables and the `[[parts]]` array."""
    lines: list[str] = []
    for key, value in doc.items():
        if key == "robots":
            for rid, robot in value.items():
                lines += _table(f"[robots.{rid}]", robot)
        elif key == "parts":
            for part in value:
                lines += _table("[[parts]]", part)
        else:
            lines += _table(f"[{key}]", value)
    return "\n".join(lines)


# ---------------------------------------------------------------- the variants
def _shift(xyz: list[float], dx: float, dy: float) -> list[float]:
    return [round(xyz[0] + dx, 4), round(xyz[1] + dy, 4), xyz[2]]


def _drop_parts(doc: dict[str, Any], rng: random.Random) -> list[str]:
    """Drops up to two of the human's and of the transport robot's parts; a screw whose host
    part is dropped goes too (its `after` names the host); `after` lists forget dropped parts."""
    parts = doc["parts"]
    hosts = [p["id"] for p in parts if p["owner"] in ("human", "r1")]
    dropped = set(rng.sample(hosts, rng.randint(1, 4)))
    dropped |= {p["id"] for p in parts if p["owner"] == "r2" and set(p.get("after", [])) & dropped}
    doc["parts"] = [p for p in parts if p["id"] not in dropped]
    for part in doc["parts"]:
        if "after" in part:
            part["after"] = [a for a in part["after"] if a not in dropped]
            if not part["after"]:
                del part["after"]
    for agent, seq in doc["sequence"].items():
        doc["sequence"][agent] = [x for x in seq if x not in dropped]
    return sorted(dropped)


def variants(n: int, seed: int) -> list[tuple[str, dict[str, Any]]]:
    bases = {
        name: tomllib.loads((ROOT / "scenarios" / f"{name}.toml").read_text()) for name in BASES
    }
    rng = random.Random(seed)
    out: list[tuple[str, dict[str, Any]]] = []
    for i in range(n):
        base = BASES[(i // len(POLICIES)) % len(BASES)]
        doc = copy.deepcopy(bases[base])
        what: list[str] = [base]
        doc["scenario"]["seed"] = rng.randrange(1, 10_000)
        for robot in doc["robots"].values():
            robot["max_tcp_speed"] = round(rng.uniform(0.1, 1.5), 2)
        cond = doc["conditions"]
        cond["anticipation"] = rng.random() < 0.5
        cond["safety_policy"] = POLICIES[i % len(POLICIES)]
        p = doc["participant"]
        p["provoke_collisions"] = rng.choice([False, 0.3, 1.0])
        p["caution"] = rng.choice([0.0, 0.5, 1.0])
        p["reaction_time_s"] = round(rng.uniform(0.25, 0.7), 2)
        what.append(
            f"seed {doc['scenario']['seed']}, speeds "
            + "/".join(str(r["max_tcp_speed"]) for r in doc["robots"].values())
            + f", {cond['safety_policy']}, anticipation {cond['anticipation']}, provoke "
            f"{p['provoke_collisions']}, caution {p['caution']}, rt "
            f"{p['reaction_time_s']}"
        )
        if rng.random() < 0.3:
            what.append("without " + ",".join(_drop_parts(doc, rng)))
        if rng.random() < 0.3:  # a new placement order for each agent
            for agent in sorted(doc["sequence"]):
                rng.shuffle(doc["sequence"][agent])
            what.append("orders " + " / ".join(",".join(q) for q in doc["sequence"].values()))
        if rng.random() < 0.4:  # every target by the same few cm: screws stay on their hosts
            dx, dy = round(rng.uniform(-0.03, 0.03), 3), round(rng.uniform(-0.03, 0.03), 3)
            for part in doc["parts"]:
                part["target"]["xyz"] = _shift(part["target"]["xyz"], dx, dy)
            what.append(f"targets +({dx}, {dy})")
        if rng.random() < 0.4:
            for rid, robot in doc["robots"].items():
                r = rng.uniform(0.0, 0.10)
                a = rng.uniform(0.0, 2.0 * math.pi)
                dx, dy = round(r * math.cos(a), 3), round(r * math.sin(a), 3)
                robot["base"]["xyz"] = _shift(robot["base"]["xyz"], dx, dy)
                what.append(f"{rid} base +({dx}, {dy})")
        if rng.random() < 0.3:
            for rid, robot in doc["robots"].items():
                if "feeder" in robot:
                    dx, dy = round(rng.uniform(-0.05, 0.05), 3), round(rng.uniform(-0.05, 0.05), 3)
                    robot["feeder"] = _shift(robot["feeder"], dx, dy)
                    what.append(f"{rid} feeder +({dx}, {dy})")
        out.append((f"v{i:02d}: " + "; ".join(what), doc))
    return out


def chosen_variants() -> list[tuple[str, str, dict[str, Any]]]:
    """What the tests run, as (test id, name, scenario): HRC_FUZZ_ONLY's variants, or
    HRC_FUZZ_N's first N, or the fixed set and one fresh variant (named with the seed and index
    that give it again; its test id is `fresh`, the same in every worker that collects it)."""
    if ONLY or N_VARIANTS:
        made = variants(max([N_VARIANTS, *(i + 1 for i in ONLY)]), GENERATOR_SEED)
        picked = [made[i] for i in ONLY] if ONLY else made
        return [(name.split(":")[0], name, doc) for name, doc in picked]
    made = variants(GENERATED, GENERATOR_SEED)
    fresh_seed = random.SystemRandom().randrange(10**6)
    fresh_i = fresh_seed % GENERATED
    name, doc = variants(GENERATED, fresh_seed)[fresh_i]
    fresh = ("fresh", f"fresh (HRC_FUZZ_SEED={fresh_seed} HRC_FUZZ_ONLY={fresh_i}) {name}", doc)
    return [*((f"v{i:02d}", *made[i]) for i in FIXED), fresh]


CHOSEN = chosen_variants()


# ---------------------------------------------------------------- running one
VERDICTS = ("finished", "refused", "stalled", "failed")


@dataclass
class Outcome:
    name: str
    verdict: str  # one of VERDICTS
    detail: str = ""


def run_variant(name: str, doc: dict[str, Any], folder: Path) -> Outcome:
    folder.mkdir(parents=True)
    path = folder / "scenario.toml"
    path.write_text(dump_toml(doc))
    v = hrc("validate", str(path), timeout=300)
    if v.returncode != 0:
        reasons = v.stderr.strip()
        if v.returncode != 1 or not reasons:
            return Outcome(name, "failed", f"hrc validate exited {v.returncode}: {reasons}")
        return Outcome(name, "refused", reasons.splitlines()[0])
    try:
        # (no 3D recording: what is checked is how the trial ends, and it costs a tenth)
        trial = str(folder / "trial")
        r = hrc("run", str(path), "--out", trial, "--max-ticks", str(MAX_TICKS), "--no-view",
                timeout=RUN_TIMEOUT_S)  # fmt: skip
    except subprocess.TimeoutExpired:
        return Outcome(name, "failed", f"hrc run still going after {RUN_TIMEOUT_S} s")
    metrics_file = folder / "trial" / "metrics.json"
    metrics = json.loads(metrics_file.read_text()) if metrics_file.exists() else {}
    run = metrics.get("run") or {}
    if run.get("end_reason") == "stalled":
        return Outcome(name, "stalled", str(run.get("stall")))
    if r.returncode != 0:
        return Outcome(name, "failed", f"exit {r.returncode}: {r.stderr.strip()[-600:]}")
    if not metrics.get("task", {}).get("finished"):
        return Outcome(
            name,
            "failed",
            f"the task did not finish ({run.get('end_reason')}, "
            f"{run.get('ticks')} ticks: the cap?)",
        )
    return Outcome(name, "finished", f"{metrics['task']['completion_s']:.1f} s task time")


@pytest.mark.skipif(bool(ONLY), reason="HRC_FUZZ_ONLY runs the variants it names")
def test_the_variants_vary_every_policy_and_base() -> None:
    assert len({doc["conditions"]["safety_policy"] for _i, _n, doc in CHOSEN}) == len(POLICIES)
    assert len({n.split(":")[1].split(";")[0].strip() for _i, n, _d in CHOSEN}) == len(BASES)


@pytest.mark.slow
@pytest.mark.e2e
@pytest.mark.timeout(RUN_TIMEOUT_S + 300)
@pytest.mark.parametrize("index", range(len(CHOSEN)), ids=[c[0] for c in CHOSEN])
def test_a_variant_is_refused_or_finishes(index: int, tmp_path: Path, ik_bin: Path) -> None:
    _id, name, doc = CHOSEN[index]
    o = run_variant(name, doc, tmp_path / "variant")
    print(f"{o.verdict:<9} {o.name}\n          {o.detail}")
    assert o.verdict in ("finished", "refused"), f"{o.verdict}: {o.name}: {o.detail}"
    # a deadlocking order is refused naming its cycle ("H5 before RA6 (RA6.after); RA6 before
    # RA3 (sequence.r1); ...; so none of H5, RA6, RA3 can ever be done"); only a new order can
    # deadlock the shipped layouts
    if o.verdict == "refused" and "deadlock" in o.detail:
        assert "orders" in o.name, o.name
        assert re.search(r"\w+ before \w+ \(", o.detail), o.detail
        assert "can ever be done" in o.detail, o.detail
