"""The golden trials give exactly the committed outputs (tests/golden/<name>/).

This is what lets a refactoring claim "behaviour unchanged": events, log and metrics are compared
line by line. After a deliberate change, `scripts/update-golden.sh` rewrites the golden files.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from .goldens import GOLDEN_ROOT, GOLDEN_TRIALS, normalised, run_trial, scenario_file

pytestmark = [pytest.mark.e2e, pytest.mark.slow]


@pytest.mark.parametrize("name", sorted(GOLDEN_TRIALS))
def test_a_golden_trial_gives_the_committed_outputs(
    name: str, tmp_path: Path, request: pytest.FixtureRequest
) -> None:
    if GOLDEN_TRIALS[name]:
        trial = run_trial(scenario_file(name, tmp_path), tmp_path / "out", "--no-view")
    else:  # the unmodified thesis trial: the session's shared run
        trial = request.getfixturevalue("thesis_trial")
    assert trial.returncode == 0, trial.stderr[-3000:]
    got, want = normalised(trial.folder), normalised(GOLDEN_ROOT / name)
    for file in ("metrics.json", "log.txt"):
        assert got[file] == want[file], f"{file} differs from tests/golden/{name}/{file}"
    events_got, events_want = got["events.jsonl"], want["events.jsonl"]
    for i, (a, b) in enumerate(zip(events_got, events_want, strict=False)):
        assert a == b, f"events.jsonl line {i + 1} differs from tests/golden/{name}/"
    assert len(events_got) == len(events_want), "events.jsonl has a different number of lines"
