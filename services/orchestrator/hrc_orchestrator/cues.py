"""Cues (`task/indicators`): the task computes the cues that should be on each tick; the board
publishes only the changes (docs/ARCHITECTURE.md: stable ids, only `on` changes)."""

from __future__ import annotations

from hrc.scenario.colors import HUMAN_COLOR  # noqa: F401  (the cues' colour of the participant)
from hrc.wire import pb


class CueBoard:
    """Remembers which cues are on and turns a desired set into on/off changes, sorted by id."""

    def __init__(self) -> None:
        self._on: dict[str, pb.Cue] = {}

    @property
    def on(self) -> dict[str, pb.Cue]:
        return dict(self._on)

    def update(self, desired: list[pb.Cue]) -> list[pb.Cue]:
        wanted = {c.id: c for c in desired}
        changes: list[pb.Cue] = []
        for cue_id in sorted(set(self._on) | set(wanted)):
            if cue_id in wanted and cue_id not in self._on:
                cue = pb.Cue()
                cue.CopyFrom(wanted[cue_id])
                cue.on = True
                changes.append(cue)
            elif cue_id in self._on and cue_id not in wanted:
                cue = pb.Cue()
                cue.CopyFrom(self._on[cue_id])
                cue.on = False
                changes.append(cue)
        self._on = {cid: wanted[cid] for cid in sorted(wanted)}
        return changes
