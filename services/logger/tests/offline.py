"""Feed a synthetic trial straight into a TrialRecorder (no bus): a test double, also handy for
trying the view."""

from __future__ import annotations

from pathlib import Path

from synthetic import Outgoing, SyntheticTrial

from hrc.wire import pb

from hrc_logger.recorder import TrialRecorder
from hrc_logger.view import View, open_recording


def run_offline(trial: SyntheticTrial, out: Path, session: str = "offline") -> TrialRecorder:
    """Writes log.txt, events.jsonl and recording.rrd of ``trial`` into ``out``."""
    view = View(open_recording(out / "recording.rrd", session))
    view.setup(trial.sc)
    rec = TrialRecorder(out, view)
    rec.write_settings(trial.sc)
    handlers = {
        "world_objects": rec.on_world_objects,
        "world_contacts": rec.on_world_contacts,
        "human_state": rec.on_human_state,
        "task_events": rec.on_event,
        "task_indicators": rec.on_indicators,
        "task_metrics": rec.on_metrics,
    }

    def send(o: Outgoing, k: int) -> None:
        o.msg.header.tick = k  # type: ignore[attr-defined]
        o.msg.header.sim_time = k * trial.dt  # type: ignore[attr-defined]
        if o.key.startswith("robot_state:"):
            rec.on_robot_state(o.key, o.msg)  # type: ignore[arg-type]
        else:
            handlers[o.key](o.key, o.msg)  # type: ignore[operator]

    for k, world, outputs in trial.ticks():
        for o in world:
            send(o, k)
        rec.on_tick(pb.ClockTick(header=pb.Header(tick=k, sim_time=k * trial.dt), dt=trial.dt))
        for o in outputs:
            send(o, k)
    rec.finish(pb.RunEnd(ok=True, reason="stopped", ticks=trial.n, sim_time=trial.n * trial.dt))
    return rec
