"""The sweep's table: one row per trial (`trials.parquet`, `trials.csv`).

Columns: study, trial, every factor by its dotted key, participant, its parameters
(`participant.<name>`), replay, seed, repetition, outcome, reason, exit_code, wall_s, then every
field of metrics.json flattened with dots (a list becomes its length). The metrics are read
generically: a field added to metrics.json becomes a column without a change here. A metric
column named like a study column (e.g. `participant`, `seed`) is left out: the study's value is
the one the trial was given.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from hrc.study.spec import Study
from hrc.study.trial import Record

if TYPE_CHECKING:
    import pandas as pd

STUDY_COLUMNS = (
    "study",
    "trial",
    "participant",
    "replay",
    "seed",
    "repetition",
    "outcome",
    "reason",
    "exit_code",
    "wall_s",
)


def flatten(obj: Any, prefix: str = "") -> dict[str, Any]:
    """{"a": {"b": 1}, "c": [1, 2]} -> {"a.b": 1, "c": 2}: nested tables by dotted keys, lists
    by their length."""
    out: dict[str, Any] = {}
    if isinstance(obj, dict):
        for key, value in obj.items():
            out.update(flatten(value, f"{prefix}.{key}" if prefix else str(key)))
    elif isinstance(obj, list):
        out[prefix] = len(obj)
    else:
        out[prefix] = obj
    return out


def rows(study: Study, records: list[Record]) -> list[dict[str, Any]]:
    by_id = {t.id: t for t in study.trials}
    out: list[dict[str, Any]] = []
    for rec in records:
        t = by_id[rec.trial]
        row: dict[str, Any] = {
            "study": study.name,
            "trial": t.id,
            **{k: t.condition.get(k) for k in study.factors},
            "participant": t.person.id,
            **{f"participant.{k}": v for k, v in t.person.params.items()},
            "replay": str(t.person.replay) if t.person.replay else None,
            "seed": t.seed,
            "repetition": t.repetition,
            "outcome": rec.outcome,
            "reason": rec.reason,
            "exit_code": rec.exit_code,
            "wall_s": rec.wall_s,
        }
        for key, value in flatten(rec.metrics or {}).items():
            row.setdefault(key, value)
        out.append(row)
    return out


def frame(study: Study, records: list[Record]) -> pd.DataFrame:
    import pandas as pd

    data = rows(study, records)
    columns: list[str] = []
    for row in data:  # first-seen order: study columns, then metrics as metrics.json lists them
        columns.extend(k for k in row if k not in columns)
    df = pd.DataFrame(data, columns=columns)
    for col in df.columns:  # a column of mixed numbers and text (factor levels) stays text
        if df[col].dtype == object and df[col].dropna().map(type).nunique() > 1:
            df[col] = df[col].map(lambda v: None if v is None else str(v))
    return df


def write_table(study: Study, records: list[Record], out: Path) -> pd.DataFrame:
    df = frame(study, records)
    df.to_parquet(out / "trials.parquet", index=False)
    df.to_csv(out / "trials.csv", index=False)
    return df
