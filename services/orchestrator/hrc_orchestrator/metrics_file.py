"""metrics.json: written by the orchestrator, which owns the numbers (schema: docs/metrics.md)."""

from __future__ import annotations

import json
import os
from pathlib import Path

from hrc import metrics as metrics_schema
from hrc.wire import pb


def write_json(path: Path, metrics: pb.Metrics) -> None:
    """The JSON form of `metrics`, written atomically: a reader never sees half a file, a crash
    never leaves one."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    with open(tmp, "w", encoding="utf-8") as f:
        json.dump(metrics_schema.to_dict(metrics), f, indent=2, sort_keys=False)
        f.write("\n")
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
