"""What every agent's logic shares: the parts, which are done, when they were grabbed and placed,
and the outputs collected during one tick."""

from __future__ import annotations

from hrc import scenario as sc
from hrc.wire import pb


class Board:
    def __init__(self, scenario: sc.Scenario) -> None:
        self.parts: dict[str, sc.Part] = scenario.parts_by_id
        self._done: dict[str, float] = {}
        self.grabbed_s: dict[str, float] = {}
        self.placed_s: dict[str, float] = {}
        self.events: list[pb.TaskEvent] = []
        self.world: list[pb.WorldCommand] = []

    # ------------------------------------------------------------------ parts
    def is_done(self, part_id: str) -> bool:
        return part_id in self._done

    def missing_deps(self, part_id: str) -> list[str]:
        """The part's `after` parts that are not done yet, in the order the file lists them."""
        return [p for p in self.parts[part_id].after if p not in self._done]

    def mark_grabbed(self, part_id: str, t: float) -> None:
        self.grabbed_s.setdefault(part_id, t)  # the first grab counts

    def mark_placed(self, part_id: str, t: float) -> None:
        self._done[part_id] = t
        self.placed_s[part_id] = t

    # ------------------------------------------------------------------ outputs of the tick
    def emit(self, event: pb.TaskEvent) -> None:
        self.events.append(event)

    def command(self, cmd: pb.WorldCommand) -> None:
        self.world.append(cmd)

    def drain(self) -> tuple[list[pb.TaskEvent], list[pb.WorldCommand]]:
        events, world = self.events, self.world
        self.events, self.world = [], []
        return events, world
