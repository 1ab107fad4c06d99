"""The scripted participant's decisions, on the mini world (minisim.py, next to the tests) and on
synthetic task state."""

from __future__ import annotations

import functools
import itertools
import math

import numpy as np
import pytest
from minisim import MiniWorld

from hrc import scenario as sc
from hrc.paths import project_root
from hrc.wire import pb

from hrc_human_input import facts as facts_mod
from hrc_human_input.scripted import Phase, ScriptedParticipant
from hrc_human_input.task_view import TaskView

ROOT = project_root()


@functools.cache
def _loaded(name: str) -> bytes:
    return sc.to_proto(sc.load(ROOT / "scenarios" / f"{name}.toml")).SerializeToString()


def scenario_pb(name: str, **params: float | bool) -> pb.Scenario:
    msg = pb.Scenario.FromString(_loaded(name))
    for k, v in params.items():
        setattr(msg.participant.scripted, k, v)
    return msg


def make_world(
    name: str = "minimal",
    *,
    anticipation: bool = True,
    seed: int | None = None,
    provoke_times: list[float] | None = None,
    provoke_probability: float = 0.0,
    **params: float | bool,
) -> MiniWorld:
    msg = scenario_pb(name, **params)
    msg.conditions.anticipation = anticipation
    if seed is not None:
        msg.info.seed = seed
    if provoke_times:
        msg.participant.provoke_times_s[:] = provoke_times
    msg.participant.provoke_probability = provoke_probability
    facts = facts_mod.from_proto(msg)
    return MiniWorld(facts, ScriptedParticipant(facts))


def hand_positions(world: MiniWorld, hand: str = "right") -> np.ndarray:
    return np.array([s.hand(hand).position for s in world.samples])


def count_peaks(speed: np.ndarray, rel: float = 0.02) -> int:
    top = float(speed.max())
    peaks, low, rising = 0, float(speed[0]), True
    for a, b in itertools.pairwise(speed):
        if rising and b < a - 1e-12:
            if a - low > rel * top:
                peaks += 1
            rising, low = False, b
        elif not rising:
            if b > a + 1e-12:
                rising, low = True, min(low, a)
            low = min(low, b)
    return peaks


@pytest.mark.parametrize("name", ["minimal", "thesis"])
def test_completes_the_scenario_with_human_like_reaches(name: str) -> None:
    w = make_world(name)
    assert w.run(max_s=300.0), f"not finished; phase {w.participant.phase}"
    facts = w.facts
    # it grabbed exactly the parts of its sequence, in order, each once (no misses at 5 mm sd)
    order = sorted(w.grabbed_at, key=lambda p: w.grabbed_at[p][0])
    assert order == facts.human_sequence
    assert [p for _t, p, _d in w.released] == facts.human_sequence
    for _ in range(int(3 * facts.tick_hz)):
        w.step()
    assert w.participant.phase == Phase.DONE
    assert w.samples[-1].right.position == pytest.approx((0.22, -0.56, 0.10))
    # the speed profile of every reach has one peak; reaches of 30-60 cm peak in the human range
    pos = hand_positions(w)
    hz = facts.tick_hz
    speed = np.linalg.norm(np.diff(pos, axis=0), axis=1) * hz
    peaks = []
    for seg in w.participant.hands["right"].segments:
        k0, k1 = int(np.ceil(seg.t0 * hz)), int(np.floor(seg.t_end * hz))
        if k1 - k0 < 6:
            continue
        prof = speed[k0:k1]
        assert count_peaks(prof) == 1, f"segment at {seg.t0:.3f}s has {count_peaks(prof)} peaks"
        if 0.30 <= seg.distance <= 0.60:
            peaks.append((seg.distance, float(prof.max())))
    assert peaks, "no 30-60 cm reach"
    for d, v in peaks:
        print(f"{name}: reach {d:.3f} m, peak hand speed {v:.3f} m/s")
        assert 0.5 <= v <= 2.0
    # the other hand rested all along
    left = hand_positions(w, "left")
    assert np.ptp(left, axis=0).max() < 1e-9


def test_waits_for_dependencies_before_placing() -> None:
    w = make_world("thesis")
    w.robot_delay_s = 6.0  # r1 is slow: H2 (after RA2) must wait
    assert w.run(max_s=400.0)
    t_release_h2 = next(t for t, p, _d in w.released if p == "H2")
    assert t_release_h2 > w.placed_at["RA2"]
    assert t_release_h2 > w.grabbed_at["H2"][0]
    assert any("H2 waits for RA2" in m for _t, m in w.participant.log)
    # and while it waited it held the part up, still
    assert w.placed_at["H5"] > w.placed_at["RA3"]


