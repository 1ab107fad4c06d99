"""``hrc bench fit``: how well ``hrc fit`` recovers known parameters, and how well a fitted twin
predicts its person in a condition it was not fitted on (docs/participant-model.md).

1. `studies/recovery.toml`: 20 simulated people with known, varied parameters, each recorded in
   two trials (robots at 0.5 m/s), run with `hrc sweep`.
2. Recovery: each person fitted on both trials; per parameter, the bias and the mean and largest
   absolute relative error against the person's true value.
3. Prediction: the same people in a condition the fit did not see (robots at 1.0 m/s), and
   their twins (`participants.fitted`: the fitted parameters) in it; the twins' human completion
   and idle times against the people's.

``--n N`` fits the first N people of the 20 (the same people, the same draws: a smaller run of
the same bench, as the test does). ``--json`` prints ``{"recovery": {PARAM: {"n", "bias",
"mean_abs_error", "max_abs_error", ...}}, "prediction": {METRIC: {...}}, "trials": N,
"wall_s": S}``.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
import tomllib
from pathlib import Path
from typing import Any

from hrc.participant.fitted import relative_errors
from hrc.paths import project_root
from hrc.study.spec import Study
from hrc.tomlw import dumps

RECOVERY_STUDY = "studies/recovery.toml"
PREDICTED = ("human.completion_s", "human.idle_s")
CONDITION = "robots.*.max_tcp_speed"
HELD_OUT = 1.0  # m/s: the condition the twins predict


def _fit_all(folder: Path, where: list[tuple[str, str]]) -> tuple[dict[str, dict[str, Any]], Any]:
    from hrc.participant.fit import fit_folders
    from hrc.participant.fitted import study_groups

    groups, table = study_groups(folder, where)
    return {who: fit_folders(dirs).params for who, dirs in sorted(groups.items())}, table


def _held_out_studies(study: Study, fitted_file: Path, out: Path) -> tuple[Path, Path]:
    """The recovery study's people, and their twins, in the held-out condition (one trial each):
    two study files written into ``out``."""
    raw = tomllib.loads(study.text)
    raw["study"].update(scenario=str(study.scenario), repetitions=1, record=False)
    raw["factors"] = {CONDITION: [HELD_OUT]}
    people = out / "held-out.toml"
    people.write_text(dumps({**raw, "study": {**raw["study"], "name": "held-out"}}))
    fixed = {k: v for k, v in raw["participants"].items() if not isinstance(v, dict)}
    twins = out / "twins.toml"
    twins.write_text(
        dumps(
            {
                "study": {**raw["study"], "name": "twins"},
                "factors": raw["factors"],
                "participants": {**fixed, "n": 0, "seed_base": 9000, "fitted": str(fitted_file)},
            }
        )
    )
    return people, twins


def prediction(held_out: Any, twins: Any) -> dict[str, Any]:
    """Per metric: each twin's value against its person's in the held-out condition: mean
    absolute error in seconds, and relative bias and errors over the people with a value > 0."""
    out: dict[str, Any] = {}
    for metric in PREDICTED:
        pairs = []
        for _, twin in twins.iterrows():
            who = str(twin["participant"]).removesuffix("-twin")
            row = held_out[held_out["participant"] == who]
            if row.empty or twin.get("outcome") != "ok" or row["outcome"].iloc[0] != "ok":
                continue
            pairs.append((who, float(row[metric].iloc[0]), float(twin[metric])))
        if not pairs:
            continue
        r: dict[str, Any] = {
            "n": len(pairs),
            "mean_abs_error_s": round(sum(abs(p - t) for _w, t, p in pairs) / len(pairs), 3),
        }
        r.update(relative_errors([(t, p) for _w, t, p in pairs]))
        r["people"] = [{"participant": w, "actual": t, "twin": p} for w, t, p in pairs]
        out[metric] = r
    return out


def _recovery_study(out: Path, people: int) -> Path:
    """`studies/recovery.toml`, or a copy of it with only its first ``people`` people (their
    parameters are drawn per person from the seed base, so they are the same people)."""
    path = project_root() / RECOVERY_STUDY
    if not people:
        return path
    raw = tomllib.loads(path.read_text(encoding="utf-8"))
    if not 0 < people <= raw["participants"]["n"]:
        raise ValueError(f"--n: between 1 and {raw['participants']['n']} people (got {people})")
    raw["participants"]["n"] = people
    raw["study"]["scenario"] = str((path.parent / raw["study"]["scenario"]).resolve())
    out.mkdir(parents=True, exist_ok=True)
    smaller = out / "recovery.toml"
    smaller.write_text(dumps(raw))
    return smaller


def bench(out: Path, workers: int = 2, people: int = 0) -> dict[str, Any]:
    """The bench in folder ``out``; ``people`` (0: all of them) keeps the study's first ones."""
    import pandas as pd

    from hrc.participant.fitted import recovery, write_fitted
    from hrc.study.spec import load_study
    from hrc.study.sweep import sweep

    t0 = time.monotonic()
    study = load_study(_recovery_study(out, people))
    people_dir = out / "people"
    # the fit reads the participant's input and the events: no 3D recording is kept
    records = sweep(study, people_dir, workers=workers, view=False)
    fitted, table = _fit_all(people_dir, [])
    fitted_file = people_dir / "fitted.toml"
    write_fitted(fitted_file, fitted, {})
    report: dict[str, Any] = {"trials": len(records)}
    report["recovery"] = recovery(table, fitted)
    # prediction: the people and their twins in the held-out condition
    held_file, twin_file = _held_out_studies(study, fitted_file, out)
    for name, path in (("held-out", held_file), ("twins", twin_file)):
        more = sweep(load_study(path), out / name, workers=workers, view=False)
        records += more
        report["trials"] += len(more)
    report["failed"] = [r.trial for r in records if r.outcome != "ok"]
    report["prediction"] = prediction(
        pd.read_csv(out / "held-out" / "trials.csv"), pd.read_csv(out / "twins" / "trials.csv")
    )
    report["wall_s"] = round(time.monotonic() - t0, 1)
    return report


def _summary(report: dict[str, Any]) -> str:
    lines = [f"{report['trials']} trials ({len(report['failed'])} failed), {report['wall_s']} s"]
    for key, r in report["recovery"].items():
        bias, mae, worst = (100 * r[k] for k in ("bias", "mean_abs_error", "max_abs_error"))
        lines.append(
            f"recovery   {key:<16} n {r['n']:>2}  bias {bias:+6.1f} %  "
            f"mean |error| {mae:5.1f} %  max {worst:5.1f} %"
        )
    for key, r in report["prediction"].items():
        rel = (
            f"  bias {100 * r['bias']:+6.1f} %  mean |error| {100 * r['mean_abs_error']:5.1f} %"
            f"  max {100 * r['max_abs_error']:5.1f} %"
            if "bias" in r
            else ""
        )
        lines.append(
            f"prediction {key:<18} n {r['n']:>2}  mean |error| {r['mean_abs_error_s']:.2f} s{rel}"
        )
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    with tempfile.TemporaryDirectory(prefix="hrc-bench-fit-") as tmp:
        try:
            report = bench(Path(tmp), people=args.n)
        except Exception as exc:
            print(f"fit bench failed: {exc}", file=sys.stderr)
            return 1
    print(json.dumps(report, indent=1) if getattr(args, "json", False) else _summary(report))
    return 0 if not report["failed"] else 1
