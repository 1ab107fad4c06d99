"""The scripted participant never leaves a trial hanging: it presses the continue button whenever
its cue is on (whatever the other hand does), again if a press did not register, and it does not
leave a hand on a robot."""

from __future__ import annotations

from test_scripted import run_view, scenario_pb

from hrc.geometry import distance
from hrc.scenario.conventions import CONTINUE_BUTTON_CUE
from hrc.wire import pb

from hrc_human_input import facts as facts_mod
from hrc_human_input.scripted import REST, Phase, ScriptedParticipant
from hrc_human_input.task_view import TaskView


def participant(policy: int) -> tuple[ScriptedParticipant, TaskView]:
    msg = scenario_pb("thesis")
    msg.conditions.safety_policy = policy
    facts = facts_mod.from_proto(msg)
    assert facts.continue_button is not None
    return ScriptedParticipant(facts), TaskView(facts)


def button_cue(view: TaskView, on: bool) -> None:
    view.on_indicators(
        pb.Indicators(
            cues=[pb.Cue(id=CONTINUE_BUTTON_CUE, on=on, kind=pb.CUE_KIND_CONTINUE_BUTTON)]
        )
    )


def near_button(p: ScriptedParticipant) -> bool:
    assert p.facts.continue_button is not None
    return distance(p.hands[p.free].pos, p.facts.continue_button) < 0.03


def presses(p: ScriptedParticipant, view: TaskView, seconds: float) -> int:
    """Steps `seconds`; the number of separate arrivals of the free hand at the button."""
    n, was = 0, False
    t0 = p.t + 1 / 240.0 if p.t > 0 else 0.2
    for k in range(int(seconds * 240)):
        p.step(t0 + k / 240.0, view)
        now = near_button(p)
        n += now and not was
        was = now
    return n


def test_presses_the_cued_button_whatever_it_does_and_again_until_it_registers() -> None:
    p, view = participant(pb.SAFETY_POLICY_RETREAT_BUTTON)
    # no collision seen by the participant, not waiting for one: idle, hands at rest
    run_view(p, view, 0.5)
    assert p.phase == Phase.IDLE and not p.in_collision
    button_cue(view, True)
    # the press does not register (the cue stays on): it presses again, every few seconds
    assert presses(p, view, 10.0) >= 2
    button_cue(view, False)
    presses(p, view, 3.0)  # back to rest
    assert presses(p, view, 6.0) == 0
    assert distance(p.hands[p.free].pos, REST[p.free]) < 0.02


def test_a_held_part_stays_in_the_other_hand_while_it_presses() -> None:
    p, view = participant(pb.SAFETY_POLICY_RETREAT_BUTTON)
    run_view(p, view, 0.2)
    p.phase = Phase.WAIT_DEPS  # holding a part, waiting: the active hand is busy with it
    p.part = "H2"
    view.on_objects(
        pb.WorldObjects(
            full=True,
            objects=[
                pb.ObjectState(
                    id="H2",
                    held_by=p.active,
                    pose=pb.Pose(
                        position=pb.Vec3(x=-0.17, y=-0.38, z=0.2), orientation=pb.Quat(w=1.0)
                    ),
                )
            ],
        )
    )
    button_cue(view, True)
    assert presses(p, view, 4.0) >= 1
    assert view.held_by("H2") == p.active  # the active hand never let go of it


def test_no_button_under_the_other_policies() -> None:
    p, view = participant(pb.SAFETY_POLICY_RETREAT)
    button_cue(view, True)
    assert presses(p, view, 5.0) == 0


def test_a_hand_left_on_a_robot_is_pulled_back() -> None:
    p, view = participant(pb.SAFETY_POLICY_STOP_COLLIDING)
    run_view(p, view, 0.2)
    view.on_contacts(
        pb.WorldContacts(
            contacts=[pb.Contact(kind=pb.CONTACT_KIND_HAND_ROBOT, begin=True, a=p.active, b="r2")]
        )
    )
    run_view(p, view, 0.5)
    assert p.phase in (Phase.PULLBACK, Phase.COLLISION_WAIT)
    run_view(p, view, 3.0)  # still touching after TOUCH_MAX_S: all the way back to rest
    hand = p.hands[p.active]
    assert not hand.busy and distance(hand.pos, REST[p.active]) < 0.02


def test_a_danger_that_comes_and_goes_holds_an_action_back_max_hold_in_all() -> None:
    from test_scripted import view_for_caution

    p, view = view_for_caution(anticipation=True)  # r1's lit target lies by H1: danger
    p.max_hold = 2.0
    cue = view.cues["target:RA1"]
    t = 0.2
    for k in range(int(8.0 * 240)):  # the cue flickers: on 0.3 s, off 0.1 s (a robot at the edge)
        cue.on = (k % 96) < 72
        p.step(t + k / 240.0, view)
        if p.phase not in (Phase.IDLE, Phase.REACT):
            break
    assert p.phase in (Phase.REACH, Phase.HOLD), p.log[-5:]
    assert p.t - t < p.max_hold + 1.5  # the limit plus a reaction time, not for ever
