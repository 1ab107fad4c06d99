"""A study's people fitted (`hrc fit`): their recorded trials grouped by participant from the
study's table, the fitted parameters written as a table a study reads (`participants.fitted`),
and how well a simulated participant's own parameters were recovered. The fit of one person:
hrc.participant.fit."""

from __future__ import annotations

import logging
import math
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


def recovery(
    table: Any,
    fitted: dict[str, dict[str, Any]],
    uncertainty: dict[str, dict[str, float]] | None = None,
) -> dict[str, Any]:
    """Per parameter: the simulated participants' true and fitted values, relative bias and
    mean absolute relative error (only parameters the table gives per participant); with the
    fit's `uncertainty` (person -> `<param>_rel_se`), how many true values lie within two of
    its standard errors (`within_2se`: [k, of n])."""
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
        ses = [
            (abs(f - t) / t, (uncertainty or {}).get(w, {}).get(f"{key}_rel_se"))
            for w, t, f in pairs
        ]
        judged = [err <= 2.0 * se for err, se in ses if se is not None]
        if judged:
            out[key]["within_2se"] = [sum(judged), len(judged)]
    return out


def write_fitted(path: Path, fitted: dict[str, dict[str, Any]], info: dict[str, Any]) -> None:
    head = (
        "# hrc fit: each person's scripted-participant parameters, fitted to their recordings\n"
        "# (docs/participant-model.md). A study uses them as participants.fitted = <this file>.\n"
    )
    path.write_text(head + dumps({"fitted": fitted, "fit_info": info}), encoding="utf-8")
