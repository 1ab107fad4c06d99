"""events.jsonl records: one flat JSON object per task event, cue change and metrics message.

Every record of a type has the same keys, defaults included, and numbers that are NaN/inf
become null (JSON has no NaN):

- ``{"type": "event", "tick", "sim_time", "seq", "kind": "COLLISION", "task_time", "agent",
  "part", "robot", "hand", "text", "payload": {...}, "wall_time"}``; ``payload`` holds the
  fields of the kind's typed payload (e.g. ``{"number": 1, "delay_s": 2.5}`` for CONTINUED),
  ``{}`` for kinds without one
- ``{"type": "cue", "tick", "sim_time", "seq", "kind": "TARGET", "id", "on", "part", "robot",
  "color", "position": [x, y, z], "text", "flashing"}`` (one per cue of an Indicators message)
- ``{"type": "metrics", "tick", "sim_time", "seq", "final", ...}`` then the metrics exactly as
  metrics.json has them (`hrc.metrics.to_dict`; fields in docs/metrics.md)
- ``{"type": "run_end", "tick", "sim_time", "ok", "reason", "failed_participant", "ticks",
  "wall_s", "realtime_factor"}`` (last line of a run that ended normally or with an error)
"""

from __future__ import annotations

import math
from typing import Any

from hrc import metrics as metrics_schema
from hrc.wire import pb
from hrc.wire.jsonmap import message_to_dict

from hrc_logger.textlog import kind_name


def num(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def cue_kind_name(kind: pb.CueKind.ValueType) -> str:
    try:
        return pb.CueKind.Name(kind).removeprefix("CUE_KIND_")
    except ValueError:
        return f"KIND_{kind}"


def _head(msg: Any, type_: str) -> dict[str, Any]:
    h = msg.header
    return {"type": type_, "tick": int(h.tick), "sim_time": num(h.sim_time), "seq": int(h.seq)}


def payload_dict(ev: pb.TaskEvent) -> dict[str, Any]:
    which = ev.WhichOneof("payload")
    return message_to_dict(getattr(ev, which)) if which else {}


def event_record(ev: pb.TaskEvent) -> dict[str, Any]:
    r = _head(ev, "event")
    r.update(
        {
            "kind": kind_name(ev.kind),
            "task_time": num(ev.task_time),
            "agent": ev.agent,
            "part": ev.part,
            "robot": ev.robot,
            "hand": ev.hand,
            "text": ev.text,
            "payload": payload_dict(ev),
            "wall_time": ev.wall_time,
        }
    )
    return r


def cue_records(ind: pb.Indicators) -> list[dict[str, Any]]:
    out = []
    for c in ind.cues:
        r = _head(ind, "cue")
        r.update(
            {
                "kind": cue_kind_name(c.kind),
                "id": c.id,
                "on": c.on,
                "part": c.part,
                "robot": c.robot,
                "color": c.color,
                "position": [num(c.position.x), num(c.position.y), num(c.position.z)],
                "text": c.text,
                "flashing": c.flashing,
            }
        )
        out.append(r)
    return out


def metrics_record(report: pb.MetricsReport) -> dict[str, Any]:
    r = _head(report, "metrics")
    r["final"] = report.final
    r.update(metrics_schema.to_dict(report.metrics))
    return r


def run_end_record(end: pb.RunEnd) -> dict[str, Any]:
    r = _head(end, "run_end")
    r.update(
        {
            "ok": end.ok,
            "reason": end.reason,
            "failed_participant": end.failed_participant,
            "ticks": int(end.ticks),
            "wall_s": num(end.wall_s),
            "realtime_factor": num(end.realtime_factor),
        }
    )
    return r
