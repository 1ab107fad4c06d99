"""Command-line refusals happen before the service joins a run."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hrc_human_input.main import main


def test_non_loopback_vr_bind_without_token_exits_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--vr-host", "0.0.0.0", "--input", "vr", "--vr-token", ""]) == 2
    assert "without a token" in capsys.readouterr().err


def test_broken_replay_file_exits_2_with_line_numbers(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    f = tmp_path / "broken.jsonl"
    f.write_text(
        json.dumps({"format": "hrc-human-input", "version": 1})
        + "\n{bad\n"
        + json.dumps({"t": 0.0})
        + "\n"
    )
    assert main(["--replay", str(f)]) == 2
    err = capsys.readouterr().err
    assert "line 2: not valid JSON" in err
    assert "line 3: head is missing" in err and "line 3: right_grip is missing" in err
