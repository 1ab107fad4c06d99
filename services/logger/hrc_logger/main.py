"""Entry point of the logger service (``hrc-logger``): observes the session, never acks.

Writes into the trial folder (``--out``): ``log.txt`` (thesis style), ``events.jsonl``,
``recording.rrd`` (always) and ``logger_stats.json`` (lag behind the clock, sequence gaps);
``--viewer`` also streams to a spawned native rerun viewer, ``--web`` serves the web viewer.
"""

from __future__ import annotations

import argparse
import os
import logging
import signal
from pathlib import Path
from types import FrameType
from typing import Any

from google.protobuf.message import Message

from hrc.bus import Bus, Outcome, add_bus_arguments, bus_config_from_args
from hrc.logsetup import setup_logging
from hrc.wire import pb

from hrc_logger.files import write_json_atomic
from hrc_logger.observer import Observer
from hrc_logger.recorder import TrialRecorder
from hrc_logger.view import View, ViewSettings, open_recording

log = logging.getLogger("hrc_logger")

NAME = "logger"
RRD_FILE = "recording.rrd"
STATS_FILE = "logger_stats.json"


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="hrc-logger", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    add_bus_arguments(p)
    p.add_argument("--out", required=True, help="trial folder (created if missing)")
    p.add_argument("--sched", choices=["idle", "nice", "normal"], default="idle",
                   help="CPU priority of this observer: idle (Linux SCHED_IDLE: only CPU time nobody "
                        "else wants; the default), nice (--nice added), normal")
    p.add_argument("--nice", type=int, default=10,
                   help="niceness added with --sched nice (default 10)")
    p.add_argument("--viewer", action="store_true", help="also stream to a spawned native rerun viewer")
    p.add_argument("--viewer-port", type=int, default=9876, help="port of the spawned viewer (default 9876)")
    p.add_argument("--web", action="store_true",
                   help="also serve the rerun web viewer on http://127.0.0.1:WEB_PORT")
    p.add_argument("--web-port", type=int, default=9090, help="web viewer port (default 9090)")
    p.add_argument("--grpc-port", type=int, default=9877,
                   help="gRPC port the web viewer reads the data from (default 9877)")
    p.add_argument("--view-hz", type=float, default=30.0,
                   help="robot/hand/object updates per simulated second in the view (default 30)")
    p.add_argument("--scenario-timeout", type=float, default=30.0,
                   help="seconds to wait for the orchestrator's scenario (default 30; without it the "
                        "view shows TCPs, hands and objects but no URDF robots, targets or workspace)")
    p.add_argument("--input-timeout", type=float, default=10.0,
                   help="seconds to wait for the inputs a clock tick lists before reporting them lost")
    p.add_argument("--log-level", default=None)
    args = p.parse_args(argv)
    if not args.view_hz > 0:
        p.error(f"--view-hz must be > 0, got {args.view_hz}")
    return args


def fetch_scenario(bus: Bus, timeout: float) -> pb.Scenario | None:
    try:
        return bus.get_one(bus.keys.scenario(), pb.Scenario, timeout=timeout)
    except TimeoutError as exc:
        log.warning("no scenario (%s): the view will lack robots' URDFs, targets and workspace", exc)
        return None


def stats_dict(obs: Observer, rec: TrialRecorder, view: View, bus: Bus, handler_errors: int) -> dict[str, Any]:
    return {
        "lag_mean_ticks": round(obs.lag.mean_ticks, 3),
        "lag_max_ticks": obs.lag.max_ticks,
        "lag_mean_ms": round(obs.lag.mean_wall_s * 1e3, 3),
        "lag_max_ms": round(obs.lag.max_wall_s * 1e3, 3),
        "ticks": obs.lag.ticks,
        "messages": obs.seq.messages,
        "seq_gaps": obs.seq.gaps,
        "lost_messages": obs.seq.lost,
        "missing_inputs": obs.missing_inputs,
        "decode_errors": sum(bus.stats.decode_errors.values()),
        "handler_errors": handler_errors,
        "events": sum(rec.kinds.values()),
        "cue_changes": rec.cue_changes,
        "rerun_logs": view.logged,
    }


