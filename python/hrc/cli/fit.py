"""``hrc fit``: each person's scripted-participant parameters from their recorded trials.

    hrc fit runs/studies/people                      # every participant with recordings
    hrc fit runs/studies/people --where conditions.anticipation=true
    hrc fit TRIAL_DIR TRIAL_DIR --participant L01     # trial folders of one person

A study folder (`hrc sweep` with `[study] record = true`, or `hrc session`) is read through its
table (`trials.csv`): ok trials whose folder holds `participant-input.jsonl`, grouped by
participant. The result goes to `fitted.toml` (`[fitted.<participant>]`, the keys of
`[participant]`), which a study uses as `participants.fitted`. Where the table has a simulated
participant's own parameters (`participant.<key>` columns), it also prints how well they were
recovered. The method: services/human_input/hrc_human_input/fit.py, docs/participant-model.md.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import sys
from pathlib import Path
from typing import Any

from hrc.study.trial import RECORDING_FILE
from hrc.tomlw import dumps

log = logging.getLogger(__name__)

TABLE_FILE = "trials.csv"
FITTED_FILE = "fitted.toml"
# the parameters whose recovery is reported (those a fit estimates)
RECOVERED = (
    "reaction_time_s",
    "peak_hand_speed",
    "fitts_a_s",
    "fitts_b_s",
    "fitts_c_s_per_m",
    "pick_dwell_s",
    "place_dwell_s",
    "grip_close_s",
    "grip_open_s",
)


def _match(value: Any, wanted: str) -> bool:
    if isinstance(value, float) and math.isnan(value):
        return wanted.lower() in ("", "none", "null", "nan")
    return str(value).lower() == wanted.lower()


def study_groups(folder: Path, where: list[tuple[str, str]]) -> tuple[dict[str, list[Path]], Any]:
    """participant -> their recorded ok trials' folders (table order), and the table."""
    import pandas as pd

    table = pd.read_csv(folder / TABLE_FILE)
    groups: dict[str, list[Path]] = {}
    for _, row in table.iterrows():
        if row.get("outcome") != "ok":
            continue
        if any(key not in row or not _match(row[key], value) for key, value in where):
            continue
        trial_dir = folder / "trials" / str(row["trial"])
        if (trial_dir / RECORDING_FILE).is_file():
            groups.setdefault(str(row["participant"]), []).append(trial_dir)
    return groups, table


def relative_errors(pairs: list[tuple[float, float]]) -> dict[str, float]:
    """Bias, mean and largest absolute error of (estimate - truth) / truth over (truth,
    estimate) pairs with a truth > 0 (empty if there is none)."""
    rel = [(est - true) / true for true, est in pairs if true > 0]
    if not rel:
        return {}
    return {
        "bias": round(sum(rel) / len(rel), 4),
        "mean_abs_error": round(sum(abs(r) for r in rel) / len(rel), 4),
        "max_abs_error": round(max(abs(r) for r in rel), 4),
    }


def recovery(table: Any, fitted: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """Per parameter: the simulated participants' true and fitted values, relative bias and
    mean absolute relative error (only parameters the table gives per participant)."""
    out: dict[str, Any] = {}
    for key in RECOVERED:
        column = f"participant.{key}"
        if column not in table.columns:
            continue
        pairs = []
        for who, params in sorted(fitted.items()):
            rows = table[table["participant"] == who]
            if rows.empty or key not in params:
                continue
            true = float(rows[column].iloc[0])
            if math.isnan(true) or true == 0.0:
                continue
            pairs.append((who, true, float(params[key])))
        if not pairs:
            continue
        out[key] = {
            "n": len(pairs),
            **relative_errors([(true, fit) for _w, true, fit in pairs]),
            "people": [{"participant": w, "true": t, "fitted": f} for w, t, f in pairs],
        }
    return out


def write_fitted(path: Path, fitted: dict[str, dict[str, Any]], info: dict[str, Any]) -> None:
    head = (
        "# hrc fit: each person's scripted-participant parameters, fitted to their recordings\n"
        "# (docs/participant-model.md). A study uses them as participants.fitted = <this file>.\n"
    )
    path.write_text(head + dumps({"fitted": fitted, "fit_info": info}), encoding="utf-8")


def run(args: argparse.Namespace) -> int:
    from hrc_human_input.fit import FitError, fit_folders

    folders = [Path(f) for f in args.folders]
    missing = [str(f) for f in folders if not f.is_dir()]
    if missing:
        print(f"hrc fit: no such folder: {', '.join(missing)}", file=sys.stderr)
        return 2
    where: list[tuple[str, str]] = []
    for item in args.where or []:
        key, sep, value = item.partition("=")
        if not sep or not key:
            print(f"hrc fit: --where wants KEY=VALUE, got {item!r}", file=sys.stderr)
            return 2
        where.append((key, value))
    table = None
    if len(folders) == 1 and (folders[0] / TABLE_FILE).is_file():
        groups, table = study_groups(folders[0], where)
        out = Path(args.out) if args.out else folders[0] / FITTED_FILE
        if not groups:
            print(
                f"hrc fit: {folders[0]}: no ok trial with a recording"
                + (" matches --where" if where else "")
                + " (record simulated trials with [study] record = true)",
                file=sys.stderr,
            )
            return 1
    else:
        if not args.participant:
            print("hrc fit: trial folders need --participant NAME", file=sys.stderr)
            return 2
        groups = {args.participant: folders}
        out = Path(args.out) if args.out else Path(FITTED_FILE)
    fitted: dict[str, dict[str, Any]] = {}
    info: dict[str, Any] = {}
    for who, trial_dirs in sorted(groups.items()):
        try:
            fit = fit_folders(trial_dirs)
        except (FitError, OSError, ValueError) as exc:
            print(f"hrc fit: {who}: {exc}", file=sys.stderr)
            return 1
        fitted[who] = fit.params
        info[who] = {"trials": [d.name for d in trial_dirs], **fit.counts, "notes": fit.notes}
    write_fitted(out, fitted, info)
    report: dict[str, Any] = {"fitted": fitted, "file": str(out)}
    if table is not None:
        rec = recovery(table, fitted)
        if rec:
            report["recovery"] = rec
    if args.json:
        print(json.dumps(report, indent=1))
        return 0
    for who, params in fitted.items():
        shown = ", ".join(f"{k} {v}" for k, v in params.items())
        print(f"{who} ({len(groups[who])} trials): {shown}")
        for note in info[who]["notes"]:
            print(f"  note: {note}")
    for key, r in report.get("recovery", {}).items():
        print(
            f"recovery {key}: n {r['n']}, bias {100 * r['bias']:+.1f} %, mean |error| "
            f"{100 * r['mean_abs_error']:.1f} %, max {100 * r['max_abs_error']:.1f} %"
        )
    print(f"written: {out}")
    return 0