def test_same_seed_same_motion_other_seed_other_motion() -> None:
    a, b, c = make_world(), make_world(), make_world(seed=99)
    for w in (a, b, c):
        w.run(max_s=60.0)
    assert a.samples == b.samples
    assert a.samples != c.samples


def test_collision_pulls_back_waits_and_resumes() -> None:
    w = make_world("thesis", caution=0.0)
    while "H1" not in w.placed_at:
        w.step()
    # a robot tool parked right where the hand will approach H2
    part = w.facts.parts["H2"]
    w.tcp["r1"] = (part.start[0], part.start[1], part.start[2] + 0.10)
    while not w.collisions and w.tick * w.dt < 20:
        w.step()
    assert w.collisions, "the hand never touched the parked tool"
    t_col = w.collisions[0][0]
    w.tcp["r1"] = (0.45, 0.45, 0.40)  # the robot leaves for its retreat pose
    y_at_collision = w.samples[-1].right.position[1]
    grabs_before = sum(len(v) for v in w.grabbed_at.values())
    while w.tick * w.dt < t_col + w.continue_after_s - 0.05:
        w.step()
    # pulled back towards the body, did not grab anything during the collision
    ys = [s.right.position[1] for s in w.samples if s.t > t_col]
    assert min(ys) < y_at_collision - 0.15
    assert sum(len(v) for v in w.grabbed_at.values()) == grabs_before
    assert w.participant.phase == Phase.COLLISION_WAIT
    assert w.run(max_s=200.0)
    assert min(w.grabbed_at["H2"]) > t_col + w.continue_after_s


def test_once_hit_it_lets_that_robot_pass_before_its_next_reach() -> None:
    """Without caution the hand used to go straight back after the robots continued, into the
    robot coming back the same way (a livelock in simulated studies: the same collision 300
    times). Now it waits while the robot that hit it moves, until it has come to rest."""
    w = make_world("thesis", caution=0.0)
    while "H1" not in w.placed_at:
        w.step()
    part = w.facts.parts["H2"]
    w.tcp["r1"] = (part.start[0], part.start[1], part.start[2] + 0.10)
    while not w.collisions and w.tick * w.dt < 20:
        w.step()
    assert w.collisions, "the hand never touched the parked tool"
    t_col = w.collisions[0][0]
    retreat = (0.45, 0.45, 0.40)
    w.tcp["r1"] = retreat
    while w.tick * w.dt < t_col + w.continue_after_s + 0.05:
        w.step()
    assert not w.participant.in_collision  # the robots continued
    # r1 comes back towards the board for 3 s (away from H2's place), then stands there
    t_go, far = w.tick * w.dt, (0.30, 0.10, 0.30)
    while w.tick * w.dt < t_go + 3.0:
        u = (w.tick * w.dt - t_go) / 3.0
        w.tcp["r1"] = tuple(a + u * (b - a) for a, b in zip(retreat, far, strict=True))
        w.step()
    assert "H2" not in w.grabbed_at, "it reached again while the robot that hit it moved"
    assert w.run(max_s=200.0)
    assert min(w.grabbed_at["H2"]) > t_go + 3.0


def test_a_held_part_may_still_be_placed_during_a_collision() -> None:
    w = make_world(caution=0.0)
    while w.participant.phase != Phase.CARRY:
        w.step()
    for _ in range(30):
        w.step()
    hand = w.samples[-1].right.position
    w.tcp["r1"] = hand  # the robot runs into the carrying hand
    w.step()
    w.step()
    assert w.collisions
    t_col = w.collisions[0][0]
    w.tcp["r1"] = (0.45, 0.45, 0.40)
    w.continue_after_s = 30.0
    w.collision_until = t_col + 30.0
    while "H1" not in w.placed_at and w.tick * w.dt < t_col + 10:
        w.step()
    assert w.placed_at["H1"] < t_col + 10, "held part was not placed during the collision"
    assert w.participant.in_collision


