"""The physics service (``hrc-physics``): the pybullet world and the clock.

Fetches the scenario from the orchestrator, builds the world and is the clock master of the tick
protocol: takes the participants' outputs, publishes the world, steps.
"""

from __future__ import annotations

import argparse
import contextlib
import logging

from hrc import scenario as sc
from hrc.bus import Bus, ClockSettings, Outcome
from hrc.bus.clock import REACTION_TICKS
from hrc.service import EXIT_BAD_INPUT, ClockMasterService, Inputs, ServiceExit, fetch_scenario
from hrc.service_table import OBSERVERS, PARTICIPANTS
from hrc.validate import all_finite, check_pose
from hrc.wire import pb

from hrc_physics.exchange import HAND_SPEED_BOUND, SpanPlanner, arm_levers, arm_speed_terms
from hrc_physics.robots import RobotModelError
from hrc_physics.world import CommandRejected, World, WorldSettings

log = logging.getLogger(__name__)


def _names(text: str) -> list[str]:
    return [n for n in text.split(",") if n]


def _human_ok(msg: pb.HumanState) -> str | None:
    for name in ("head", "left_hand", "right_hand"):
        problem = check_pose(getattr(msg, name))
        if problem:
            return f"{name}: {problem}"
    bound = msg.hand_speed_bound
    if not 0.0 <= bound < float("inf"):  # also false for NaN
        return f"hand_speed_bound = {bound} is not a speed (finite, >= 0)"
    for name in ("left_grip", "right_grip"):
        v = getattr(msg, name)
        if not 0.0 <= v <= 1.0:  # also false for NaN
            return f"{name} = {v} is outside [0, 1]"
    return None


def _robot_ok(msg: pb.RobotState) -> str | None:
    if not all_finite(msg.joint_positions):
        return f"robot {msg.robot!r}: joint positions contain NaN or infinity"
    bounds = msg.joint_speed_fraction_bounds
    if bounds:
        if len(bounds) != len(msg.joint_names):
            return (
                f"robot {msg.robot!r}: {len(bounds)} joint_speed_fraction_bounds for "
                f"{len(msg.joint_names)} joint_names"
            )
        if not all(0.0 <= f < float("inf") for f in bounds):  # also false for NaN
            return f"robot {msg.robot!r}: joint_speed_fraction_bounds must be finite and >= 0"
    linear, angular = msg.link_linear_speed_bounds, msg.link_angular_speed_bounds
    if linear or angular:
        if not bounds or len(linear) != len(angular) or len(linear) > len(msg.joint_names):
            return (
                f"robot {msg.robot!r}: {len(linear)} link_linear_speed_bounds and "
                f"{len(angular)} link_angular_speed_bounds for {len(msg.joint_names)} "
                f"joint_names and {len(bounds)} joint_speed_fraction_bounds (one each per "
                "joint of the chain, with the fractions)"
            )
        if not all(0.0 <= v < float("inf") for v in (*linear, *angular)):
            return f"robot {msg.robot!r}: link speed bounds must be finite and >= 0"
    return None


