"""``hrc fit``: each person's scripted-participant parameters from their recorded trials.

    hrc fit runs/studies/people                      # every participant with recordings
    hrc fit runs/studies/people --where conditions.anticipation=true
    hrc fit TRIAL_DIR TRIAL_DIR --participant L01     # trial folders of one person

A study folder (`hrc sweep` with `[study] record = true`, or `hrc session`) is read through its
table (`trials.csv`): ok trials whose folder holds `participant-input.jsonl`, grouped by
participant. The result goes to `fitted.toml` (`[fitted.<participant>]`, the keys of
`[participant]`), which a study uses as `participants.fitted`. Where the table has a simulated
participant's own parameters (`participant.<key>` columns), it also prints how well they were
recovered. The method: hrc.participant.fit, docs/participant-model.md.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from hrc.participant.fitted import FITTED_FILE, TABLE_FILE, recovery, study_groups, write_fitted


def run(args: argparse.Namespace) -> int:
    from hrc.participant.fit import FitError, fit_folders

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
    refused: dict[str, str] = {}
    for who, trial_dirs in sorted(groups.items()):
        try:
            fit = fit_folders(trial_dirs)
        except (FitError, OSError, ValueError) as exc:
            # one person's unusable recordings do not cost the others their fit
            print(f"hrc fit: {who}: not fitted: {exc}", file=sys.stderr)
            refused[who] = str(exc)
            continue
        fitted[who] = fit.params
        info[who] = {
            "trials": [d.name for d in trial_dirs],
            **fit.counts,
            "uncertainty": fit.uncertainty,
            "notes": fit.notes,
        }
    if not fitted:
        print("hrc fit: nobody could be fitted (above: why)", file=sys.stderr)
        return 1
    write_fitted(out, fitted, info)
    report: dict[str, Any] = {"fitted": fitted, "file": str(out), "info": info}
    if refused:
        report["not_fitted"] = refused
    if table is not None:
        rec = recovery(table, fitted, {w: i["uncertainty"] for w, i in info.items()})
        if rec:
            report["recovery"] = rec
    if args.json:
        print(json.dumps(report, indent=1))
        return 1 if refused else 0
    for who, params in fitted.items():
        shown = ", ".join(f"{k} {v}" for k, v in params.items())
        n = len(info[who]["trials"])
        print(f"{who} ({n} trial{'s' if n != 1 else ''}): {shown}")
        sure = info[who]["uncertainty"]
        if sure:
            print("  uncertainty: " + ", ".join(f"{k} {v:g}" for k, v in sure.items()))
        for note in info[who]["notes"]:
            print(f"  note: {note}")
    for key, r in report.get("recovery", {}).items():
        within = r.get("within_2se")
        print(
            f"recovery {key}: n {r['n']}, bias {100 * r['bias']:+.1f} %, mean |error| "
            f"{100 * r['mean_abs_error']:.1f} %, max {100 * r['max_abs_error']:.1f} %"
            + (f"; within 2 standard errors: {within[0]} of {within[1]}" if within else "")
        )
    print(f"written: {out}")
    if refused:
        print(f"not fitted: {', '.join(refused)} (above: why)")
    return 1 if refused else 0