def view_for_caution(anticipation: bool, **cue_kw: object) -> tuple[ScriptedParticipant, TaskView]:
    msg = scenario_pb("minimal", caution=1.0)
    msg.conditions.anticipation = anticipation
    facts = facts_mod.from_proto(msg)
    view = TaskView(facts)
    p = ScriptedParticipant(facts)
    h1 = facts.parts["H1"]
    wo = pb.WorldObjects(full=True)
    wo.objects.add(
        id="H1",
        grabbable=True,
        pose=pb.Pose(
            position=pb.Vec3(x=h1.start[0], y=h1.start[1], z=h1.start[2]),
            orientation=pb.Quat(w=1.0),
        ),
    )
    view.on_objects(wo)
    for rid, tcp in (("r1", (0.20, 0.25, 0.25)), ("r2", (-0.20, 0.25, 0.25))):
        for t in (0.0, 0.1):  # two states: it stands still
            rs = pb.RobotState(
                robot=rid, tcp=pb.Pose(position=pb.Vec3(x=tcp[0], y=tcp[1], z=tcp[2]))
            )
            rs.header.sim_time = t
            view.on_robot_state(rs)
    # r1 carries RA1 and its lit target says it is heading to where H1 lies
    view.on_indicators(
        pb.Indicators(
            cues=[
                pb.Cue(
                    id="target:RA1",
                    kind=pb.CUE_KIND_TARGET,
                    on=True,
                    part="RA1",
                    robot="r1",
                    color="yellow",
                    position=pb.Vec3(x=h1.start[0], y=h1.start[1] + 0.05, z=0.05),
                )
            ]
        )
    )
    if cue_kw:
        view.on_indicators(pb.Indicators(cues=[pb.Cue(**cue_kw)]))
    return p, view


def run_view(p: ScriptedParticipant, view: TaskView, seconds: float) -> None:
    t0 = p.t + 1 / 240.0 if p.t > 0 else 0.2
    for k in range(int(seconds * 240)):
        p.step(t0 + k / 240.0, view)


def test_caution_uses_the_anticipation_cues_only_when_enabled() -> None:
    p_on, v_on = view_for_caution(anticipation=True)
    p_off, v_off = view_for_caution(anticipation=False)
    run_view(p_on, v_on, 2.0)
    run_view(p_off, v_off, 2.0)
    assert p_on.phase == Phase.REACT and p_on.hold_backs and p_on.hold_backs[0][1] == "r1"
    assert not p_off.hold_backs and p_off.phase in (Phase.REACH, Phase.HOLD)
    # a robot showing "Waiting.." is not coming: no reason to hold back
    p_wait, v_wait = view_for_caution(
        True, id="waiting:r1", kind=pb.CUE_KIND_WAITING, on=True, robot="r1"
    )
    run_view(p_wait, v_wait, 2.0)
    assert not p_wait.hold_backs
    # for a robot standing still in the way (its cue lit, it does not move), at most
    # max_hold_back_s
    p_on.max_hold = 1.0
    run_view(p_on, v_on, 1.5)
    assert any("stood still in the way 1 s: going" in m for _t, m in p_on.log)
    assert p_on.phase == Phase.REACH


def test_caution_sees_a_robot_moving_towards_the_goal_without_anticipation() -> None:
    p, view = view_for_caution(anticipation=False)
    goal = p.grasp_point(view, "H1")
    dt = 1.0 / view.facts.tick_hz
    for k in range(2):  # r2 sweeping towards the part at 0.5 m/s, states on two ticks
        x = goal[0] + 0.35 - 0.5 * dt * k
        rs = pb.RobotState(
            robot="r2", tcp=pb.Pose(position=pb.Vec3(x=x, y=goal[1], z=goal[2] + 0.08))
        )
        rs.header.sim_time = 0.3 + k * dt
        view.on_robot_state(rs)
    above = (goal[0], goal[1], goal[2] + 0.08)
    p.t = 0.3 + 2 * dt  # the tick after the last state
    assert p.danger(view, above) == "r2"
    p.t = 0.3 + 3 * dt  # no state since: it has stopped (states come on change)
    assert p.danger(view, above) is None
    p.t = 0.3 + 2 * dt
    p.caution = 0.0
    assert p.danger(view, above) is None


def test_provoke_at_a_task_time_reaches_into_the_robot() -> None:
    w = make_world(provoke_times=[1.0], caution=0.0)
    w.tcp["r1"] = (0.10, 0.05, 0.25)
    assert w.run(max_s=60.0)
    assert len(w.collisions) == 1
    t, robot, hand = w.collisions[0]
    assert robot == "r1" and hand == "right"
    assert t - w.task_start >= 1.0
    assert any("reaching into r1" in m for _t, m in w.participant.log)


