"""The physics service's tick work: take the participants' outputs, publish the world, step."""

from __future__ import annotations

import logging
import math

from hrc import scenario as sc
from hrc.bus import Bus, ClockMaster
from hrc.validate import check_pose
from hrc.wire import pb
from hrc_physics.world import CommandRejected, World, WorldSettings

log = logging.getLogger(__name__)


def _human_ok(msg: pb.HumanState) -> str | None:
    for name in ("head", "left_hand", "right_hand"):
        problem = check_pose(getattr(msg, name))
        if problem:
            return f"{name}: {problem}"
    for name in ("left_grip", "right_grip"):
        v = getattr(msg, name)
        if not 0.0 <= v <= 1.0:  # also false for NaN
            return f"{name} = {v} is outside [0, 1]"
    return None


def _robot_ok(msg: pb.RobotState) -> str | None:
    if not all(math.isfinite(v) for v in msg.joint_positions):
        return f"robot {msg.robot!r}: joint positions contain NaN or infinity"
    return None


class PhysicsService:
    """Holds the world and feeds it the latest inputs of each participant.

    Use as a context manager (the world owns a pybullet client)."""

    def __init__(self, bus: Bus, scenario: pb.Scenario, tick_hz: float,
                 solver_iterations: int = WorldSettings.solver_iterations) -> None:
        self.bus = bus
        self.scenario = scenario
        typed = sc.from_proto(scenario)  # raises ScenarioError naming the bad field
        self.world = World(typed, WorldSettings(dt=1.0 / tick_hz,
                                                solver_iterations=solver_iterations))
        self.pending_commands: list[pb.WorldCommand] = []
        keys = bus.keys
        self._commands_key = keys.world_commands()
        self._objects_pub = bus.publisher(keys.world_objects())
        self._contacts_pub = bus.publisher(keys.world_contacts())

    def __enter__(self) -> "PhysicsService":
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()

    def close(self) -> None:
        if self.world.rejected:
            log.info("world commands rejected, by object: %s",
                     ", ".join(f"{k}: {v}" for k, v in sorted(self.world.rejected.items())))
        self.world.close()

    def register_inputs(self, clock: ClockMaster) -> None:
        keys = self.bus.keys
        clock.input(keys.robot_states(), pb.RobotState, self._on_robot_state, validate=_robot_ok)
        clock.input(keys.human_state(), pb.HumanState, self._on_human, validate=_human_ok)
        clock.input(keys.world_commands(), pb.WorldCommands, self._on_world_commands)

    def _on_robot_state(self, key: str, msg: pb.RobotState) -> None:
        robot = msg.robot or self.bus.keys.robot_of(key)
        try:
            self.world.set_robot_state(robot, list(msg.joint_names), list(msg.joint_positions))
        except CommandRejected as exc:
            self.bus.reject(key, msg.header.sender, f"robot state rejected: {exc}")

    def _on_human(self, _key: str, msg: pb.HumanState) -> None:
        self.world.set_human(msg)

    def _on_world_commands(self, _key: str, msg: pb.WorldCommands) -> None:
        self.pending_commands.extend(msg.commands)

    def publish_world(self, tick: int, sim_time: float) -> None:
        """World state of ``tick``: every object at tick 0, then the moving and changed ones,
        with the object events of the tick; the contacts that began or ended, if any."""
        full = tick == 0
        states = self.world.object_states(full=full)
        events = self.world.take_events()
        if full or states or events:
            self._objects_pub.put(pb.WorldObjects(objects=states, full=full, events=events),
                                  tick, sim_time)
        contacts = self.world.contact_events()
        if contacts:
            self._contacts_pub.put(pb.WorldContacts(contacts=contacts), tick, sim_time)
            for c in contacts:
                log.debug("tick %d: contact %s %s %s-%s %s", tick, pb.ContactKind.Name(c.kind),
                          "begins" if c.begin else "ends", c.a, c.b, c.link)

    def step(self, tick: int, sim_time: float) -> None:
        """Applies the outputs of ``tick`` and advances the world to ``tick + 1``."""
        problems = self.world.step(self.pending_commands)
        self.pending_commands.clear()
        for problem in problems:
            n = self.bus.stats.count_error(self._commands_key)
            log.warning("tick %d: world command #%d rejected: %s", tick, n, problem)
