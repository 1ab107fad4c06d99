"""Event-aligned exchanges keep the timing of one-tick exchanges (docs/ARCHITECTURE.md,
"Exchange step"), with the five real services.

The thesis trial with two provoked collisions (the golden `thesis-collisions`: a cautious
participant who holds back for robots, reaches into one twice, and is hit) runs twice: with the
default exchanges (up to `max_exchange_ticks` ticks, ended at every event a participant
declares, started at every look it declares, and at every gap the speed bounds could close) and
with `max_exchange_ticks = 1`. Every event happens at the same tick and the metrics and the log
are the same, but for the participant's idle time: a hand crossing the workspace's edge inside
an exchange is seen at its end (documented there).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from hrc.bus.clock import exchange_counts
from hrc.trial.aligned import compare

from .goldens import GOLDEN_TRIALS, MINIMAL, THESIS, normalised, run_trial

pytestmark = [pytest.mark.e2e, pytest.mark.slow]


def _scenario(tmp: Path, max_ticks: int | None) -> Path:
    text = THESIS.read_text()
    assert "caution = 0.5" in text and "seed = 1\n" in text
    for old, new in GOLDEN_TRIALS["thesis-collisions"]:
        text = text.replace(old, new)
    if max_ticks is not None:
        text = text.replace("seed = 1\n", f"seed = 1\nmax_exchange_ticks = {max_ticks}\n", 1)
    # in the test's folder: its relative paths (robots/arm5.urdf) resolve against the project
    # root there. (A copy beside thesis.toml was seen by another pytest process collecting
    # scenarios/*.toml, and gone when that test ran.)
    path = tmp / f"thesis-collisions-{max_ticks}.toml"
    path.write_text(text)
    return path


def _trial(tmp: Path, max_ticks: int | None) -> tuple[Path, int, int]:
    scenario = _scenario(tmp, max_ticks)
    out = tmp / f"span{max_ticks}"
    proc = run_trial(scenario, out, "--no-view")  # the events are compared, not views
    assert proc.returncode == 0, proc.stderr[-3000:]
    counts = exchange_counts((out / "services" / "physics.log").read_text())
    assert counts, "physics logs its exchanges at the end"
    return out, *counts


def test_event_aligned_exchanges_give_the_events_of_one_tick_exchanges(tmp_path: Path) -> None:
    aligned, ticks, exchanges = _trial(tmp_path, None)
    single, ticks_1, exchanges_1 = _trial(tmp_path, 1)
    assert ticks == ticks_1 == exchanges_1
    assert exchanges < ticks / 5, f"{exchanges} exchanges for {ticks} ticks: hardly any saved"
    collisions = [e for e in normalised(single)["events.jsonl"] if e.get("kind") == "COLLISION"]
    assert len(collisions) >= 2, "the trial is to show the participant hit (and cautious after)"
    # the events and cues at the same ticks, the same metrics and log lines (hrc.trial.aligned:
    # but for the participant's idle time)
    found = compare(aligned, single)
    assert found.records > 150
    assert found.aligned, "not as with one-tick exchanges:\n" + "\n".join(
        str(d) for d in found.differences
    )


def test_a_continue_button_press_is_seen_at_its_tick(tmp_path: Path) -> None:
    """Under retreat_button (the minimal task, two provoked collisions, each confirmed at the
    button): a hand may press the button only where an exchange ends, and the robots go on at
    the ticks of one-tick exchanges. (Before, a press was seen at its exchange's end: both of
    them here, 1 and 26 ticks late.)"""
    text = MINIMAL.read_text()
    assert 'safety_policy = "retreat"' in text and 'input = "scripted"\n' in text
    text = text.replace('safety_policy = "retreat"', 'safety_policy = "retreat_button"')
    text = text.replace(
        'input = "scripted"\n', 'input = "scripted"\nprovoke_collisions = [1.0, 4.0]\n'
    )
    outs = []
    for span in (None, 1):
        scenario = tmp_path / f"minimal-button-{span}.toml"
        scenario.write_text(
            text
            if span is None
            else text.replace("seed = 1\n", "seed = 1\nmax_exchange_ticks = 1\n", 1)
        )
        out = tmp_path / f"span{span}"
        proc = run_trial(scenario, out, "--no-view")
        assert proc.returncode == 0, proc.stderr[-3000:]
        outs.append(out)
    kinds = [e.get("kind") for e in normalised(outs[1])["events.jsonl"]]
    assert kinds.count("COLLISION") == kinds.count("BUTTON_PRESSED") == 2
    found = compare(*outs)
    assert found.aligned, "not as with one-tick exchanges:\n" + "\n".join(
        str(d) for d in found.differences
    )
