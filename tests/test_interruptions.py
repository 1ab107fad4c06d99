"""Every interruption is recovered (docs/task-semantics.md, "Interruptions"): every task move of
the thesis scenario and of the dense layout, under each safety policy, interrupted at its start,
middle and just before its end by what that policy does to a moving arm (a hold; a retreat under
the retreat policies; a speed scale of 0 under ssm) and then commanded again, is finished by the
real IK planner (``hrc-ik --check-moves``), in exactly the joint configuration the undisturbed
move ends in, so every later move starts where the motion check judged it."""

from __future__ import annotations

import pytest

from hrc import scenario as sc
from hrc.paths import ik_binary, project_root
from hrc.scenario import SafetyPolicy
from hrc.scenario.motion_check import (
    INTERRUPT_FRACTIONS,
    interrupted_moves,
    run_check,
    task_moves,
)

ROOT = project_root()
pytestmark = pytest.mark.skipif(not ik_binary().exists(), reason=f"{ik_binary()} is not built")


@pytest.mark.parametrize("policy", [p.value for p in SafetyPolicy])
@pytest.mark.parametrize("name", ["thesis", "dense-4x4"])
def test_every_move_interrupted_anywhere_is_finished_where_it_would_have_ended(
    name: str, policy: str
) -> None:
    scenario = sc.load(ROOT / "scenarios" / f"{name}.toml", motion_check=False)
    scenario.conditions.safety_policy = SafetyPolicy(policy)
    assert not sc.validate(scenario, motion_check=True), "the layout must validate"
    spb = sc.to_proto(scenario)
    task = [m for rid in sorted(scenario.robots) for m in task_moves(scenario, rid)]
    undisturbed = run_check(spb, task)
    assert all(r.feasible for r in undisturbed)
    ends = {m.label: list(r.end_joints) for m, r in zip(task, undisturbed, strict=True)}
    durations = {m.label: r.duration_s for m, r in zip(task, undisturbed, strict=True)}
    interrupted = interrupted_moves(scenario, durations)
    kinds = (
        {"hold"}
        | ({"retreat"} if policy in ("retreat", "retreat_button") else set())
        | ({"speed 0"} if policy == "ssm" else set())
    )
    assert len(interrupted) == len(task) * len(INTERRUPT_FRACTIONS) * len(kinds)
    results = run_check(spb, task + interrupted)[len(task) :]
    problems = []
    for move, r in zip(interrupted, results, strict=True):
        base = move.label.split(" (")[0]
        deviation = max(
            (abs(a - b) for a, b in zip(r.end_joints, ends[base], strict=True)), default=1.0
        )
        if not r.feasible or not r.interrupted or deviation > 1e-9:
            problems.append(
                f"{move.label}: feasible {r.feasible}, interrupted {r.interrupted}, "
                f"{deviation:.3g} rad from the undisturbed end: {r.detail}"
            )
    print(f"{name} under {policy}: {len(interrupted)} interrupted moves, {len(problems)} problems")
    assert not problems, "\n".join(problems[:20])
