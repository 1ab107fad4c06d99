"""Full trials with all five services (issue 6 acceptance): the scripted participant completes
the shipped scenarios; a recorded trial replays to the same task events and metrics."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from hrc.paths import ik_binary, project_root
from hrc.trial import TrialOptions, run_trial

from .conftest import strip_fields

ROOT = project_root()
pytestmark = [
    pytest.mark.e2e,
    pytest.mark.slow,
    pytest.mark.skipif(not ik_binary().exists(), reason=f"{ik_binary()} is not built"),
]
MAX_TICKS = 240 * 400  # sim seconds cap, so a stuck trial fails instead of hanging

# Fields that legitimately differ between two runs of the same trial.
WALL_FIELDS = {"wall_time", "wall_s", "realtime_factor", "created"}


def trial(scenario: str, out: Path, **kw: Any) -> Path:
    opts = TrialOptions(
        scenario=ROOT / "scenarios" / f"{scenario}.toml", out=out, max_ticks=MAX_TICKS, **kw
    )
    result = run_trial(opts, out)
    assert result.ok, result.message
    assert result.run_end is not None
    assert result.run_end.reason.startswith("stopped"), (
        f"the run did not end by the task finishing: {result.run_end.reason}"
    )
    return out


def events(trial_dir: Path) -> list[dict[str, Any]]:
    out = []
    for line in (trial_dir / "events.jsonl").read_text().splitlines():
        obj = json.loads(line)
        out.append({k: v for k, v in obj.items() if k not in WALL_FIELDS})
    return out


def strip(obj: Any) -> Any:
    return strip_fields(obj, WALL_FIELDS)


@pytest.mark.parametrize("scenario", ["minimal", "thesis"])
def test_scripted_participant_completes_the_scenario(
    scenario: str, tmp_path: Path, request: pytest.FixtureRequest
) -> None:
    if scenario == "thesis":  # the session's shared run of the unmodified thesis trial
        shared = request.getfixturevalue("thesis_trial")
        assert shared.returncode == 0, shared.stderr[-3000:]
        end_reason = shared.metrics["run"]["end_reason"]
        assert end_reason.startswith("stopped"), (
            f"the run did not end by the task finishing: {end_reason}"
        )
        d = shared.folder
    else:
        d = trial(scenario, tmp_path / "trial")
    kinds = [e.get("kind") for e in events(d)]
    assert "TASK_FINISHED" in kinds and "HUMAN_FINISHED" in kinds
    metrics = json.loads((d / "metrics.json").read_text())
    assert metrics["human"]["completion_s"] > 0
    print(
        f"{scenario}: task {metrics['task']['completion_s']:.2f} s, human "
        f"{metrics['human']['completion_s']:.2f} s, collisions "
        f"{metrics['collisions']['human_robot_count']}"
    )


def test_record_then_replay_gives_the_same_events_and_metrics(tmp_path: Path) -> None:
    rec = tmp_path / "p00.jsonl"
    first = trial("minimal", tmp_path / "scripted", record=rec)
    assert rec.exists() and len(rec.read_text().splitlines()) > 100
    second = trial("minimal", tmp_path / "replayed", replay=rec)
    assert strip(events(second)) == strip(events(first))  # all but wall-clock fields
    m1 = strip(json.loads((first / "metrics.json").read_text()))
    m2 = strip(json.loads((second / "metrics.json").read_text()))
    assert m2 == m1
