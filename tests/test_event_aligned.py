"""Event-aligned exchanges keep the timing of one-tick exchanges (docs/ARCHITECTURE.md,
"Exchange step"), with the five real services.

The thesis trial runs twice: with the default exchanges (up to `max_exchange_ticks` ticks, ended
at every event a participant declares and at every gap the speed bounds could close) and with
`max_exchange_ticks = 1`. The participant's caution is off: it reads the robots' positions every
tick to decide whether to hold back, a reaction no participant can announce, so with caution a
decision may fall a few ticks apart (the thesis trial's last human placement moves by up to a
third of a second). Without it every event happens at the same tick and the metrics and the log
are the same.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import pytest

from .goldens import THESIS, normalised, run_trial

pytestmark = [pytest.mark.e2e, pytest.mark.slow]


def _scenario(tmp: Path, max_ticks: int) -> Path:
    text = THESIS.read_text()
    assert "caution = 0.5" in text and "seed = 1\n" in text
    text = text.replace("caution = 0.5", "caution = 0.0")
    text = text.replace("seed = 1\n", f"seed = 1\nmax_exchange_ticks = {max_ticks}\n", 1)
    # next to thesis.toml, so that its relative paths resolve
    path = THESIS.parent / f".test-event-aligned-{tmp.name}-{max_ticks}.toml"
    path.write_text(text)
    return path


def _flat(obj: Any, prefix: str = "") -> dict[str, Any]:
    if isinstance(obj, dict):
        return {k: v for key, val in obj.items() for k, v in _flat(val, f"{prefix}.{key}").items()}
    if isinstance(obj, list):
        return {k: v for i, val in enumerate(obj) for k, v in _flat(val, f"{prefix}[{i}]").items()}
    return {prefix: obj}


def _trial(tmp: Path, max_ticks: int) -> tuple[dict[str, Any], int, int]:
    scenario = _scenario(tmp, max_ticks)
    out = tmp / f"span{max_ticks}"
    try:
        proc = run_trial(scenario, out, "--no-view")  # the events are compared, not views
    finally:
        scenario.unlink()
    assert proc.returncode == 0, proc.stderr[-3000:]
    log = (out / "services" / "physics.log").read_text()
    found = re.search(r"(\d+) ticks in (\d+) exchanges", log)
    assert found, "physics logs its exchanges at the end"
    return normalised(out), int(found[1]), int(found[2])


def test_event_aligned_exchanges_give_the_events_of_one_tick_exchanges(tmp_path: Path) -> None:
    aligned, ticks, exchanges = _trial(tmp_path, 16)
    single, ticks_1, exchanges_1 = _trial(tmp_path, 1)
    assert ticks == ticks_1 == exchanges_1
    assert exchanges < ticks / 2, f"{exchanges} exchanges for {ticks} ticks: hardly any saved"
    got, want = aligned["events.jsonl"], single["events.jsonl"]
    for i, (a, b) in enumerate(zip(got, want, strict=False)):
        assert a == b, f"event {i + 1}: {json.dumps(a)} != {json.dumps(b)} (one-tick exchanges)"
    assert len(got) == len(want)
    m_got, m_want = _flat(aligned["metrics.json"]), _flat(single["metrics.json"])
    differ = sorted(k for k in m_got.keys() | m_want.keys() if m_got.get(k) != m_want.get(k))
    assert not differ, f"metrics differ: {differ}"
    assert aligned["log.txt"] == single["log.txt"]
