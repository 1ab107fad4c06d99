"""The numbers of a trial as `pb.Metrics`, the one schema of metrics.json (docs/metrics.md).

The orchestrator fills the message; metrics.json, the published reports and every other form
are produced from it by `hrc.metrics.to_dict`. Times are task times in seconds, rounded to the
microsecond; a time that never happened stays unset (null in JSON).
"""

from __future__ import annotations

from google.protobuf.message import Message

from hrc import metrics as metrics_schema
from hrc.wire import pb

from hrc_orchestrator.task import Task


def _r(x: float) -> float:
    return round(x, 6)


def _set_time(msg: Message, name: str, x: float | None) -> None:
    if x is not None:
        setattr(msg, name, _r(x))


def build(task: Task, seed: int, run: pb.RunMetrics | None = None) -> pb.Metrics:
    """The metrics of the task as it stands; `run` once the run has ended."""
    s = task.scenario
    t_end = task.completion_s if task.completion_s is not None else task.now()
    m = pb.Metrics(scenario=s.scenario.name, participant=s.participant.name, seed=int(seed))
    m.conditions.CopyFrom(metrics_schema.conditions(s))

    m.task.SetInParent()
    m.task.started = task.started
    m.task.finished = task.done
    _set_time(m.task, "completion_s", task.completion_s)
    _set_time(m.task, "completion_home_s", task.completion_home_s)

    human_end = task.human.completion_s if task.human.completion_s is not None else t_end
    m.human.SetInParent()
    _set_time(m.human, "completion_s", task.human.completion_s)
    m.human.idle_s = _r(task.human.idle.value(human_end))

    for rid, agent in task.agents.items():
        r = m.robots[rid]
        _set_time(r, "completion_s", agent.completion_s)
        r.idle_s = _r(agent.idle.value(t_end))
        r.avg_tcp_speed_mps = _r(agent.speed.avg_moving)
        r.max_tcp_speed_mps = _r(agent.speed.max)
        r.avg_tcp_speed_over_time_mps = _r(agent.speed.avg_over_time)
        _set_time(r, "completion_home_s", agent.home_s)
        mon = task.safety.ssm.get(rid)
        if mon is not None:
            r.ssm.SetInParent()
            _set_time(r.ssm, "min_separation_m", mon.min_separation)
            r.ssm.reduced_speed_s = _r(mon.reduced_s)
            r.ssm.protective_stop_count = mon.stops
            r.ssm.protective_stop_s = _r(mon.stop_s)

    col = m.collisions
    col.SetInParent()
    for rec in task.safety.records:
        c = col.human_robot.add(t_s=_r(rec.t_s), robot=rec.robot, hand=rec.hand)
        _set_time(c, "delay_s", rec.delay_s)
    col.human_robot_count = len(task.safety.records)
    col.total_delay_s = _r(task.safety.total_delay)
    for t in task.safety.near_times:
        col.near.add(t_s=_r(t))
    col.near_count = len(task.safety.near_times)

    for p in s.parts:
        part = m.parts[p.id]
        _set_time(part, "grabbed_s", task.board.grabbed_s.get(p.id))
        _set_time(part, "placed_s", task.board.placed_s.get(p.id))
    if run is not None:
        m.run.CopyFrom(run)
    return m


def run_metrics(end: pb.RunEnd) -> pb.RunMetrics:
    """The run section from physics's run/end."""
    return pb.RunMetrics(
        mode=end.mode,
        ticks=end.ticks,
        wall_s=_r(end.wall_s),
        realtime_factor=_r(end.realtime_factor),
        ok=end.ok,
        end_reason=end.reason,
        deadline_misses=dict(end.deadline_misses),
    )


def broken_off_run(ticks: int, reason: str) -> pb.RunMetrics:
    """The run section when the run broke off without run/end: mode and wall time unknown."""
    return pb.RunMetrics(ticks=ticks, ok=False, end_reason=reason)


def report(metrics: pb.Metrics, final: bool) -> pb.MetricsReport:
    """What goes on task/metrics (the header is stamped by the publisher)."""
    return pb.MetricsReport(final=final, metrics=metrics)
