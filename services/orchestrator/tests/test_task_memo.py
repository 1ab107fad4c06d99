"""The task recomputes its grabbable flags and cues only when what they depend on changed: the
outputs must be exactly those of recomputing them every tick."""

from __future__ import annotations

import pytest
from orch_fakes import FakeHuman, Sim, load

from hrc.wire import pb

HR = pb.CONTACT_KIND_HAND_ROBOT


def outputs(policy: str, anticipation: bool, recompute: bool) -> list[bytes]:
    """Every tick's cue changes and world commands (serialized) of a run with collisions now and
    then; ``recompute``: forget what the task last computed them from, before every tick."""
    sim = Sim(
        load("thesis.toml", conditions={"safety_policy": policy, "anticipation": anticipation}),
        human=FakeHuman(grab_delay_s=0.8, place_delay_s=0.6, misses=1),
    )
    log: list[bytes] = []
    while not sim.stop and sim.k < 20_000:  # retreat_button: nobody presses it
        if recompute:
            sim.task._cues_key = sim.task._grabbable_key = None
        if sim.k % 1100 == 500:  # the hand touches r1, and lets go 150 ticks later
            sim.contact(HR, True, "right", "r1", "link3")
        if sim.k % 1100 == 650:
            sim.contact(HR, False, "right", "r1", "link3")
        out = sim.step()
        log += [c.SerializeToString() for c in out.cues]
        log += [w.SerializeToString() for w in out.world_commands]
        log.append(b"|")
    return log


@pytest.mark.parametrize("policy", ["retreat", "retreat_button", "stop_colliding", "ssm"])
@pytest.mark.parametrize("anticipation", [True, False])
def test_cues_and_grabbable_flags_are_those_of_recomputing_every_tick(
    policy: str, anticipation: bool
) -> None:
    memo = outputs(policy, anticipation, recompute=False)
    assert any(x != b"|" for x in memo)  # cues and flags did change during the run
    assert memo == outputs(policy, anticipation, recompute=True)
