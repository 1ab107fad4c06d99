"""A readable summary of a trial's metrics.json, printed by ``hrc run``.

metrics.json is read back into `pb.Metrics` (`hrc.metrics.from_dict`), so the summary names the
schema's fields and cannot drift from it.
"""

from __future__ import annotations

import contextlib
import json
from pathlib import Path
from typing import Any

from google.protobuf.message import Message

from hrc import metrics as metrics_schema
from hrc.wire import pb
from hrc.wire.jsonmap import enum_text


def _f(v: float | None, unit: str = "", digits: int = 2) -> str:
    return "-" if v is None else f"{v:.{digits}f}{unit}"


def _opt(msg: Message, name: str) -> float | None:
    """An optional field's value, None when unset."""
    value: float = getattr(msg, name)
    return value if msg.HasField(name) else None


def format_summary(m: pb.Metrics, logger: dict[str, Any] | None = None) -> list[str]:
    c = m.conditions
    speeds = ", ".join(f"{rid} {c.robots[rid].max_tcp_speed:g} m/s" for rid in sorted(c.robots))
    policy = enum_text(pb.SafetyPolicy.DESCRIPTOR, c.safety_policy) or "?"
    source = enum_text(pb.InputSource.DESCRIPTOR, c.participant.input) or "?"
    lines = [
        f"scenario {m.scenario}, participant {m.participant}, seed {m.seed}",
        f"conditions          anticipation {'on' if c.anticipation else 'off'}, policy {policy}, "
        f"{speeds or 'no robots'}, participant {source} (all: metrics.json)",
        f"task completion     {_f(_opt(m.task, 'completion_s'), ' s')} "
        f"(robots home {_f(_opt(m.task, 'completion_home_s'), ' s')})",
        f"human               done {_f(_opt(m.human, 'completion_s'), ' s')}, "
        f"idle {_f(m.human.idle_s, ' s')}",
    ]
    for rid in sorted(m.robots):
        r = m.robots[rid]
        lines.append(
            f"robot {rid:<13} done {_f(_opt(r, 'completion_s'), ' s')} "
            f"(home {_f(_opt(r, 'completion_home_s'), ' s')}), idle {_f(r.idle_s, ' s')}, "
            f"TCP avg moving {_f(r.avg_tcp_speed_mps, ' m/s', 3)}"
            f" (over time {_f(r.avg_tcp_speed_over_time_mps, ' m/s', 3)})"
            f" max {_f(r.max_tcp_speed_mps, ' m/s', 3)}"
        )
    col = m.collisions
    lines.append(
        f"collisions          human-robot {col.human_robot_count} "
        f"(delay {_f(col.total_delay_s, ' s')}), robot-robot near {col.near_count}"
    )
    run = m.run
    mode = enum_text(pb.ClockMode.DESCRIPTOR, run.mode) or "?"
    lines.append(
        f"run                 {mode}, {run.ticks if m.HasField('run') else '?'} ticks, "
        f"{_f(_opt(run, 'wall_s'), ' s wall')}, "
        f"{_f(_opt(run, 'realtime_factor'), 'x realtime', 1)}"
    )
    if logger:
        # The logger runs at a lower priority during the run and catches up at the end.
        lines.append(
            f"logger lag          mean {_f(logger.get('lag_mean_ticks'), ' ticks', 1)}, "
            f"max {logger.get('lag_max_ticks', '-')} ticks (it yields the CPU, then "
            "catches up)"
        )
    if m.recording.lost_messages:
        spans = ", ".join(f"{sp.from_s:.1f}-{sp.to_s:.1f} s" for sp in m.recording.loss_spans)
        lines.append(
            f"recording           INCOMPLETE: {m.recording.lost_messages} message(s) lost "
            f"(simulated time {spans})"
        )
    return lines


def print_summary(trial_dir: Path, result: Any) -> None:
    path = trial_dir / "metrics.json"
    try:
        m = metrics_schema.from_dict(json.loads(path.read_text()))
    except (OSError, ValueError) as exc:  # JSONDecodeError is a ValueError
        print(f"trial finished but {path} is unreadable: {exc}")
        return
    logger: dict[str, Any] | None = None
    stats = trial_dir / "logger_stats.json"  # written by the logger, which measures its own lag
    if stats.exists():
        with contextlib.suppress(OSError, json.JSONDecodeError):
            logger = json.loads(stats.read_text())
    print("\n".join(format_summary(m, logger)))
    print(f"files: {trial_dir}")
