"""The sweep's table: one row per trial (`trials.parquet`, `trials.csv`).

Columns: study, trial, every factor by its dotted key, participant, participant_kind
(`simulated`, `replay`, `live`), order_position (a live participant's trials: 1, 2, ...; 0 for
practice), practice, its parameters (`participant.<name>`), replay, seed, repetition, outcome,
reason, exit_code, wall_s, then every field of metrics.json flattened with dots (a list becomes
its length), then the questionnaires' answers and scores (`q.<questionnaire>.<item>`; those
asked at the end of a session are on each of the participant's rows).

The sweep's trials come from its records, the live participants' from their sessions
(`sessions/<id>/session.json`): `write_study_table` writes both, whoever calls it. The metrics
are read generically: a field added to metrics.json becomes a column without a change here. A
metric column named like a study column (e.g. `participant`, `seed`) is left out: the study's
value is the one the trial was given.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from hrc.study.spec import Person, Study
from hrc.study.trial import MANIFEST, Manifest, Record

if TYPE_CHECKING:
    import pandas as pd

STUDY_COLUMNS = (
    "study",
    "trial",
    "participant",
    "participant_kind",
    "order_position",
    "practice",
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
            "participant_kind": _kind(t.person),
            "order_position": None,
            "practice": False,
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


def _kind(person: Person) -> str:
    if person.replay is not None:
        return "replay"
    return "fitted" if person.fitted_from is not None else "simulated"


def live_rows(study: Study, out: Path) -> list[dict[str, Any]]:
    """One row per trial of the live sessions in `out` that has run (pending ones are left
    out), in session order."""
    from hrc.study.session_state import all_sessions
    from hrc.study.trial import read_metrics

    result: list[dict[str, Any]] = []
    for s in all_sessions(out):
        given = {**s.start_answers, **s.end_answers}  # (a questionnaire is asked in one slot)
        session_q = answer_columns(given, _scores(study, given, {**s.start_scores, **s.end_scores}))
        for t in s.trials:
            if not t.attempts and t.status == "pending":
                continue
            last = t.attempts[-1] if t.attempts else None
            row: dict[str, Any] = {
                "study": study.name,
                "trial": t.id,
                **{k: t.condition.get(k) for k in study.factors},
                "participant": s.participant,
                "participant_kind": "live",
                "order_position": t.order_position,
                "practice": t.practice,
                "replay": None,
                "seed": t.seed,
                "repetition": t.repetition,
                "outcome": t.status,
                "reason": t.reason,
                "exit_code": last.exit_code if last else None,
                "wall_s": last.wall_s if last else None,
                "attempts": len(t.attempts),
                # the experimenter's notes on the trial (`n`, `f` in hrc session), in order
                "notes": " | ".join(n["text"] for n in t.notes if n.get("text")) or None,
                "flagged": any(n.get("flag") for n in t.notes),
            }
            if t.status in ("ok", "stalled"):
                for key, value in flatten(
                    read_metrics(out / "trials" / t.id / "metrics.json") or {}
                ).items():
                    row.setdefault(key, value)
            row.update(answer_columns(t.answers, _scores(study, t.answers, t.scores)))
            row.update(session_q)
            result.append(row)
    return result


def _scores(
    study: Study, answers: dict[str, dict[str, Any]], kept: dict[str, dict[str, Any]]
) -> dict[str, dict[str, Any]]:
    """The scores kept with the answers, by questionnaire; scored again from the answers (kept
    as given) where the study's questionnaire names its scores otherwise: a session.json
    written before the SSQ's subscales were named `*_score` kept `nausea` for the subscale,
    the name of an item too."""
    live = study.live
    slots = (live.before_session, live.before_trial, live.after_trial, live.end) if live else ()
    asked = {q.id: q for slot in slots for q in slot}
    out = dict(kept)
    for qid, items in answers.items():
        asked_q = asked.get(qid)
        if asked_q is not None and set(kept.get(qid) or {}) != set(asked_q.score_names()):
            out[qid] = asked_q.score(items)
    return out


def answer_columns(
    answers: dict[str, dict[str, Any]], scores: dict[str, dict[str, Any]]
) -> dict[str, Any]:
    """A trial's (or a session's) answers and scores as table columns: `q.<questionnaire>.<item>`
    and `q.<questionnaire>.<score>` (a questionnaire's items and scores never share a name)."""
    out: dict[str, Any] = {}
    for qid, items in answers.items():
        for item, value in items.items():
            out[f"q.{qid}.{item}"] = value
        for name, value in (scores.get(qid) or {}).items():
            out[f"q.{qid}.{name}"] = value
    return out


def frame(study: Study, records: list[Record], out: Path | None = None) -> pd.DataFrame:
    import pandas as pd

    data = rows(study, records) + (live_rows(study, out) if out is not None else [])
    columns: list[str] = []
    for row in data:  # first-seen order: study columns, then metrics as metrics.json lists them
        columns.extend(k for k in row if k not in columns)
    df = pd.DataFrame(data, columns=columns)
    for col in df.columns:  # a column of mixed numbers and text (factor levels) stays text
        if df[col].dtype == object and df[col].dropna().map(type).nunique() > 1:
            df[col] = df[col].map(lambda v: None if v is None else str(v))
    return df


def write_table(study: Study, records: list[Record], out: Path) -> pd.DataFrame:
    """The table of the sweep's `records` and of every live session in `out` (written to
    temporary files, then renamed: a reader never sees half a table)."""
    import os

    df = frame(study, records, out)
    for name, write in (("trials.parquet", df.to_parquet), ("trials.csv", df.to_csv)):
        tmp = out / f".{name}.{os.getpid()}.tmp"  # a sweep and a session may write at once
        write(tmp, index=False)
        os.replace(tmp, out / name)
    return df


def write_study_table(study: Study, out: Path) -> pd.DataFrame:
    """The table from what is on disk: the sweep's manifest and the live sessions."""

    manifest = Manifest(out / MANIFEST)
    records = [manifest.records[t.id] for t in study.trials if t.id in manifest.records]
    return write_table(study, records, out)
