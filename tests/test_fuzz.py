"""A condition and layout fuzz test: variants of scenarios/thesis.toml of the kind a study makes
(speeds, anticipation, all three safety policies, provoked collisions, caution, reaction time,
seeds, target shifts, robot base shifts up to 10 cm). Every variant is either rejected by
`hrc validate` with its reasons or finishes; none stalls, none reaches the tick cap.

`HRC_FUZZ_N` sets the number of variants (default 32), `HRC_FUZZ_SEED` the generator's seed,
`HRC_FUZZ_ONLY` (e.g. "6,16") runs only those variants. Two variants run at a time.
"""

from __future__ import annotations

import copy
import json
import math
import os
import random
import subprocess
import tomllib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from .conftest import HRC, ROOT

N_VARIANTS = int(os.environ.get("HRC_FUZZ_N", "32"))
GENERATOR_SEED = int(os.environ.get("HRC_FUZZ_SEED", "12"))
ONLY = [int(x) for x in os.environ.get("HRC_FUZZ_ONLY", "").split(",") if x.strip()]
MAX_TICKS = 150_000  # 625 s of simulated time at 240 Hz: a safety cap, never reached by a pass
RUN_TIMEOUT_S = 900
POLICIES = ("retreat", "retreat_button", "stop_colliding")


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


def variants(n: int, seed: int) -> list[tuple[str, dict[str, Any]]]:
    base = tomllib.loads((ROOT / "scenarios" / "thesis.toml").read_text())
    rng = random.Random(seed)
    out: list[tuple[str, dict[str, Any]]] = []
    for i in range(n):
        doc = copy.deepcopy(base)
        what: list[str] = []
        doc["scenario"]["seed"] = rng.randrange(1, 10_000)
        for robot in doc["robots"].values():
            robot["max_tcp_speed"] = rng.choice([0.15, 0.25, 0.5, 0.8, 1.2, 1.5])
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
        out.append((f"v{i:02d}: " + "; ".join(what), doc))
    return out


# ---------------------------------------------------------------- running one
@dataclass
class Outcome:
    name: str
    verdict: str  # "rejected" | "finished" | "FAILED"
    detail: str = ""


def run_variant(name: str, doc: dict[str, Any], folder: Path) -> Outcome:
    folder.mkdir(parents=True)
    path = folder / "scenario.toml"
    path.write_text(dump_toml(doc))
    v = subprocess.run([HRC, "validate", str(path)], capture_output=True, text=True, timeout=300)
    if v.returncode != 0:
        reasons = v.stderr.strip()
        if v.returncode != 1 or not reasons:
            return Outcome(name, "FAILED", f"hrc validate exited {v.returncode}: {reasons}")
        return Outcome(name, "rejected", reasons.splitlines()[0])
    try:
        r = subprocess.run(
            [HRC, "run", str(path), "--out", str(folder / "trial"), "--max-ticks", str(MAX_TICKS)],
            capture_output=True,
            text=True,
            timeout=RUN_TIMEOUT_S,
        )
    except subprocess.TimeoutExpired:
        return Outcome(name, "FAILED", f"hrc run still going after {RUN_TIMEOUT_S} s")
    metrics_file = folder / "trial" / "metrics.json"
    metrics = json.loads(metrics_file.read_text()) if metrics_file.exists() else {}
    run = metrics.get("run") or {}
    if r.returncode != 0:
        return Outcome(name, "FAILED", f"exit {r.returncode}: {r.stderr.strip()[-600:]}")
    if not metrics.get("task", {}).get("finished"):
        return Outcome(
            name,
            "FAILED",
            f"the task did not finish ({run.get('end_reason')}, "
            f"{run.get('ticks')} ticks: the cap?)",
        )
    return Outcome(name, "finished", f"{metrics['task']['completion_s']:.1f} s task time")


@pytest.mark.slow
@pytest.mark.e2e
@pytest.mark.timeout(7200)
def test_every_variant_is_rejected_or_finishes(tmp_path: Path, ik_bin: Path) -> None:
    todo = variants(N_VARIANTS, GENERATOR_SEED)
    assert len({doc["conditions"]["safety_policy"] for _n, doc in todo}) == 3

    def one(i: int) -> Outcome:
        o = run_variant(todo[i][0], todo[i][1], tmp_path / f"v{i:02d}")
        print(f"[{o.verdict}] {o.name}: {o.detail}", flush=True)  # progress, with -s
        return o

    with ThreadPoolExecutor(max_workers=2) as pool:  # two cores: two trials at a time
        outcomes = list(pool.map(one, ONLY or range(len(todo))))
    counts = {k: sum(o.verdict == k for o in outcomes) for k in ("rejected", "finished", "FAILED")}
    for o in outcomes:
        print(f"{o.verdict:<9} {o.name}\n          {o.detail}")
    print(
        f"fuzz: {len(outcomes)} variants: {counts['finished']} finished, "
        f"{counts['rejected']} rejected by hrc validate, {counts['FAILED']} failed"
    )
    failed = [o for o in outcomes if o.verdict == "FAILED"]
    assert not failed, "\n".join(f"{o.name}: {o.detail}" for o in failed)
