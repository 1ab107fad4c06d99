"""The trial's files: log.txt, events.jsonl, and the rerun view, fed one message at a time.

Bus-free, so tests can drive it directly; the service's observer calls the handlers in the
deterministic tick order of the bus inbox.
"""

from __future__ import annotations

import logging
from collections import Counter
from pathlib import Path
from typing import TYPE_CHECKING

from hrc import metrics as metrics_schema
from hrc import scenario as sc
from hrc.wire import pb

from hrc_logger.files import JsonlFile, LineFile
from hrc_logger.records import cue_records, event_record, metrics_record, run_end_record
from hrc_logger.textlog import ThesisLog, kind_name, loss_lines, run_end_line

if TYPE_CHECKING:  # rerun is imported only by whoever builds a View (slow to import)
    from hrc_logger.view import View

log = logging.getLogger(__name__)


class TrialRecorder:
    """Writes every task event, cue and final metrics; forwards world state to the view."""

    def __init__(self, out: Path, view: View | None = None) -> None:
        self.out = out
        out.mkdir(parents=True, exist_ok=True)
        self.events = JsonlFile(out / metrics_schema.EVENTS_FILE)
        self.text = LineFile(out / metrics_schema.TEXT_LOG_FILE)
        self.thesis = ThesisLog()
        self.view = view
        self.kinds: Counter[str] = Counter()
        self.cue_changes = 0
        self.last_metrics: pb.MetricsReport | None = None
        self.final_metrics_written = False
        self.task_finished = False
        self.last_task_time = 0.0
        self.task_start_sim: float | None = None  # simulated time of the first grab
        self.closed = False

    def write_settings(self, scenario: pb.Scenario | None) -> None:
        """The first line of log.txt: the trial's conditions, as the thesis logged its
        settings."""
        if scenario is None:
            self.text.write_line("SETTINGS: unknown (no scenario received from the orchestrator)")
            return
        try:
            s = sc.from_proto(scenario)
        except (sc.ScenarioError, ValueError) as exc:  # pydantic's errors are ValueErrors
            self.text.write_line(f"SETTINGS: unreadable scenario ({exc})")
            return
        c = metrics_schema.conditions(s)
        self.text.write_line(metrics_schema.settings_line(s.participant.name, s.scenario.seed, c))

    # ------------------------------------------------------------------ task
    def on_event(self, _key: str, ev: pb.TaskEvent) -> None:
        self.events.write(event_record(ev))
        self.kinds[kind_name(ev.kind)] += 1
        self.last_task_time = max(self.last_task_time, ev.task_time)
        if ev.kind == pb.TASK_EVENT_KIND_TASK_STARTED and self.task_start_sim is None:
            self.task_start_sim = ev.header.sim_time - ev.task_time
        lines = self.thesis.lines_for(ev)
        for line in lines:
            self.text.write_line(line)
        if ev.kind == pb.TASK_EVENT_KIND_TASK_FINISHED:
            self.task_finished = True
        if self.view is not None:
            self.view.event(ev, lines[0] if lines else None)

    def on_indicators(self, _key: str, ind: pb.Indicators) -> None:
        for r in cue_records(ind):
            self.events.write(r)
            self.cue_changes += 1
        if self.view is not None:
            self.view.indicators(ind)

    def on_metrics(self, _key: str, m: pb.MetricsReport) -> None:
        self.last_metrics = m
        if m.final:
            self.events.write(metrics_record(m))
            self.final_metrics_written = True

    # ------------------------------------------------------------------ world (view only)
    def on_robot_state(self, _key: str, st: pb.RobotState) -> None:
        if self.view is not None:
            self.view.robot_state(st)

    def on_human_state(self, _key: str, hs: pb.HumanState) -> None:
        if self.view is not None:
            self.view.human_state(hs)

    def on_world_objects(self, _key: str, wo: pb.WorldObjects) -> None:
        if self.view is not None:
            self.view.world_objects(wo)

    def on_world_contacts(self, _key: str, wc: pb.WorldContacts) -> None:
        if self.view is not None:
            self.view.world_contacts(wc)

    def on_tick(self, tick: pb.ClockTick) -> None:
        if self.view is not None:
            self.view.tick(tick.header.tick, tick.header.sim_time)

    # ------------------------------------------------------------------ end
    def finish(
        self,
        run_end: pb.RunEnd | None,
        reason: str = "",
        losses: list[pb.LossSpan] | None = None,
    ) -> None:
        """Closing lines (metrics if no final ones came, what the recording lost, run end, why
        the log stops), then close. ``losses``: the spans of simulated time in which messages
        never reached the logger."""
        if self.closed:
            return
        self.closed = True
        try:
            if not self.final_metrics_written and self.last_metrics is not None:
                self.events.write(metrics_record(self.last_metrics))  # final = false: say so
            # without run/end (the clock master is gone, a stop) the record still says why
            ended = run_end if run_end is not None else pb.RunEnd(ok=False, reason=reason)
            self.events.write(run_end_record(ended))
            # the closing line carries the time of the end, not that of the last event
            at = self.last_task_time
            if run_end is not None and self.task_start_sim is not None:
                at = max(at, run_end.sim_time - self.task_start_sim)
            start = self.task_start_sim or 0.0
            for lost in loss_lines(losses or [], start):
                self.text.write_line(lost)
            line = run_end_line(run_end, reason, self.task_finished, at)
            if line is not None:
                self.text.write_line(line)
        finally:
            self.events.close()
            self.text.close()
            if self.view is not None:
                self.view.close()
