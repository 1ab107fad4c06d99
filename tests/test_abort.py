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

SAMPLES_READ = 200


def test_a_participant_whose_step_raises_ends_the_trial_within_2_s_naming_it(
        trial_factory, tmp_path: Path) -> None:
    fifo = tmp_path / "recording.jsonl"
    os.mkfifo(fifo)
    closed_at: list[float] = []

    def reader() -> None:  # the header, some samples, then gone
        with open(fifo, encoding="utf-8") as f:
            for _ in range(1 + SAMPLES_READ):
                f.readline()
        closed_at.append(time.monotonic())

    threading.Thread(target=reader, daemon=True).start()
    trial = trial_factory(extra=["--record", str(fifo)])
    code, _out, err = trial.communicate(timeout=120)
    ended_at = time.monotonic()
    assert closed_at, err
    took = ended_at - closed_at[0]
    print(f"hrc run ended {took:.2f} s after the recording's reader went away")
    assert code != 0
    assert "run failed: aborted by human_input: tick " in err, err
    assert "human_input.log" in err and "BrokenPipeError" in err, err  # its log's tail
    m = json.loads((trial.out / "metrics.json").read_text())
    assert not m["run"]["ok"]
    assert m["run"]["end_reason"].startswith("aborted by human_input: tick "), m["run"]
    events = [json.loads(line) for line in (trial.out / "events.jsonl").read_text().splitlines()]
    run_end = [e for e in events if e["type"] == "run_end"]
    assert run_end and run_end[0]["failed_participant"] == "human_input", run_end
    assert took < 2.0, f"took {took:.2f} s"
