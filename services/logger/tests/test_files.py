"""Line files reach the OS line by line: SIGKILL loses nothing already written."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from hrc.atomic import write_json_atomic

from hrc_logger.files import JsonlFile, LineFile

CHILD = r"""
import sys
from pathlib import Path
from hrc_logger.files import JsonlFile
f = JsonlFile(Path(sys.argv[1]))
i = 0
while True:
    i += 1
    f.write({"type": "event", "i": i, "text": "x" * (i % 300)})
    if i % 50 == 0:
        print(i, flush=True)
"""


def test_kill_9_mid_run_leaves_every_written_line_parseable(tmp_path: Path) -> None:
    path = tmp_path / "events.jsonl"
    child = subprocess.Popen(
        [sys.executable, "-c", CHILD, str(path)], stdout=subprocess.PIPE, text=True
    )
    try:
        assert child.stdout is not None
        reported = 0
        while reported < 2000:
            line = child.stdout.readline()
            assert line, "writer child exited early"
            reported = int(line)
    finally:
        os.kill(child.pid, signal.SIGKILL)
        child.wait()
    lines = path.read_text().splitlines()
    assert len(lines) >= reported  # nothing it had written before reporting was lost
    numbers = [json.loads(line)["i"] for line in lines]  # every line is complete JSON
    assert numbers == list(range(1, len(lines) + 1))


def test_a_line_break_inside_a_line_is_refused(tmp_path: Path) -> None:
    with LineFile(tmp_path / "log.txt") as f:
        with pytest.raises(ValueError, match="line break"):
            f.write_line("a\nb")
        f.write_line("ok")
    assert (tmp_path / "log.txt").read_text() == "ok\n"


def test_jsonl_refuses_nan(tmp_path: Path) -> None:
    with JsonlFile(tmp_path / "e.jsonl") as f, pytest.raises(ValueError):
        f.write({"x": float("nan")})


def test_atomic_json(tmp_path: Path) -> None:
    write_json_atomic(tmp_path / "s.json", {"a": 1})
    assert json.loads((tmp_path / "s.json").read_text()) == {"a": 1}
    assert not (tmp_path / "s.json.tmp").exists()
