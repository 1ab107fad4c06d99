"""The orchestrator service (``hrc-orchestrator``).

Loads and serves the scenario, takes part in the clock, feeds each tick's inputs to the task
logic (`hrc_orchestrator.task.Task`) and publishes what it decides; writes metrics.json at the end.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import math
from pathlib import Path

from google.protobuf.message import Message

from hrc import scenario as scenario_mod
from hrc.bus import Bus, Outcome
from hrc.bus.bus import Validator
from hrc.bus.lockstep import opens_exchange
from hrc.service import EXIT_BAD_INPUT, Inputs, Service, ServiceExit
from hrc.validate import check_pose
from hrc.wire import pb

from hrc_orchestrator import metrics
from hrc_orchestrator.metrics_file import write_json
from hrc_orchestrator.task import Inputs as TaskInputs
from hrc_orchestrator.task import Outputs, Task

log = logging.getLogger("hrc_orchestrator")


# ---------------------------------------------------------------- input validation
def make_validators(robot_ids: list[str]) -> dict[str, Validator]:
    def robot_state(msg: Message) -> str | None:
        assert isinstance(msg, pb.RobotState)
        if msg.robot not in robot_ids:
            return f"unknown robot {msg.robot!r}"
        if not math.isfinite(msg.tcp_speed):
            return "tcp_speed is NaN or infinite"
        return check_pose(msg.tcp)

    def world_objects(msg: Message) -> str | None:
        assert isinstance(msg, pb.WorldObjects)
        for obj in msg.objects:
            if (problem := check_pose(obj.pose)) is not None:
                return f"object {obj.id!r}: {problem}"
        for e in msg.events:
            if (problem := check_pose(e.pose)) is not None:
                return f"event on {e.object!r}: {problem}"
        return None

    return {"robot_state": robot_state, "world_objects": world_objects}


class OrchestratorService(Service):
    """Wires a Task to the bus: inputs per tick in, outputs out, metrics at the end."""

    name = "orchestrator"

    @classmethod
    def add_arguments(cls, p: argparse.ArgumentParser) -> None:
        p.add_argument("--scenario", required=True, help="scenario TOML file")
        p.add_argument("--out", default=None, help="trial folder for metrics.json (default: none)")
        p.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
        p.add_argument(
            "--metrics-every",
            type=float,
            default=1.0,
            metavar="S",
            help="publish interim metrics every S seconds of task time (0: only final)",
        )
        p.add_argument(
            "--keep-running",
            action="store_true",
            help="do not ask the clock to stop when the task finishes (fixed-length runs)",
        )
        p.add_argument(
            "--no-reach-check",
            action="store_true",
            help="skip the motion check when loading the scenario",
        )
        p.add_argument(
            "--stall-timeout",
            type=float,
            default=None,
            metavar="S",
            help="end the trial after S simulated seconds without progress "
            "(default: the scenario's stall_timeout_s; 0: never)",
        )

    def __init__(self, args: argparse.Namespace) -> None:
        """Loads and checks the scenario before joining the bus."""
        super().__init__(args)
        try:
            self.scenario = scenario_mod.load(args.scenario, motion_check=not args.no_reach_check)
        except scenario_mod.ScenarioError as exc:
            raise ServiceExit(f"scenario rejected:\n{exc}", EXIT_BAD_INPUT) from exc
        except OSError as exc:
            raise ServiceExit(
                f"cannot read scenario {args.scenario}: {exc}", EXIT_BAD_INPUT
            ) from exc
        self.spb = scenario_mod.to_proto(self.scenario)
        if args.seed is not None:
            if args.seed < 0:
                raise ServiceExit(f"--seed must be >= 0, got {args.seed}", EXIT_BAD_INPUT)
            self.spb.info.seed = args.seed
            self.scenario.scenario.seed = args.seed
        self.out_dir = Path(args.out) if args.out else None
        self.seed = int(self.spb.info.seed)
        if args.stall_timeout is not None and not (
            math.isfinite(args.stall_timeout) and args.stall_timeout >= 0
        ):
            raise ServiceExit(
                f"--stall-timeout must be >= 0, got {args.stall_timeout}", EXIT_BAD_INPUT
            )
        self.task = Task(self.scenario, stall_timeout_s=args.stall_timeout)
        self.metrics_every_s = args.metrics_every
        self.keep_running = args.keep_running  # fixed-length runs: no stop at the task's end
        self._next_metrics = self.metrics_every_s
        self._pending = TaskInputs()
        self._stop_sent = False

    def open(self, bus: Bus, stack: contextlib.ExitStack) -> None:
        super().open(bus, stack)
        spb = self.spb
        spb.header.session = bus.keys.session
        spb.header.sender = self.name
        bus.queryable(bus.keys.scenario(), None, lambda _req: spb)
        keys = bus.keys
        robots = self.scenario.robots
        self.cmd_pubs = {rid: bus.publisher(keys.robot_command(rid)) for rid in robots}
        self.world_pub = bus.publisher(keys.world_commands())
        self.events_pub = bus.publisher(keys.task_events())
        self.cues_pub = bus.publisher(keys.task_indicators())
        self.metrics_pub = bus.publisher(keys.task_metrics())
        self.control_pub = bus.publisher(keys.run_control(self.name), express=True)
        log.info(
            "serving scenario %r (seed %d, policy %s, anticipation %s)",
            spb.info.name,
            spb.info.seed,
            self.scenario.conditions.safety_policy,
            spb.conditions.anticipation,
        )

    def register_inputs(self, inputs: Inputs) -> None:
        keys = self.bus.keys
        v = make_validators(list(self.scenario.robots))
        inputs.input(keys.robot_states(), pb.RobotState, self._on_state, v["robot_state"])
        inputs.input(keys.world_objects(), pb.WorldObjects, self._on_objects, v["world_objects"])
        inputs.input(keys.world_contacts(), pb.WorldContacts, self._on_contacts)
        # Not human/state: the task reads the participant only through physics (contacts,
        # grabs, separations); its ~3 states per exchange would cost decoding and an inbox entry.
        if self.task.safety.ssm:  # only under ssm does physics publish separations
            inputs.input(keys.world_separation(), pb.Separations, self._on_separations)

    # ------------------------------------------------------------------ inputs (run() thread)
    def _on_state(self, _key: str, msg: Message) -> None:
        self._pending.robot_states.append(msg)  # type: ignore[arg-type]

    def _on_objects(self, _key: str, msg: Message) -> None:
        self._pending.objects.append(msg)  # type: ignore[arg-type]

    def _on_contacts(self, _key: str, msg: Message) -> None:
        self._pending.contacts.append(msg)  # type: ignore[arg-type]

    def _on_separations(self, _key: str, msg: Message) -> None:
        self._pending.separations.append(msg)  # type: ignore[arg-type]

    # ------------------------------------------------------------------ one tick
    def step(self, tick: pb.ClockTick) -> None:
        k, t = tick.header.tick, tick.header.sim_time
        inputs, self._pending = self._pending, TaskInputs()
        out = self.task.step(k, t, inputs, first=opens_exchange(tick))
        self._publish(out, k, t)

    def next_event_tick(self) -> int:
        return self.task.next_event_tick()

    def next_sample_tick(self) -> tuple[int, int]:
        return self.task.next_scan_tick()

    def _publish(self, out: Outputs, k: int, t: float) -> None:
        # Events first: what happened this tick, then what is done about it.
        for event in out.events:
            # One parseable line per event (tests and people read the service log too).
            log.info(
                "event %s | %s",
                pb.TaskEventKind.Name(event.kind).removeprefix("TASK_EVENT_KIND_"),
                event.text,
            )
            self.events_pub.put(event, k, t)
        for cmd in out.robot_commands:
            if cmd.kind == pb.RobotCommand.KIND_SPEED_SCALE:
                log.debug("command %s speed scale %.2f", cmd.robot, cmd.speed_scale)
                self.cmd_pubs[cmd.robot].put(cmd, k, t)
                continue
            log.info(
                "command %s #%d %s (%.4f, %.4f, %.4f)",
                cmd.robot,
                cmd.command_id,
                pb.RobotCommand.Kind.Name(cmd.kind).removeprefix("KIND_"),
                cmd.target.x,
                cmd.target.y,
                cmd.target.z,
            )
            self.cmd_pubs[cmd.robot].put(cmd, k, t)
        if out.world_commands:
            self.world_pub.put(pb.WorldCommands(commands=out.world_commands), k, t)
        if out.cues:
            self.cues_pub.put(pb.Indicators(cues=out.cues), k, t)
        if self.task.running and self.metrics_every_s > 0 and self.task.now() >= self._next_metrics:
            self._next_metrics += self.metrics_every_s
            self.metrics_pub.put(metrics.report(metrics.build(self.task, self.seed), False), k, t)
        if out.stalled and not self._stop_sent:
            self._stop_sent = True
            log.error("%s", out.stalled)
            self.metrics_pub.put(metrics.report(metrics.build(self.task, self.seed), True), k, t)
            # FAIL, not ABORT: the run ends after this tick on every machine (an abort is
            # acted on at once, mid-exchange, wherever the clock master then is)
            self.control_pub.put(
                pb.RunControl(command=pb.RunControl.COMMAND_FAIL, reason=out.stalled), k, t
            )
        if out.stop and not self._stop_sent:
            self._stop_sent = True
            self.metrics_pub.put(metrics.report(metrics.build(self.task, self.seed), True), k, t)
            if not self.keep_running:
                self.control_pub.put(
                    pb.RunControl(command=pb.RunControl.COMMAND_STOP, reason=out.stop), k, t
                )

    # ------------------------------------------------------------------ the end
    def finish(self, outcome: Outcome) -> int | None:
        run_end = outcome.run_end
        # The run broke off without run/end: say so, keep the task numbers.
        run = (
            metrics.run_metrics(run_end)
            if run_end is not None
            else metrics.broken_off_run(self.task.tick, outcome.reason)
        )
        if self.task.watchdog.message:
            run.end_reason = "stalled"
            run.stall = self.task.watchdog.message
        data = metrics.build(self.task, self.seed, run)
        if run_end is not None:
            try:  # best effort: the run is over, observers may already be leaving
                self.metrics_pub.put(metrics.report(data, True), run_end.ticks, run_end.sim_time)
            except Exception as exc:  # never lose metrics.json over this
                log.warning("could not publish the final metrics: %s", exc)
        if self.out_dir is not None:
            write_json(self.out_dir / "metrics.json", data)
            log.info("wrote %s", self.out_dir / "metrics.json")
        return None
