"""The numbers of a trial (SPEC §4), as the metrics.json dict and as `pb.Metrics`.

The dict is the one source; the message is built from it. Times are task times in seconds;
a time that never happened is null in JSON and -1 in the message.
"""

from __future__ import annotations

from typing import Any

from hrc.wire import pb
from hrc_orchestrator.metrics_file import run_section
from hrc_orchestrator.task import Task

NEVER = -1.0


def _r(x: float | None) -> float | None:
    return None if x is None else round(x, 6)


def build(task: Task, seed: int, run_end: pb.RunEnd | None = None) -> dict[str, Any]:
    s = task.scenario
    t_end = task.completion_s if task.completion_s is not None else task.now()
    robots: dict[str, Any] = {}
    for rid, agent in task.agents.items():
        robots[rid] = {
            "completion_s": _r(agent.completion_s),
            "idle_s": _r(agent.idle.value(t_end)),
            "avg_tcp_speed_mps": _r(agent.avg_speed),
            "max_tcp_speed_mps": _r(agent.speed_max),
        }
    human_robot = [{"t_s": _r(rec.t_s), "robot": rec.robot, "hand": rec.hand,
                    "delay_s": _r(rec.delay_s)} for rec in task.safety.records]
    human_end = task.human.completion_s if task.human.completion_s is not None else t_end
    data: dict[str, Any] = {
        "scenario": s.scenario.name,
        "participant": s.participant.name,
        "conditions": {"anticipation": s.conditions.anticipation,
                       "safety_policy": s.conditions.safety_policy},
        "seed": int(seed),
        "task": {
            "started": task.started,
            "finished": task.finished,
            "completion_s": _r(task.completion_s),
        },
        "human": {
            "completion_s": _r(task.human.completion_s),
            "idle_s": _r(task.human.idle.value(human_end)),
        },
        "robots": robots,
        "collisions": {
            "human_robot": human_robot,
            "human_robot_count": len(human_robot),
            "total_delay_s": _r(task.safety.total_delay),
            "near": [{"t_s": _r(t)} for t in task.safety.near_times],
            "near_count": len(task.safety.near_times),
        },
        "parts": {
            p.id: {"grabbed_s": _r(task.board.grabbed_s.get(p.id)),
                   "placed_s": _r(task.board.placed_s.get(p.id))}
            for p in s.parts
        },
    }
    if run_end is not None:
        data["run"] = run_section(run_end)
    return data


def _t(x: float | None) -> float:
    return NEVER if x is None else float(x)


def to_proto(data: dict[str, Any], final: bool) -> pb.Metrics:
    m = pb.Metrics(final=final, scenario=data["scenario"], participant=data["participant"],
                   seed=data["seed"])
    m.conditions.anticipation = data["conditions"]["anticipation"]
    m.conditions.safety_policy = data["conditions"]["safety_policy"]
    m.task_completion_s = _t(data["task"]["completion_s"])
    m.human_completion_s = _t(data["human"]["completion_s"])
    m.human_idle_s = _t(data["human"]["idle_s"])
    for rid, r in data["robots"].items():
        m.robots[rid].CopyFrom(pb.RobotMetrics(
            completion_s=_t(r["completion_s"]), idle_s=_t(r["idle_s"]),
            avg_tcp_speed_mps=_t(r["avg_tcp_speed_mps"]),
            max_tcp_speed_mps=_t(r["max_tcp_speed_mps"])))
    col = data["collisions"]
    for rec in col["human_robot"]:
        m.human_robot.add(t_s=_t(rec["t_s"]), robot=rec["robot"], hand=rec["hand"],
                          delay_s=_t(rec["delay_s"]))
    m.total_delay_s = _t(col["total_delay_s"])
    for near in col["near"]:
        m.near.add(t_s=_t(near["t_s"]))
    for pid, p in data["parts"].items():
        m.parts[pid].CopyFrom(pb.PartMetrics(grabbed_s=_t(p["grabbed_s"]),
                                             placed_s=_t(p["placed_s"])))
    run = data.get("run")
    if run:
        m.run.CopyFrom(pb.RunMetrics(mode=run["mode"], ticks=run["ticks"], wall_s=run["wall_s"],
                                     realtime_factor=run["realtime_factor"]))
    return m