def test_provoke_probability_one_collides_once_per_part_and_still_finishes() -> None:
    w = make_world("thesis", provoke_probability=1.0, caution=0.0)
    w.tcp["r1"] = (0.10, 0.05, 0.25)
    assert w.run(max_s=400.0)
    # the first reach of H1 happens before the task starts (robots count only after), so one
    # collision per part from H2 on
    assert len(w.collisions) == len(w.facts.human_sequence) - 1


def test_missed_release_is_grabbed_again() -> None:
    w = make_world("thesis", place_error_m=0.02)
    assert w.run(max_s=600.0)
    misses = [p for _t, p, d in w.released if d > w.facts.place_tolerance_m]
    assert misses, "with 2 cm place error some release should miss"
    for part in misses:
        assert len(w.grabbed_at[part]) >= 2
    assert set(w.placed_at) >= set(w.facts.human_sequence)


def test_parameters_come_from_the_scenario_model() -> None:
    msg = scenario_pb("minimal", caution=0.9)
    assert facts_mod.from_proto(msg).params.caution == 0.9
    msg.participant.scripted.ClearField("caution")  # unset: the model's default
    assert facts_mod.from_proto(msg).params.caution == sc.ScriptedParams().caution
    msg.participant.ClearField("scripted")
    assert facts_mod.from_proto(msg).params == sc.ScriptedParams()


def test_out_of_range_parameters_are_refused_naming_the_key() -> None:
    msg = scenario_pb("minimal", caution=7.0)
    with pytest.raises(sc.ScenarioError) as err:
        facts_mod.from_proto(msg)
    assert [p.key for p in err.value.problems] == ["participant.caution"]


def test_left_handed_participant_uses_the_left_hand() -> None:
    w = make_world(left_handed=True)
    assert w.run(max_s=60.0)
    assert w.released and all(True for _ in w.released)
    right = hand_positions(w, "right")
    assert np.ptp(right, axis=0).max() < 1e-9


def test_under_ssm_it_waits_for_a_part_beside_the_body_with_both_hands() -> None:
    from hrc.geometry import distance

    from hrc_human_input.scripted import REST, WAIT_SSM

    msg = scenario_pb("thesis")
    msg.conditions.safety_policy = pb.SAFETY_POLICY_SSM
    facts = facts_mod.from_proto(msg)
    w = MiniWorld(facts, ScriptedParticipant(facts))
    w.robot_delay_s = 6.0  # r1 is slow: H2 (after RA2) waits
    p = w.participant
    waited_at: list[tuple[float, float]] = []  # (right, left) distances from WAIT_SSM
    for _ in range(400 * 240):
        w.step()
        if w.done():
            break
        if p.phase == Phase.WAIT_DEPS and not p.hand.busy:
            waited_at.append(
                (
                    distance(p.hands["right"].pos, WAIT_SSM["right"]),
                    distance(p.hands["left"].pos, WAIT_SSM["left"]),
                )
            )
    assert waited_at, "it never waited for a part"
    assert max(r for r, _l in waited_at) < 0.01  # holding the part beside the body
    assert max(lft for _r, lft in waited_at) < 0.01  # the free hand too
    assert w.placed_at["H2"] > w.placed_at["RA2"]
    # under the other policies the rest pose is in front of the body, as before
    assert REST["right"] != WAIT_SSM["right"]


def test_a_robot_moving_into_the_way_is_waited_for_longer_than_max_hold() -> None:
    p, view = view_for_caution(anticipation=False)
    p.max_hold = 1.0
    goal = p.grasp_point(view, "H1")
    t = 0.2
    # r2 sweeps to and fro across the region around H1 for 4 s, always moving
    for k in range(int(4.0 * 240)):
        now = t + k / 240.0
        x = goal[0] + 0.05 * math.sin(2.0 * math.pi * 0.5 * (now - t))
        rs = pb.RobotState(
            robot="r2", tcp=pb.Pose(position=pb.Vec3(x=x, y=goal[1], z=goal[2] + 0.08))
        )
        rs.header.sim_time = now
        view.on_robot_state(rs)
        p.step(now, view)
        assert p.phase in (Phase.IDLE, Phase.REACT), (now, p.log[-3:])
    assert p.hold_backs and not any("going" in m for _t, m in p.log)
    # once it stands still in the way, max_hold later it goes
    for k in range(int(3.0 * 240)):
        p.step(t + 4.0 + k / 240.0, view)
        if p.phase == Phase.REACH:
            break
    assert p.phase == Phase.REACH
    assert any("stood still in the way 1 s: going" in m for _t, m in p.log)
