"""events.jsonl records: one flat JSON object per task event, cue change and metrics message.

Our own flat mapping (not MessageToDict) so every record of a type has the same keys, defaults
included, and numbers that are NaN/inf become null (JSON has no NaN):

- ``{"type": "event", "tick", "sim_time", "seq", "kind": "COLLISION", "task_time", "agent",
  "part", "robot", "hand", "value", "text", "numbers": {...}, "wall_time"}``
- ``{"type": "cue", "tick", "sim_time", "seq", "kind": "TARGET", "id", "on", "part", "robot",
  "color", "position": [x, y, z], "text", "flashing"}`` (one per cue of an Indicators message)
- ``{"type": "metrics", "tick", "sim_time", "final", ...}`` with the metrics in the shape of
  metrics.json (SPEC §4: scenario, participant, conditions, seed, task, human, robots,
  collisions, parts, run)
- ``{"type": "run_end", "tick", "sim_time", "ok", "reason", "failed_participant", "ticks",
  "wall_s", "realtime_factor"}`` (last line of a run that ended normally or with an error)
"""

from __future__ import annotations

import math
from typing import Any

from hrc.wire import pb

from hrc_logger.textlog import kind_name


def num(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def cue_kind_name(kind: int) -> str:
    try:
        return pb.CueKind.Name(kind).removeprefix("CUE_KIND_")
    except ValueError:
        return f"KIND_{kind}"


def _head(msg: Any, type_: str) -> dict[str, Any]:
    h = msg.header
    return {"type": type_, "tick": int(h.tick), "sim_time": num(h.sim_time), "seq": int(h.seq)}


def event_record(ev: pb.TaskEvent) -> dict[str, Any]:
    r = _head(ev, "event")
    r.update({
        "kind": kind_name(ev.kind),
        "task_time": num(ev.task_time),
        "agent": ev.agent,
        "part": ev.part,
        "robot": ev.robot,
        "hand": ev.hand,
        "value": num(ev.value),
        "text": ev.text,
        "numbers": {k: num(v) for k, v in sorted(ev.numbers.items())},
        "wall_time": ev.wall_time,
    })
    return r


def cue_records(ind: pb.Indicators) -> list[dict[str, Any]]:
    out = []
    for c in ind.cues:
        r = _head(ind, "cue")
        r.update({
            "kind": cue_kind_name(c.kind),
            "id": c.id,
            "on": c.on,
            "part": c.part,
            "robot": c.robot,
            "color": c.color,
            "position": [num(c.position.x), num(c.position.y), num(c.position.z)],
            "text": c.text,
            "flashing": c.flashing,
        })
        out.append(r)
    return out


def metrics_body(m: pb.Metrics) -> dict[str, Any]:
    """The metrics in the shape of metrics.json (SPEC §4)."""
    collisions = [{"t_s": num(c.t_s), "robot": c.robot, "hand": c.hand, "delay_s": num(c.delay_s)}
                  for c in m.human_robot]
    near = [{"t_s": num(n.t_s)} for n in m.near]
    return {
        "scenario": m.scenario,
        "participant": m.participant,
        "conditions": {"anticipation": m.conditions.anticipation,
                       "safety_policy": m.conditions.safety_policy},
        "seed": int(m.seed),
        "task": {"completion_s": num(m.task_completion_s)},
        "human": {"completion_s": num(m.human_completion_s), "idle_s": num(m.human_idle_s)},
        "robots": {rid: {"completion_s": num(r.completion_s), "idle_s": num(r.idle_s),
                         "avg_tcp_speed_mps": num(r.avg_tcp_speed_mps),
                         "max_tcp_speed_mps": num(r.max_tcp_speed_mps)}
                   for rid, r in sorted(m.robots.items())},
        "collisions": {"human_robot": collisions, "human_robot_count": len(collisions),
                       "total_delay_s": num(m.total_delay_s), "near": near,
                       "near_count": len(near)},
        "parts": {pid: {"grabbed_s": num(p.grabbed_s), "placed_s": num(p.placed_s)}
                  for pid, p in sorted(m.parts.items())},
        "run": {"mode": m.run.mode, "ticks": int(m.run.ticks), "wall_s": num(m.run.wall_s),
                "realtime_factor": num(m.run.realtime_factor)},
    }


def metrics_record(m: pb.Metrics) -> dict[str, Any]:
    r = _head(m, "metrics")
    r["final"] = m.final
    r.update(metrics_body(m))
    return r


def run_end_record(end: pb.RunEnd) -> dict[str, Any]:
    r = _head(end, "run_end")
    r.update({"ok": end.ok, "reason": end.reason, "failed_participant": end.failed_participant,
              "ticks": int(end.ticks), "wall_s": num(end.wall_s),
              "realtime_factor": num(end.realtime_factor)})
    return r
