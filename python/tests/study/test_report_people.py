"""`hrc report` with live participants (hrc.study.report): live and simulated side by side,
questionnaire scores by condition, the order position in the live trials' model, practice
trials kept in the table and left out of the statistics. The table is made here: what is
tested is the report of it."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from hrc.study.report import write_report

FACTOR = "conditions.anticipation"


def table(folder: Path) -> None:
    rng = np.random.default_rng(5)
    rows = []
    for kind, prefix in (("simulated", "P"), ("live", "L")):
        for k in range(1, 7):
            pid = f"{prefix}{k:02d}"
            order = [True, False] if k % 2 else [False, True]  # counterbalanced
            if kind == "live":  # a practice trial, far off: it must not count
                rows.append(
                    dict(kind=kind, pid=pid, ant=True, pos=0, practice=True, t=500.0, tlx=99)
                )
            for pos, ant in enumerate(order, start=1):
                # anticipation saves 3 s; live people 10 s slower and 2 s faster each trial
                t = 40.0 - 3.0 * ant + rng.normal(0, 0.5)
                if kind == "live":
                    t += 10.0 - 2.0 * pos
                tlx = 50 - 10 * ant + int(rng.integers(-5, 6)) if kind == "live" else None
                rows.append(
                    dict(
                        kind=kind,
                        pid=pid,
                        ant=ant,
                        pos=pos if kind == "live" else None,
                        practice=False,
                        t=t,
                        tlx=tlx,
                    )
                )
    df = pd.DataFrame(
        {
            "study": "people",
            "trial": [f"{r['pid']}_{r['ant']}_{r['pos']}" for r in rows],
            FACTOR: [r["ant"] for r in rows],
            "participant": [r["pid"] for r in rows],
            "participant_kind": [r["kind"] for r in rows],
            "order_position": [r["pos"] for r in rows],
            "practice": [r["practice"] for r in rows],
            "outcome": "ok",
            "reason": "",
            "task.completion_s": [r["t"] for r in rows],
            "q.tlx.raw": [r["tlx"] for r in rows],
        }
    )
    df.to_parquet(folder / "trials.parquet", index=False)
    meta = {
        "name": "people",
        "scenario": "minimal.toml",
        "factors": {FACTOR: [True, False]},
        "questionnaires": {
            "tlx": {
                "title": "NASA Task Load Index",
                "when": "after_trial",
                "scores": ["raw"],
                "items": [],
            }
        },
    }
    (folder / "study.json").write_text(json.dumps(meta))


def text(html: str) -> str:
    return re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", html))


def test_live_and_simulated_side_by_side_with_the_order_position_in_the_model(
    tmp_path: Path,
) -> None:
    table(tmp_path)
    page = write_report(tmp_path).read_text()
    plain = text(page)
    assert "Statistics use the 24 trials that ended ok (6 practice trials left out)" in plain
    assert "<th>condition</th><th>live</th><th>simulated</th>" in page
    # live people 10 - 2 * 1.5 = 7 s slower on average than the simulated, in each condition
    m = re.search(r"anticipation = True ([\d.]+) \[[^\]]+\] \(6\) ([\d.]+) \[", plain)
    assert m, plain[:3000]
    assert float(m.group(1)) - float(m.group(2)) == pytest.approx(7.0, abs=1.0)
    assert (tmp_path / "figures" / "kinds_task_completion_s.png").is_file()
    # the live trials' model: anticipation about -3 s, the order position about -2 s per step
    live = plain[plain.index("Live trials: mixed models") :]
    m = re.search(r"order position \(per step\) (-?[\d.]+) \[(-?[\d.]+), (-?[\d.]+)\]", live)
    assert m, live[:2000]
    assert float(m.group(1)) == pytest.approx(-2.0, abs=0.7)
    # the questionnaire by condition: practice answers (99) left out
    q = plain[plain.index("Questionnaires") :]
    m = re.search(r"q\.tlx\.raw ([\d.]+) \[[^\]]+\] \(6\) ([\d.]+) \[[^\]]+\] \(6\)", q)
    assert m, q[:1500]
    assert float(m.group(1)) < 45 < float(m.group(2)) < 56  # anticipation on, off
    assert "q.tlx.raw ~ factors + order position" in q


def test_a_participant_whose_trials_were_all_skipped_is_not_counted_as_taking_part(
    tmp_path: Path,
) -> None:
    table(tmp_path)
    df = pd.read_parquet(tmp_path / "trials.parquet")
    skipped = df[df["participant"] == "P01"].assign(
        participant="L07", participant_kind="live", outcome="skipped", reason="skipped"
    )
    pd.concat([df, skipped]).to_parquet(tmp_path / "trials.parquet", index=False)
    plain = text(write_report(tmp_path).read_text())
    assert "12 participants with trials in the statistics (1 more with none: L07)" in plain, plain[
        :800
    ]


def test_the_design_says_which_factor_the_people_meet_between_and_which_within(
    tmp_path: Path,
) -> None:
    table(tmp_path)
    meta = json.loads((tmp_path / "study.json").read_text())
    meta.update(live_participants=["L01"], between=[FACTOR])
    (tmp_path / "study.json").write_text(json.dumps(meta))
    plain = text(write_report(tmp_path).read_text())
    assert f"{FACTOR} True, False between (one level each)" in plain, plain[:1500]


def test_the_experimenters_notes_and_flags_are_listed_and_nothing_is_left_out(
    tmp_path: Path,
) -> None:
    table(tmp_path)
    df = pd.read_parquet(tmp_path / "trials.parquet")
    df["notes"] = None
    df["flagged"] = False
    live = df.index[df["participant_kind"] == "live"]
    df.loc[live[1], "notes"] = "the participant sneezed | asked to go on"
    df.loc[live[2], "flagged"] = True
    df.to_parquet(tmp_path / "trials.parquet", index=False)
    plain = text(write_report(tmp_path).read_text())
    notes = plain[plain.index("The experimenter's notes") :]
    assert f"{df.loc[live[1], 'trial']} (L01) the participant sneezed | asked to go on" in notes
    assert f"{df.loc[live[2], 'trial']} (L01) flagged" in notes
    assert "Statistics use the 24 trials that ended ok" in plain  # none left out for them
    # without notes or flags: no section
    df["notes"], df["flagged"] = None, False
    df.to_parquet(tmp_path / "trials.parquet", index=False)
    assert "The experimenter's notes" not in write_report(tmp_path).read_text()
