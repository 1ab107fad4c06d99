"""hrc.trial.aligned: a trial against its one-tick twin, what is left out on purpose and what is
not."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

from hrc.trial.aligned import compare

EVENTS: list[dict[str, Any]] = [
    {"type": "event", "tick": 10, "seq": 1, "kind": "TASK_STARTED", "wall_time": "08:00:01"},
    {"type": "event", "tick": 20, "seq": 2, "kind": "HUMAN_IDLE_BEGIN", "text": "idle"},
    {"type": "event", "tick": 40, "seq": 3, "kind": "PART_PLACED", "part": "H1"},
    {"type": "cue", "tick": 41, "seq": 4, "kind": "CONTINUE_BUTTON", "on": True},
    {"type": "event", "tick": 50, "seq": 5, "kind": "BUTTON_PRESSED", "text": "pressed"},
    {"type": "cue", "tick": 50, "seq": 6, "kind": "CONTINUE_BUTTON", "on": False},
    {
        "type": "event",
        "tick": 60,
        "seq": 7,
        "kind": "HUMAN_FINISHED",
        "text": "Idle 2.000 sec.",
        "payload": {"idle_s": 2.0},
    },
]
METRICS: dict[str, Any] = {
    "human": {"completion_s": 9.0, "idle_s": 2.0},
    "robots": {"r1": {"completion_s": 8.0, "idle_s": 1.0}},
    "run": {"ticks": 100, "wall_s": 1.5, "realtime_factor": 9.0},
}
LOG = ["SETTINGS: x", "08:00:01 - TASK STARTED.", "1.000 sec : human placed H1.", "idle 2.0"]


def trial(
    folder: Path, events: list[dict[str, Any]], metrics: dict[str, Any], log: list[str]
) -> Path:
    folder.mkdir()
    (folder / "events.jsonl").write_text("".join(json.dumps(e) + "\n" for e in events))
    (folder / "metrics.json").write_text(json.dumps(metrics))
    (folder / "log.txt").write_text("\n".join(log) + "\n")
    return folder


def twin(tmp_path: Path) -> Path:
    return trial(tmp_path / "one-tick", EVENTS, METRICS, LOG)


def test_idle_time_wall_clock_and_seq_are_left_out(tmp_path: Path) -> None:
    events = copy.deepcopy(EVENTS)
    events[0]["wall_time"] = "09:30:00"
    events[1]["tick"] = 23  # the idle begins at an exchange's end
    events[6]["text"], events[6]["payload"] = "Idle 2.012 sec.", {"idle_s": 2.0125}
    for e in events[2:]:
        e["seq"] += 1  # (a record more before them would shift every seq)
    metrics = copy.deepcopy(METRICS)
    metrics["human"]["idle_s"] = 2.0125
    metrics["run"]["wall_s"] = 3.0
    log = [*LOG[:1], "09:30:00 - TASK STARTED.", LOG[2], "idle 2.0125"]
    found = compare(trial(tmp_path / "default", events, metrics, log), twin(tmp_path))
    assert found.aligned, found.differences
    assert found.records == 6  # all but the idle event


def test_a_button_press_at_another_tick_is_a_difference(tmp_path: Path) -> None:
    events = copy.deepcopy(EVENTS)
    events[4]["tick"] = events[5]["tick"] = 55  # seen at an exchange's end
    found = compare(trial(tmp_path / "default", events, METRICS, LOG), twin(tmp_path))
    assert [d.where for d in found.differences] == [
        "events.jsonl record 4",
        "events.jsonl record 5",
    ]


def test_an_event_at_another_tick_a_robots_idle_and_a_log_line_are_differences(
    tmp_path: Path,
) -> None:
    events = copy.deepcopy(EVENTS)
    events[2]["tick"] = 43
    metrics = copy.deepcopy(METRICS)
    metrics["robots"]["r1"]["idle_s"] = 1.1  # the robots' idle time is aligned
    log = [*LOG[:2], "1.012 sec : human placed H1.", LOG[3]]
    found = compare(trial(tmp_path / "default", events, metrics, log), twin(tmp_path))
    assert not found.aligned
    where = [d.where for d in found.differences]
    assert where == ["events.jsonl record 2", "metrics.json .robots.r1.idle_s", "log.txt line 3"]
    assert found.differences[0].got["tick"] == 43 and found.differences[0].want["tick"] == 40


def test_a_missing_record_is_a_difference(tmp_path: Path) -> None:
    found = compare(trial(tmp_path / "default", EVENTS[:-1], METRICS, LOG), twin(tmp_path))
    assert [d.where for d in found.differences] == ["events.jsonl length"]
