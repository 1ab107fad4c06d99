"""Participant data is private by default: a trial's folders are 0700 and its files 0600, so
another local user (``nobody``) reads none of them; ``HRC_DATA_ACCESS=group`` opens them to the
user's group and nobody else; an output folder already open to others is warned about; a bad
setting is refused naming it."""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from .conftest import HRC
from .goldens import MINIMAL

pytestmark = [pytest.mark.e2e]


def run(out: Path, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [HRC, "run", str(MINIMAL), "--out", str(out), "--ticks", "30"],
        capture_output=True,
        text=True,
        env={**os.environ, **(env or {})},
        timeout=180,
    )


def modes(folder: Path) -> dict[str, int]:
    """The mode of the folder and of everything in it, by path relative to it."""
    found = {".": stat.S_IMODE(folder.stat().st_mode)}
    for p in folder.rglob("*"):
        found[str(p.relative_to(folder))] = stat.S_IMODE(p.lstat().st_mode)
    return found


def as_nobody(*argv: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        ["setpriv", "--reuid=nobody", "--regid=nogroup", "--clear-groups", *argv],
        capture_output=True,
        text=True,
        timeout=30,
    )


@pytest.fixture
def open_place() -> Iterator[Path]:
    """A folder every user may enter, in the system's temporary folder (pytest's own is 0700):
    only the trial's own modes can keep others out of it."""
    place = Path(tempfile.mkdtemp(prefix="hrc-privacy-"))
    place.chmod(0o755)
    try:
        yield place
    finally:
        shutil.rmtree(place, ignore_errors=True)


def test_a_trials_records_are_readable_by_its_user_alone(open_place: Path) -> None:
    out = open_place / "trial"
    done = run(out)
    assert done.returncode == 0, done.stderr[-2000:]
    found = modes(out)
    assert {"metrics.json", "events.jsonl", "log.txt", "recording.rrd"} <= set(found), found
    for path, mode in found.items():
        is_dir = (out / path).is_dir()
        assert mode == (0o700 if is_dir else 0o600), (path, oct(mode))
    assert "open to other users" not in done.stderr
    if os.geteuid() == 0:  # another user tries (needs root to become one)
        for name in ("metrics.json", "events.jsonl", "recording.rrd"):
            tried = as_nobody("cat", str(out / name))
            assert tried.returncode != 0 and "Permission denied" in tried.stderr, tried
        listed = as_nobody("ls", str(out))
        assert listed.returncode != 0, listed.stdout


def test_a_lab_group_may_read_and_an_open_folder_is_warned_about(open_place: Path) -> None:
    out = open_place / "trial"
    out.mkdir(mode=0o755)
    out.chmod(0o755)
    done = run(out, {"HRC_DATA_ACCESS": "group"})
    assert done.returncode == 0, done.stderr[-2000:]
    assert f"warning: {out} is open to other users (mode 0755)" in done.stderr, done.stderr
    found = modes(out)
    for path, mode in found.items():
        if path == ".":
            continue  # it was there before: hrc only warns
        is_dir = (out / path).is_dir()
        assert mode == (0o750 if is_dir else 0o640), (path, oct(mode))
    bad = run(open_place / "never", {"HRC_DATA_ACCESS": "everyone"})
    assert bad.returncode == 2
    assert "HRC_DATA_ACCESS='everyone': use one of group, private" in bad.stderr, bad.stderr
    assert not (open_place / "never").exists()