def lower_priority(sched: str, nice: int) -> None:
    if sched == "idle" and hasattr(os, "SCHED_IDLE"):
        try:
            os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
            return
        except OSError as exc:
            log.warning("SCHED_IDLE refused (%s); using nice %d instead", exc, nice)
            sched = "nice"
    if sched in ("idle", "nice") and nice:
        os.nice(nice)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    setup_logging(NAME, args.log_level)
    # An observer must never slow the co-simulation down: the barrier's participants get the CPU
    # first. Its lag behind the clock is measured and reported instead. Set before any thread
    # starts (zenoh's, rerun's): on Linux the policy is per thread and new threads inherit it.
    lower_priority(args.sched, args.nice)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    handler_errors = 0
    with Bus(bus_config_from_args(args), NAME) as bus:
        scenario = fetch_scenario(bus, args.scenario_timeout)
        rec = open_recording(out / RRD_FILE, bus.keys.session, viewer=args.viewer, web=args.web,
                             viewer_port=args.viewer_port, web_port=args.web_port,
                             grpc_port=args.grpc_port)
        view = View(rec, ViewSettings(view_hz=args.view_hz))
        view.setup(scenario)
        recorder = TrialRecorder(out, view)
        obs = Observer(bus, input_timeout_s=args.input_timeout)

        def guarded(handler: Any) -> Any:
            # A failing view update must not cost the text logs anything: log, count, go on.
            def call(key: str, msg: Message) -> None:
                nonlocal handler_errors
                try:
                    handler(key, msg)
                except Exception:
                    handler_errors += 1
                    log.exception("handling a message on %s failed", key)
            return call

        keys = bus.keys
        # Subscription order is the hand-over order within a tick (Inbox): task first.
        obs.input(keys.task_events(), pb.TaskEvent, guarded(recorder.on_event))
        obs.input(keys.task_indicators(), pb.Indicators, guarded(recorder.on_indicators))
        obs.input(keys.task_metrics(), pb.MetricsReport, guarded(recorder.on_metrics))
        obs.input(keys.world_objects(), pb.WorldObjects, guarded(recorder.on_world_objects))
        obs.input(keys.world_contacts(), pb.WorldContacts, guarded(recorder.on_world_contacts))
        obs.input(keys.robot_states(), pb.RobotState, guarded(recorder.on_robot_state))
        obs.input(keys.human_state(), pb.HumanState, guarded(recorder.on_human_state))

        first = True

        def step(tick: pb.ClockTick) -> None:
            nonlocal first
            if first and scenario is None and tick.dt > 0:
                view.set_tick_hz(1.0 / tick.dt)
            first = False
            guarded(lambda _k, t: recorder.on_tick(t))(keys.clock(), tick)

        obs.on_tick(step)

        def on_signal(signum: int, _frame: FrameType | None) -> None:
            obs.stop(Outcome(False, f"terminated by {signal.Signals(signum).name}"), hurry=True)

        signal.signal(signal.SIGTERM, on_signal)
        signal.signal(signal.SIGINT, on_signal)
        obs.start()
        log.info("observing session %s; writing %s", keys.session, out)
        outcome = obs.run()
        recorder.finish(outcome.run_end, outcome.reason)
        stats = stats_dict(obs, recorder, view, bus, handler_errors)
        write_json_atomic(out / STATS_FILE, stats)
        log.info("logger summary: %d ticks, %d messages, lag mean %.1f / max %d ticks "
                 "(%.1f / %.1f ms), %d sequence gap(s), %d event(s), %d cue change(s)",
                 stats["ticks"], stats["messages"], stats["lag_mean_ticks"], stats["lag_max_ticks"],
                 stats["lag_mean_ms"], stats["lag_max_ms"], stats["seq_gaps"], stats["events"],
                 stats["cue_changes"])
        if stats["seq_gaps"]:
            log.error("%d sequence gap(s), %d message(s) lost", stats["seq_gaps"], stats["lost_messages"])
        if not outcome.ok:
            log.error("run ended with an error: %s", outcome.reason)
        return outcome.exit_code


if __name__ == "__main__":
    raise SystemExit(main())
