"""A readable summary of a trial's metrics.json, printed by ``hrc run``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any


def _f(v: Any, unit: str = "", digits: int = 2) -> str:
    if isinstance(v, (int, float)):
        return f"{v:.{digits}f}{unit}"
    return "-"


def format_summary(m: dict[str, Any]) -> list[str]:
    lines = [f"scenario {m.get('scenario', '?')}, participant {m.get('participant', '?')}, "
             f"seed {m.get('seed', '?')}, conditions {json.dumps(m.get('conditions', {}))}"]
    task = m.get("task")
    if task:
        lines.append(f"task completion     {_f(task.get('completion_s'), ' s')}")
    human = m.get("human")
    if human:
        lines.append(f"human               done {_f(human.get('completion_s'), ' s')}, "
                     f"idle {_f(human.get('idle_s'), ' s')}")
    for rid, r in sorted((m.get("robots") or {}).items()):
        lines.append(f"robot {rid:<13} done {_f(r.get('completion_s'), ' s')}, "
                     f"idle {_f(r.get('idle_s'), ' s')}, TCP avg {_f(r.get('avg_tcp_speed_mps'), ' m/s', 3)}"
                     f" max {_f(r.get('max_tcp_speed_mps'), ' m/s', 3)}")
    col = m.get("collisions")
    if col:
        lines.append(f"collisions          human-robot {col.get('human_robot_count', 0)} "
                     f"(delay {_f(col.get('total_delay_s'), ' s')}), "
                     f"robot-robot near {col.get('near_count', 0)}")
    run = m.get("run", {})
    lines.append(f"run                 {run.get('mode', '?')}, {run.get('ticks', '?')} ticks, "
                 f"{_f(run.get('wall_s'), ' s wall')}, {_f(run.get('realtime_factor'), 'x realtime', 1)}")
    lag = m.get("logger")
    if lag:
        # The logger only gets CPU time nobody else wants (SCHED_IDLE) and catches up at the end.
        lines.append(f"logger lag          mean {_f(lag.get('lag_mean_ticks'), ' ticks', 1)}, "
                     f"max {lag.get('lag_max_ticks', '-')} ticks (it yields the CPU, then catches up)")
    return lines


def print_summary(trial_dir: Path, result: Any) -> None:
    path = trial_dir / "metrics.json"
    try:
        m = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        print(f"trial finished but {path} is unreadable: {exc}")
        return
    stats = trial_dir / "logger_stats.json"  # written by the logger, which measures its own lag
    if stats.exists() and "logger" not in m:
        try:
            m["logger"] = json.loads(stats.read_text())
        except (OSError, json.JSONDecodeError):
            pass
    print("\n".join(format_summary(m)))
    print(f"files: {trial_dir}")
