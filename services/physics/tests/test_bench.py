"""``hrc bench physics`` runs the physics package's own bench as a process."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

HRC = str(Path(sys.executable).with_name("hrc"))


def test_hrc_bench_physics_prints_one_json_object() -> None:
    proc = subprocess.run(
        [HRC, "bench", "physics", "--json", "--n", "50"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)
    assert list(result) == ["us_per_tick"] and result["us_per_tick"] > 0


def test_the_bench_refuses_a_bad_tick_count() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "hrc_physics.bench", "--n", "0"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2 and "--n must be >= 1" in proc.stderr
