"""The logger service (``hrc-logger``): observes the session, never acks.

Writes into the trial folder (``--out``): ``log.txt`` (thesis style), ``events.jsonl``,
``recording.rrd`` (always) and ``logger_stats.json`` (lag behind the clock, sequence gaps);
``--viewer`` also streams to a spawned native rerun viewer, ``--web`` serves the web viewer.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hrc.atomic import write_json_atomic
from hrc.bus import Bus, Observer, Outcome
from hrc.bus.bus import M
from hrc.priority import leave_idle, thread_ids
from hrc.service import EXIT_BAD_INPUT, Inputs, Service, ServiceExit
from hrc.wire import pb
from hrc.wire.jsonmap import message_to_dict

from hrc_logger.recorder import TrialRecorder

if TYPE_CHECKING:
    from hrc_logger.view import View

# At most this long for the view's set-up (scenario, rerun, URDFs) beyond the scenario timeout.
VIEW_SETUP_S = 60.0
STOP_VIEW_WAIT_S = 0.5  # after a stop signal (hrc.service_table.STOP_GRACE_S is 2 s)

log = logging.getLogger("hrc_logger")

RRD_FILE = "recording.rrd"
STATS_FILE = "logger_stats.json"


def fetch_scenario(bus: Bus, timeout: float) -> pb.Scenario | None:
    try:
        return bus.get_one(bus.keys.scenario(), pb.Scenario, timeout=timeout)
    except TimeoutError as exc:
        log.warning(
            "no scenario (%s): the view will lack robots' URDFs, targets and workspace", exc
        )
        return None


def recording_metrics(obs: Observer, timeline: str) -> pb.RecordingMetrics:
    """What never reached the logger, and when (simulated time; the clock's gaps tell)."""
    dt = obs.last_tick.dt if obs.last_tick is not None else 0.0
    rec = pb.RecordingMetrics(lost_messages=obs.seq.lost)
    for sp in obs.seq.loss_spans(timeline):
        rec.loss_spans.add(from_s=sp.from_tick * dt, to_s=sp.to_tick * dt, messages=sp.messages)
    return rec


def stats_dict(
    obs: Observer,
    rec: TrialRecorder,
    view: View | None,
    bus: Bus,
    handler_errors: int,
    recording: pb.RecordingMetrics,
) -> dict[str, Any]:
    return {
        "lag_mean_ticks": round(obs.lag.mean_ticks, 3),
        "lag_max_ticks": obs.lag.max_ticks,
        "lag_mean_ms": round(obs.lag.mean_wall_s * 1e3, 3),
        "lag_max_ms": round(obs.lag.max_wall_s * 1e3, 3),
        "ticks": obs.lag.ticks,
        "messages": obs.seq.messages,
        "seq_gaps": obs.seq.gaps,
        "lost_messages": obs.seq.lost,
        # what hrc run puts into metrics.json: when messages were lost (pb.RecordingMetrics)
        "recording": message_to_dict(recording),
        "missing_inputs": obs.missing_inputs,
        "decode_errors": sum(bus.stats.decode_errors.values()),
        "handler_errors": handler_errors,
        "events": sum(rec.kinds.values()),
        "cue_changes": rec.cue_changes,
        "rerun_logs": view.logged if view is not None else 0,
    }


def lower_priority(sched: str, nice: int, exclude: set[int]) -> bool:
    """Lowers every thread but ``exclude`` (zenoh's included) as ``--sched`` says; True if
    they are now SCHED_IDLE."""
    tids = thread_ids(None, exclude)
    if sched == "idle" and hasattr(os, "SCHED_IDLE"):
        try:
            for tid in tids:
                with contextlib.suppress(ProcessLookupError):  # a thread that just ended
                    os.sched_setscheduler(tid, os.SCHED_IDLE, os.sched_param(0))
            return True
        except OSError as exc:
            log.warning("SCHED_IDLE refused (%s); using nice %d instead", exc, nice)
            sched = "nice"
    if sched in ("idle", "nice") and nice:
        for tid in tids:
            with contextlib.suppress(ProcessLookupError):
                prio = os.getpriority(os.PRIO_PROCESS, tid)
                os.setpriority(os.PRIO_PROCESS, tid, min(19, prio + nice))
    return False


class LoggerService(Service):
    """Hands every message of the session to the trial recorder, tick by tick."""

    name = "logger"

    @classmethod
    def add_arguments(cls, p: argparse.ArgumentParser) -> None:
        p.add_argument("--out", required=True, help="trial folder (created if missing)")
        p.add_argument(
            "--sched",
            choices=["idle", "nice", "normal"],
            default="idle",
            help="CPU priority of this observer during the run: idle (Linux SCHED_IDLE: only "
            "CPU time nobody else wants; in lockstep, where the clock waits for the observer, "
            "--nice instead; the default), nice (--nice added), normal",
        )
        p.add_argument(
            "--nice", type=int, default=10, help="niceness added with --sched nice (default 10)"
        )
        p.add_argument(
            "--viewer", action="store_true", help="also stream to a spawned native rerun viewer"
        )
        p.add_argument(
            "--viewer-port",
            type=int,
            default=9876,
            help="port of the spawned viewer (default 9876)",
        )
        p.add_argument(
            "--web",
            action="store_true",
            help="also serve the rerun web viewer on http://127.0.0.1:WEB_PORT",
        )
        p.add_argument("--web-port", type=int, default=9090, help="web viewer port (default 9090)")
        p.add_argument(
            "--grpc-port",
            type=int,
            default=9877,
            help="gRPC port the web viewer reads the data from (default 9877)",
        )
        p.add_argument(
            "--no-view",
            action="store_true",
            help=f"no 3D recording ({RRD_FILE}) and no viewer: log.txt, events.jsonl and the "
            "statistics only (a study's trials that only need their metrics)",
        )
        p.add_argument(
            "--view-hz",
            type=float,
            default=30.0,
            help="robot/hand/object updates per simulated second in the view (default 30)",
        )
        p.add_argument(
            "--scenario-timeout",
            type=float,
            default=30.0,
            help="seconds to wait for the orchestrator's scenario (default 30; without "
            "it the view shows TCPs, hands and objects but no URDF robots, "
            "targets or workspace)",
        )

    def __init__(self, args: argparse.Namespace) -> None:
        super().__init__(args)
        if not args.view_hz > 0:
            raise ServiceExit(f"--view-hz must be > 0, got {args.view_hz}", EXIT_BAD_INPUT)
        if args.no_view and (args.viewer or args.web):
            raise ServiceExit("--no-view leaves nothing for --viewer or --web", EXIT_BAD_INPUT)
        self._view_ready = threading.Event()
        self._view_lock = threading.Lock()
        self._view_abandoned = False
        # rerun's import and the URDFs on a thread of their own, at the normal priority: they
        # must not wait for idle CPU while the run goes on. Started once the bus is joined (it
        # needs the scenario from it): the process joins with one thread, as the others do.
        self._view_thread = threading.Thread(target=self._open_view, name="view-setup", daemon=True)
        self._priority_set = False  # see _priority
        self._lowered = False
        self.out = Path(args.out)
        self.out.mkdir(parents=True, exist_ok=True)
        self.handler_errors = 0
        self._first = True

    def open(self, bus: Bus, stack: contextlib.ExitStack) -> None:
        super().open(bus, stack)
        self.scenario: pb.Scenario | None = None
        self.view: View | None = None
        self.recorder = TrialRecorder(self.out)
        # The view (scenario, rerun's import, the URDFs: seconds) is built on a thread of its
        # own while the run starts: the clock need not wait for it, the messages wait in the
        # inbox, and the first one handled waits for the view (_view_up).
        self._view_thread.start()
        log.info("observing session %s; writing %s", bus.keys.session, self.out)

    def _open_view(self) -> None:
        args, t0 = self.args, time.monotonic()
        try:
            # The scenario before rerun's import (seconds where the logger was not forked ready):
            # a short run is over by then, and the orchestrator that answers with it gone.
            self.scenario = fetch_scenario(self.bus, args.scenario_timeout)
            # log.txt's first line; events wait for the view (_view_up), so none comes before
            self.recorder.write_settings(self.scenario)
            if args.no_view:
                log.info("no view (--no-view): no %s", RRD_FILE)
                return
            from hrc_logger.view import View, ViewSettings, open_recording

            rec = open_recording(
                self.out / RRD_FILE,
                self.bus.keys.session,
                viewer=args.viewer,
                web=args.web,
                viewer_port=args.viewer_port,
                web_port=args.web_port,
                grpc_port=args.grpc_port,
            )
            # time series in small batches if someone watches, else every few seconds (a
            # logger stopped before the end keeps what it had sent)
            live = args.viewer or args.web
            view = View(
                rec, ViewSettings(view_hz=args.view_hz, series_flush_s=0.25 if live else 5.0)
            )
            view.setup(self.scenario)
            with self._view_lock:
                if not self._view_abandoned:
                    self.view = self.recorder.view = view
            log.info("view ready (%.1f s)", time.monotonic() - t0)
        except Exception:
            log.exception("the view could not be set up: no %s (the text logs go on)", RRD_FILE)
        finally:
            self._view_ready.set()

    def _priority(self) -> None:
        """An observer must never slow the co-simulation down: once the run is on (the first
        tick we handle, whose mode we then know), every thread but the view's set-up gets a
        lower priority. In realtime ``--sched``'s (the barrier's participants get the CPU
        first; the lag behind the clock is measured and reported instead). In lockstep
        ``idle`` means niceness ``--nice`` instead: the clock waits for our acks (a window of
        ticks), so under SCHED_IDLE beside busy processes (another trial, a build) no thread
        of ours, Zenoh's included, got the CPU for 10 s and the run failed naming us; a nice
        thread still gets a share. Not before the run: at a lower priority the start-up
        (imports, zenoh's session, the token) waited for CPU the other services were using
        while they waited for our token (seconds on a busy machine). Once the run is over
        nobody waits on our account: catch up at the normal priority (hrc run waits for our
        files)."""
        obs = self.observer
        ended = obs is not None and obs.ended
        if not self._priority_set:
            mode = obs.mode if obs is not None else None
            if mode is None and not ended:
                return  # no tick handled yet: decide with the first one
            self._priority_set = True
            if not ended:
                sched = self.args.sched
                if sched == "idle" and mode == pb.CLOCK_MODE_LOCKSTEP:
                    sched = "nice"
                view = self._view_thread.native_id if self._view_thread.is_alive() else None
                self._lowered = lower_priority(sched, self.args.nice, {view} if view else set())
        elif self._lowered and ended:
            self._lowered = False
            leave_idle()

    def _view_up(self) -> None:
        """Waits (once) until the view is set up or has failed; a run that was stopped waits
        at most STOP_VIEW_WAIT_S (the text logs must be written within the stop's grace)."""
        if self._view_ready.is_set():
            return
        t0 = time.monotonic()
        limit = self.args.scenario_timeout + VIEW_SETUP_S
        while not self._view_ready.wait(0.05):
            waited = time.monotonic() - t0
            obs = self.observer
            if waited >= limit or (obs is not None and obs.hurried and waited >= STOP_VIEW_WAIT_S):
                with self._view_lock:
                    self._view_abandoned = True
                log.error("the view is not set up after %.1f s: logging without it", waited)
                self._view_ready.set()

    def _guarded(self, handler: Callable[[str, M], None]) -> Callable[[str, M], None]:
        # A failing view update must not cost the text logs anything: log, count, go on.
        def call(key: str, msg: M) -> None:
            self._priority()
            self._view_up()
            try:
                handler(key, msg)
            except Exception:
                self.handler_errors += 1
                log.exception("handling a message on %s failed", key)

        return call

    def register_inputs(self, inputs: Inputs) -> None:
        keys, rec, g = self.bus.keys, self.recorder, self._guarded
        # Registration order is the hand-over order within a tick (Inbox): task first.
        inputs.input(keys.task_events(), pb.TaskEvent, g(rec.on_event))
        inputs.input(keys.task_indicators(), pb.Indicators, g(rec.on_indicators))
        inputs.input(keys.task_metrics(), pb.MetricsReport, g(rec.on_metrics))
        if not self.args.no_view:
            # The world's state is the view's alone: without one the logger does not subscribe
            # to it (most of the session's messages: a robot's state every tick it moves), so
            # nobody routes, sends or decodes them for it.
            inputs.input(keys.world_objects(), pb.WorldObjects, g(rec.on_world_objects))
            inputs.input(keys.world_contacts(), pb.WorldContacts, g(rec.on_world_contacts))
            inputs.input(keys.robot_states(), pb.RobotState, g(rec.on_robot_state))
            inputs.input(keys.human_state(), pb.HumanState, g(rec.on_human_state))
        if self.observer is not None:
            # The orchestrator's final metrics (with the run's figures) come after run/end.
            self.observer.after_end(keys.task_metrics(), "orchestrator")

    def step(self, tick: pb.ClockTick) -> None:
        self._priority()
        self._view_up()
        if self._first and self.scenario is None and self.view is not None and tick.dt > 0:
            self.view.set_tick_hz(1.0 / tick.dt)
        self._first = False

        def on_tick(_key: str, t: pb.ClockTick) -> None:
            self.recorder.on_tick(t)

        self._guarded(on_tick)(self.bus.keys.clock(), tick)

    def finish(self, outcome: Outcome) -> int | None:
        self._view_up()
        obs = self.observer
        assert obs is not None, "run_service sets the observer"
        recording = recording_metrics(obs, self.bus.keys.clock())
        self.recorder.finish(outcome.run_end, outcome.reason, list(recording.loss_spans))
        stats = stats_dict(obs, self.recorder, self.view, self.bus, self.handler_errors, recording)
        write_json_atomic(self.out / STATS_FILE, stats)
        log.info(
            "logger summary: %d ticks, %d messages, lag mean %.1f / max %d ticks "
            "(%.1f / %.1f ms), %d sequence gap(s), %d event(s), %d cue change(s)",
            stats["ticks"],
            stats["messages"],
            stats["lag_mean_ticks"],
            stats["lag_max_ticks"],
            stats["lag_mean_ms"],
            stats["lag_max_ms"],
            stats["seq_gaps"],
            stats["events"],
            stats["cue_changes"],
        )
        if stats["seq_gaps"]:
            log.error(
                "%d sequence gap(s), %d message(s) lost", stats["seq_gaps"], stats["lost_messages"]
            )
        return None
