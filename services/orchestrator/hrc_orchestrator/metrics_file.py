"""metrics.json (SPEC §4): written by the orchestrator, which owns the numbers."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from hrc.wire import pb

MODE_NAMES = {pb.CLOCK_MODE_LOCKSTEP: "lockstep", pb.CLOCK_MODE_REALTIME: "realtime"}


def run_section(end: pb.RunEnd) -> dict[str, Any]:
    return {
        "mode": MODE_NAMES.get(end.mode, "unknown"),
        "ticks": int(end.ticks),
        "wall_s": round(end.wall_s, 6),
        "realtime_factor": round(end.realtime_factor, 6),
        "ok": end.ok,
        "end_reason": end.reason,
        "deadline_misses": dict(end.deadline_misses),
    }


def write_json(path: Path, data: dict[str, Any]) -> None:
    """Atomic write: a reader never sees half a file, a crash never leaves one."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    with open(tmp, "w", encoding="utf-8") as f:
        json.dump(data, f, indent=2, sort_keys=False)
        f.write("\n")
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
