"""metrics.json: written by the orchestrator, which owns the numbers (schema: docs/metrics.md)."""

from __future__ import annotations

from pathlib import Path

from hrc import metrics as metrics_schema
from hrc.atomic import write_json_atomic
from hrc.wire import pb


def write_json(path: Path, metrics: pb.Metrics) -> None:
    """The JSON form of `metrics`, written atomically: a reader never sees half a file, a crash
    never leaves one."""
    path.parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(path, metrics_schema.to_dict(metrics))
