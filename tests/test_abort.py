"""A participant whose step raises ends the trial at once, naming it (through ``hrc run``).

No test hook: human_input records to a pipe whose reader goes away, so the recorder's write in
its step genuinely raises (BrokenPipeError), as it would on a full disk.
"""

from __future__ import annotations

import json
import os
import threading
import time
from pathlib import Path

from hrc.wire import pb


def test_a_participant_whose_step_raises_ends_the_trial_within_2_s_naming_it(
    trial_factory, tmp_path: Path
) -> None:
    fifo = tmp_path / "recording.jsonl"
    os.mkfifo(fifo)
    leave = threading.Event()
    closed_at: list[float] = []

    def reader() -> None:  # reads what human_input records until told to go away
        with open(fifo, encoding="utf-8") as f:
            while not leave.is_set() and f.readline():
                pass
        closed_at.append(time.monotonic())

    threading.Thread(target=reader, daemon=True).start()
    trial = trial_factory(extra=["--record", str(fifo)])
    trial.wait_ticking()
    ends: list[tuple[float, pb.RunEnd]] = []
    bus = trial.bus()
    bus.subscribe(bus.keys.run_end(), pb.RunEnd, lambda _k, e: ends.append((time.monotonic(), e)))
    time.sleep(0.3)  # the subscription reaches the router
    leave.set()
    code, _out, err = trial.communicate(timeout=120)
    exited_at = time.monotonic()
    assert closed_at and ends, err
    ((ended_at, end),) = ends
    print(
        f"run/end {(ended_at - closed_at[0]) * 1e3:.0f} ms and hrc run's exit "
        f"{exited_at - closed_at[0]:.2f} s after the recording's reader went away"
    )
    assert not end.ok and end.failed_participant == "human_input", end
    assert end.reason.startswith("aborted by human_input: tick "), end.reason
    assert "BrokenPipeError" in end.reason
    assert ended_at - closed_at[0] < 2.0
    assert code != 0
    assert "run failed: aborted by human_input: tick " in err, err
    assert "human_input.log" in err and "BrokenPipeError" in err, err  # its log's tail
    m = json.loads((trial.out / "metrics.json").read_text())
    assert not m["run"]["ok"] and m["run"]["end_reason"] == end.reason
    events = [json.loads(line) for line in (trial.out / "events.jsonl").read_text().splitlines()]
    assert [e["failed_participant"] for e in events if e["type"] == "run_end"] == ["human_input"]
