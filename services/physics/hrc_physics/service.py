"""The physics service's tick work: take the participants' outputs, publish the world, step."""

from __future__ import annotations

import logging

from hrc.bus import Bus, ClockMaster, check_pose
from hrc.wire import pb

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


class PhysicsService:
    """Holds the latest inputs of each participant and the world they act on."""

    def __init__(self, bus: Bus, scenario: pb.Scenario) -> None:
        self.bus = bus
        self.scenario = scenario
        self.robot_states: dict[str, pb.RobotState] = {}
        self.human: pb.HumanState | None = None
        self.pending_commands: list[pb.WorldCommand] = []
        keys = bus.keys
        self._objects_pub = bus.publisher(keys.world_objects())
        self._contacts_pub = bus.publisher(keys.world_contacts())

    def register_inputs(self, clock: ClockMaster) -> None:
        keys = self.bus.keys
        clock.input(keys.robot_states(), pb.RobotState, self._on_robot_state)
        clock.input(keys.human_state(), pb.HumanState, self._on_human, validate=_human_ok)
        clock.input(keys.world_commands(), pb.WorldCommands, self._on_world_commands)

    def _on_robot_state(self, _key: str, msg: pb.RobotState) -> None:
        self.robot_states[msg.robot] = msg

    def _on_human(self, _key: str, msg: pb.HumanState) -> None:
        self.human = msg

    def _on_world_commands(self, _key: str, msg: pb.WorldCommands) -> None:
        self.pending_commands.extend(msg.commands)

    def publish_world(self, tick: int, sim_time: float) -> None:
        """World state of ``tick``: every object at tick 0, then the moving ones."""
        if tick == 0:
            self._objects_pub.put(pb.WorldObjects(full=True), tick, sim_time)

    def step(self, tick: int, sim_time: float) -> None:
        """Applies the outputs of ``tick`` and advances the world to ``tick + 1``."""
        self.pending_commands.clear()