class PhysicsService(ClockMasterService):
    """Holds the world and feeds it the latest inputs of each participant."""

    name = "physics"

    @classmethod
    def add_arguments(cls, p: argparse.ArgumentParser) -> None:
        p.add_argument(
            "--clock",
            choices=["lockstep", "realtime"],
            default="lockstep",
            help="co-simulation mode (default lockstep)",
        )
        p.add_argument(
            "--ticks", type=int, default=0, help="stop after N ticks (0: when told to stop)"
        )
        p.add_argument(
            "--tick-hz",
            type=float,
            default=0.0,
            help="override the scenario's tick_hz (0: use the scenario's)",
        )
        p.add_argument(
            "--participants",
            default=",".join(PARTICIPANTS),
            help="comma-separated services whose acks close the barrier "
            "(default: the service table's, %(default)s)",
        )
        p.add_argument(
            "--observers",
            default=",".join(OBSERVERS),
            help="comma-separated services that must be present but never ack "
            "(default: the service table's, %(default)s)",
        )
        p.add_argument(
            "--watchers",
            default="",
            help="comma-separated tools whose tokens the first tick waits for, which never "
            "hold the clock nor end the run by leaving (hrc run passes its own: experimenter)",
        )
        p.add_argument(
            "--barrier-timeout",
            type=float,
            default=10.0,
            help="lockstep: seconds a participant may take for one tick (default 10)",
        )
        p.add_argument(
            "--start-timeout",
            type=float,
            default=60.0,
            help="seconds to wait for the scenario and every service (default 60)",
        )
        p.add_argument(
            "--max-span",
            type=int,
            default=None,
            help="lockstep: at most N ticks per exchange, fewer near a hand-arm contact "
            "(1: an exchange every tick; default: the scenario's max_exchange_ticks)",
        )
        p.add_argument(
            "--solver-iterations",
            type=int,
            default=WorldSettings.solver_iterations,
            help="pybullet solver iterations per step (default %(default)s)",
        )

    def __init__(self, args: argparse.Namespace) -> None:
        super().__init__(args)
        if args.ticks < 0:
            raise ServiceExit(f"--ticks must be >= 0, got {args.ticks}", EXIT_BAD_INPUT)
        if args.max_span is not None and args.max_span < 1:
            raise ServiceExit(f"--max-span must be >= 1, got {args.max_span}", EXIT_BAD_INPUT)
        if args.solver_iterations < 1:
            raise ServiceExit(
                f"--solver-iterations must be >= 1, got {args.solver_iterations}", EXIT_BAD_INPUT
            )
        self.pending_commands: list[pb.WorldCommand] = []

    def open(self, bus: Bus, stack: contextlib.ExitStack) -> None:
        super().open(bus, stack)
        args = self.args
        self.scenario = fetch_scenario(bus, args.start_timeout)
        tick_hz = args.tick_hz or self.scenario.info.tick_hz or 240.0
        try:
            self.settings = ClockSettings(
                mode=args.clock,
                tick_hz=tick_hz,
                ticks=args.ticks,
                participants=_names(args.participants),
                observers=_names(args.observers),
                watchers=_names(args.watchers),
                barrier_timeout_s=args.barrier_timeout,
                start_timeout_s=args.start_timeout,
            )
        except ValueError as exc:
            raise ServiceExit(str(exc), EXIT_BAD_INPUT) from exc
        try:
            typed = sc.from_proto(self.scenario)  # raises ScenarioError naming the bad field
            self.world = World(
                typed, WorldSettings(dt=1.0 / tick_hz, solver_iterations=args.solver_iterations)
            )
        except (sc.ScenarioError, RobotModelError) as exc:
            raise ServiceExit(f"cannot build the world: {exc}") from exc
        stack.callback(self.close)
        self.planner = SpanPlanner(
            dt=1.0 / tick_hz,
            arm_terms={rid: arm_speed_terms(r) for rid, r in self.world.robots.items()},
            arm_levers={rid: arm_levers(r) for rid, r in self.world.robots.items()},
            max_span=args.max_span or typed.scenario.max_exchange_ticks,
            arm_pairs=[
                (a, b, self.world.robots[a].near_margin + self.world.robots[b].near_margin)
                for a, b in self.world.robot_pairs
            ],
            button=self.world.button_bounds()
            if typed.conditions.safety_policy == sc.SafetyPolicy.RETREAT_BUTTON
            else None,
        )
        self._reacting_until = 0  # exchanges of one tick before it: a button press's reactions
        keys = bus.keys
        self._commands_key = keys.world_commands()
        self._objects_pub = bus.publisher(keys.world_objects())
        self._contacts_pub = bus.publisher(keys.world_contacts())
        self._separation_pub = (
            bus.publisher(keys.world_separation()) if self.world.separation is not None else None
        )
        log.info(
            "scenario %r, %s at %g Hz, %d objects, waiting for %s",
            self.scenario.info.name,
            args.clock,
            tick_hz,
            len(self.world.objects),
            ", ".join(self.settings.participants + self.settings.observers),
        )

    def close(self) -> None:
        if self.planner.histogram:
            log.info(
                "exchange spans planned (span: count): %s; arm speed bounds %s m/s",
                ", ".join(f"{k}: {v}" for k, v in sorted(self.planner.histogram.items())),
                ", ".join(f"{k} {v:.2f}" for k, v in sorted(self.planner.arm_bounds.items())),
            )
        if self.world.rejected:
            log.info(
                "world commands rejected, by object: %s",
                ", ".join(f"{k}: {v}" for k, v in sorted(self.world.rejected.items())),
            )
        self.world.close()

    def clock_settings(self) -> ClockSettings:
        return self.settings

    def register_inputs(self, inputs: Inputs) -> None:
        keys = self.bus.keys
        inputs.input(keys.robot_states(), pb.RobotState, self._on_robot_state, validate=_robot_ok)
        inputs.input(keys.human_state(), pb.HumanState, self._on_human, validate=_human_ok)
        inputs.input(keys.world_commands(), pb.WorldCommands, self._on_world_commands)
        # Only to know which arms may start a new motion in the next exchange (rare messages).
        inputs.input(keys.robot_commands(), pb.RobotCommand, self._on_robot_command)

    def _on_robot_state(self, key: str, msg: pb.RobotState) -> None:
        robot = msg.robot or self.bus.keys.robot_of(key)
        try:
            self.world.set_robot_state(robot, list(msg.joint_names), list(msg.joint_positions))
        except CommandRejected as exc:
            self.bus.reject(key, msg.header.sender, f"robot state rejected: {exc}")
            return
        self.planner.declare(
            robot,
            msg.joint_names,
            msg.joint_speed_fraction_bounds,
            msg.joint_speed_window_ticks,
            msg.link_linear_speed_bounds,
            msg.link_angular_speed_bounds,
        )

    def _on_robot_command(self, key: str, _msg: pb.RobotCommand) -> None:
        self.planner.commanded(self.bus.keys.robot_of(key))

    def _on_human(self, _key: str, msg: pb.HumanState) -> None:
        self.world.set_human(msg)
        # the source's own bound if it declares one (docs/ARCHITECTURE.md, "Exchange step")
        self.planner.hand_bound = msg.hand_speed_bound or HAND_SPEED_BOUND

    def _on_world_commands(self, _key: str, msg: pb.WorldCommands) -> None:
        self.pending_commands.extend(msg.commands)

    def publish_world(self, tick: int, sim_time: float) -> None:
        """World state of ``tick``: every object at tick 0, then the moving and changed ones,
        with the object events of the tick; the contacts that began or ended, if any."""
        full = tick == 0
        states = self.world.object_states(full=full)
        events = self.world.take_events()
        if full or states or events:
            self._objects_pub.put(
                pb.WorldObjects(objects=states, full=full, events=events), tick, sim_time
            )
        if self._separation_pub is not None:
            seps = self.world.separations()
            if seps is not None:
                self._separation_pub.put(pb.Separations(separations=seps), tick, sim_time)
        self._publish_contacts(tick, sim_time)

    def _publish_contacts(self, tick: int, sim_time: float) -> None:
        contacts = self.world.contact_events()
        if contacts:
            self._contacts_pub.put(pb.WorldContacts(contacts=contacts), tick, sim_time)
            if self.planner.button is not None:
                self._follow_button(tick, contacts)

    def _follow_button(self, tick: int, contacts: list[pb.Contact]) -> None:
        """retreat_button: the button may be wanted from a hand-arm contact (a collision) to
        the next press, and only then do the planner's hand-button gaps count; a press, in the
        state of this tick, the orchestrator answers at once (the robots going on), so its
        reactions keep one-tick exchanges, as after a declared event (docs/ARCHITECTURE.md,
        "Exchange step")."""
        for c in contacts:  # in the order the orchestrator takes them
            if c.begin and c.kind == pb.CONTACT_KIND_HAND_ROBOT:
                self.planner.button_armed = True
            elif c.begin and c.kind == pb.CONTACT_KIND_HAND_BUTTON:
                self.planner.button_armed = False
                self._reacting_until = tick + REACTION_TICKS

    def max_exchange_ticks(self) -> int:
        return self.planner.max_span

    def exchange_span(self, tick: int, limit: int) -> int:
        if tick < self._reacting_until:
            return 1
        return self.planner.span(
            self.world.c, list(self.world.hands.values()), self.world.robots, limit
        )

    def publish_substep(self, tick: int, sim_time: float) -> None:
        """Inside an exchange: the object events and contacts of ``tick``, stamped with it (the
        objects' poses go with the next clock tick)."""
        events = self.world.take_events()
        if events:
            self._objects_pub.put(
                pb.WorldObjects(objects=self.world.object_states(), events=events),
                tick,
                sim_time,
            )
        self._publish_contacts(tick, sim_time)

    def step_world(self, tick: int, sim_time: float) -> None:
        """Applies the outputs of ``tick`` and advances the world to ``tick + 1``."""
        problems = self.world.step(self.pending_commands)
        self.pending_commands.clear()
        for problem in problems:
            n = self.bus.stats.count_error(self._commands_key)
            log.warning("tick %d: world command #%d rejected: %s", tick, n, problem)

    def finish(self, outcome: Outcome) -> int | None:
        end = outcome.run_end
        if end is not None:
            log.info(
                "run ended after %d ticks (%.2f s wall, %.1fx realtime): %s",
                end.ticks,
                end.wall_s,
                end.realtime_factor,
                end.reason,
            )
        return None
