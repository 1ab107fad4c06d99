"""The scripted participant: performs the human sequence from what it perceives on the bus.

Per part: wait for it to become grabbable (outline cue / SetGrabbable) -> reaction time -> reach
above it and down (minimum-jerk, Fitts time) -> close the grip -> dwell -> lift -> wait while the
part's `after` parts are not placed -> reaction time -> carry it above its target, turning it to
the target yaw -> lower -> dwell, open the grip -> placed? withdraw : grab it again.

Around that:
- a human-robot collision (COLLISION event, or a hand-robot contact) makes it pull the hand back
  after a reflex delay and wait until the robots continue (CONTINUED; COLLISION_END for
  `stop_colliding`; under `ssm` it pulls the hand back to rest, out of the robot's protective
  zone, so the robot resumes); a held part may still be placed meanwhile; under
  `retreat_button` the free hand presses the continue button whenever its cue is on (whatever
  the other hand does, and again every few seconds while the cue stays on: a press that did not
  register). A hand that still touches a robot after `TOUCH_MAX_S` is pulled right back to
  rest (a person does not lean on a halted robot).
- `caution` in [0, 1] makes it hold back before a reach while a robot is heading into the region
  it wants to reach: radius 0.08 + 0.17 * caution m around the goal; with anticipation it knows
  where robots are heading from their lit target cues (and that a robot showing "Waiting.." is not
  coming); without, it only sees where the TCPs are and extrapolates their motion over
  0.5 + caution s. It goes when the way is clear: it waits for a moving robot as long as it
  moves there, and for one standing still in the way at most `max_hold_back_s`. It looks when
  it would start (go_t) and, while it holds back, every LOOK_S: at ticks it declares
  (next_look_s), so long exchanges never change what it sees.
- Once hit, it lets that robot pass (whatever its caution): after a collision with a robot its
  next reach or carry waits while that robot is on a move (its state's status, which changes at
  declared events only, so the timing of one-tick exchanges holds), until it has moved and come
  to rest (or has stood still for `max_hold_back_s`). Without it a hand that goes straight back
  where the robot returns to meets it again and again (a livelock seen in simulated studies:
  the same collision 300 times).
- While it waits (held back, for a part's `after` parts, for the robots to continue after a
  collision, with nothing to grab) its hands are out of the robots' way: at rest in front of the
  body, and under `ssm` beside the body (WAIT_SSM), outside every robot's protective separation
  distance, so that no robot stays in a protective stop because of a person who waits for it
  (docs/task-semantics.md, "How the scripted participant waits").
- `provoke_collisions`: at the given task times, or with the given probability on the first reach
  for each part, it reaches into the nearest robot's tool instead (until physics reports contact).

Why one file of over 600 lines: one participant's decisions form one state machine (its phases);
the motor law, the hand and the plans it drives are the library's (hrc.participant).
"""

from __future__ import annotations

import logging
import math
from enum import Enum

import numpy as np

from hrc.geometry import Pose, Vec3, add, distance, look_quat, rotate_z_rad, slerp
from hrc.participant.hand import Dwell, Grip, Hand, Move
from hrc.participant.motor import FIXED_PLACE, MotorParams, reaction_draw, reaction_time
from hrc.participant.plans import (
    APPROACH_CLEARANCE,
    CARRY_CLEARANCE,
    GROSS_WIDTH,
    place_plan,
    reach_plan,
)
from hrc.participant.sample import Sample
from hrc.scenario import SafetyPolicy
from hrc.scenario.conventions import CONTINUE_BUTTON_CUE, GRIP_CLOSED
from hrc.wire import pb

from hrc_human_input.facts import PartFacts, ScenarioFacts
from hrc_human_input.task_view import TaskView

log = logging.getLogger(__name__)

HEAD_POS: Vec3 = (0.0, -0.70, 0.60)  # standing at -y, eyes 0.6 m above the board
REST: dict[str, Vec3] = {"left": (-0.22, -0.56, 0.10), "right": (0.22, -0.56, 0.10)}
# Hands down beside the body, level with the table top, behind its edge: over 0.55 m from
# anything a robot reaches on the board, beyond the resume distance of the default SSM parameters
# (0.30 m), so a person waiting here never holds a robot in its protective stop.
WAIT_SSM: dict[str, Vec3] = {"left": (-0.30, -0.74, 0.0), "right": (0.30, -0.74, 0.0)}
STILL_SPEED = 0.02  # m/s: a robot TCP slower than this stands still
GRASP_HEIGHT_MAX = 0.02  # hand this far above a part's centre at most (top face if lower)
RELEASE_CLEARANCE = 0.003  # let go this far above the resting height
# (moves to the hands' resting and waiting places: FIXED_PLACE, no homing)
PULLBACK = (0.0, -0.20, 0.08)
HAND_Y_MIN = -0.60
GRASP_TIMEOUT_S = 0.6  # grip closed, still not held: try again
RELEASE_RETRY_S = 1.5  # released, not placed: grab it again after this long at most
RELEASE_MIN_S = 0.3  # ... and not before this
COLLISION_FALLBACK_S = 30.0  # no CONTINUED ever: carry on anyway
PROVOKE_GIVE_UP_S = 4.0
BUTTON_REPEAT_S = 3.0
TOUCH_MAX_S = 2.0  # a hand touching a robot this long is pulled right back
HEAD_TIME_CONSTANT_S = 0.15
# While it holds back (caution) or follows a robot's tool (provoking), it looks at the robots
# this often: at declared ticks (next_look_s), which start exchanges, so what it sees is what
# it would see with one-tick exchanges, however long they are.
LOOK_S = 1.0 / 30.0


class Phase(str, Enum):
    IDLE = "idle"  # waiting for something to grab
    REACT = "react"  # reaction time (and caution) before a reach
    REACH = "reach"  # reaching and gripping
    HOLD = "hold"  # holding: decide to carry (reaction time, caution)
    WAIT_DEPS = "wait_deps"  # holding, lifted, while the part's `after` parts are missing
    CARRY = "carry"  # carrying, lowering and releasing
    RELEASE_CHECK = "release_check"
    WITHDRAW = "withdraw"
    PULLBACK = "pullback"  # collision: pulling the hand back
    COLLISION_WAIT = "collision_wait"
    PROVOKE = "provoke"  # reaching into a robot on purpose
    DONE = "done"


class ScriptedParticipant:
    def __init__(self, facts: ScenarioFacts, seed: int | None = None) -> None:
        self.facts = facts
        p = facts.params
        self.motor = MotorParams.of(p)
        self.caution = p.caution
        self.pick_dwell = p.pick_dwell_s
        self.place_dwell = p.place_dwell_s
        self.place_error = p.place_error_m
        self.max_hold = p.max_hold_back_s
        self.stop_above = p.stop_above
        self.collision_reaction_s = p.collision_reaction_s
        self.active = "left" if p.left_handed else "right"
        self.free = "right" if self.active == "left" else "left"
        # Independent streams, so e.g. provoking collisions does not change reaction times.
        ss = np.random.SeedSequence([facts.seed if seed is None else seed, 0x485549])
        s_rt, s_mt_l, s_mt_r, s_place, s_provoke = ss.spawn(5)
        self.rng_rt = np.random.default_rng(s_rt)
        self.rng_place = np.random.default_rng(s_place)
        self.rng_provoke = np.random.default_rng(s_provoke)
        self.hands = {
            "left": Hand("left", REST["left"], 0.0, self.motor, np.random.default_rng(s_mt_l)),
            "right": Hand("right", REST["right"], 0.0, self.motor, np.random.default_rng(s_mt_r)),
        }
        self.head_q = look_quat(HEAD_POS, (0.0, 0.0, 0.0))
        self._head_t: float | None = None
        self._look_goal: Vec3 | None = None  # _look's last goal, its look, dt and weight
        self._look_q = self.head_q
        self._look_dt = -1.0
        self._look_u = 0.0
        self.phase = Phase.IDLE
        self.phase_since = 0.0
        self.part: str | None = None  # the part being handled
        self.go_t: float | None = None  # when the pending action starts
        self.hold_since: float | None = None  # holding back (caution) since
        self.hold_expired = False
        self.still_since: float | None = None  # the robot holding it back stands still since
        self.next_look: float | None = None  # holding back or provoking: its next look at robots
        self.held_by_hitter = False  # held back by the robot that hit it (watched every step)
        self.hold_backs: list[tuple[float, str]] = []  # (time, robot) whenever caution held back
        # the robot that last hit a hand, let pass before the next action: (robot, seen moving)
        self.bitten: tuple[str, bool] | None = None
        self.grasp: tuple[Vec3, float, float] | None = None  # hand - object, hand & object yaw_rad
        self.in_collision = False
        self.collision_since = 0.0
        self.collision_confirmed = False  # the orchestrator announced it (COLLISION event)
        self.last_press: float | None = None
        self.touch_since: float | None = None  # a hand has touched a robot since
        self.provoke_times = list(facts.provoke_times_s)
        self.provoked_parts: set[str] = set()
        self.provoke_robot: str | None = None
        self.released_at: float | None = None
        self.rested = False
        self.t = 0.0
        self.log: list[tuple[float, str]] = []  # (time, what) decisions, for tests and debugging

    # ------------------------------------------------------------------ helpers
    @property
    def look_ticks(self) -> int:
        """LOOK_S in ticks: the period of its looks at the robots."""
        return max(1, round(LOOK_S * self.facts.tick_hz))

    def _look_after(self, t: float) -> float:
        """The next look's time: look_ticks after ``t``, half a tick early, so that its tick
        (the first at or after it) is the same whatever the rounding of the times."""
        return t + (self.look_ticks - 0.5) / self.facts.tick_hz

    def next_look_s(self) -> tuple[float, int] | None:
        """When it next looks at the robots, if after its last step, and the period in ticks of
        the looks after it: held back by caution, or following a tool it provokes, every
        look_ticks; holding a part, a look that falls due while the hand is busy (its grip and
        dwell, its way back from where it waited) comes when the hand is free: from a lower
        bound of that time on, every tick (the next step's declaration is nearer). A look at
        go_t is a timer (next_timer_s)."""
        holding = self.hold_since is not None
        period = self.look_ticks
        if self.phase == Phase.HOLD and self.hand.busy and (holding or self.go_t is not None):
            # _hold decides only once the hand is free (e.g. back from where it waited)
            due = self.go_t if not holding else self.t if self.held_by_hitter else self.next_look
            due, period = max(due or self.t, self.hand.free_not_before(self.t)), 1
        elif (holding and not self.held_by_hitter) or self.phase == Phase.PROVOKE:
            due = self.next_look  # (held by its hitter it watches a status: no look needed)
        else:
            return None
        if due is None:
            return None
        # (a look already due comes at the next step)
        return max(due, self.t + 0.5 / self.facts.tick_hz), period

    def hand_speed_bound(self) -> float:
        """m/s no point of either hand exceeds: every motion is a Move whose minimum-jerk
        profile peaks at most at peak_hand_speed, for the hand's centre and, separately, for
        its turn (Hand._start); a cancel stops the hand where it is."""
        return 2.0 * self.motor.peak_hand_speed

    def next_timer_s(self, view: TaskView) -> float | None:
        """The earliest time one of its own timers may make it decide from what it perceives
        (a reaction time running out, a provoke time, a wait's limit): physics then starts an
        exchange there, so the decision reads the inputs it would read with one-tick exchanges.
        A lower bound; None if no timer runs."""
        ph, times = self.phase, []
        if ph in (Phase.REACT, Phase.HOLD) and self.go_t is not None:
            times.append(self.go_t)
        if self.still_since is not None and not self.hold_expired:
            times.append(self.still_since + self.max_hold)
        if self.provoke_times and view.task_start is not None:
            times.append(view.task_start + self.provoke_times[0])
        if ph == Phase.PROVOKE:
            times.append(self.phase_since + PROVOKE_GIVE_UP_S)
        if ph == Phase.RELEASE_CHECK and self.released_at is not None:
            times += [self.released_at + RELEASE_MIN_S, self.released_at + RELEASE_RETRY_S]
        if ph == Phase.REACH:
            segs = self.hand.segments
            times.append((segs[-1].t_end if segs else self.phase_since) + GRASP_TIMEOUT_S)
        if ph in (Phase.IDLE, Phase.DONE):
            times.append(self.phase_since + 1.0)  # hands down after a second of nothing
        if self.in_collision:
            times += [self.collision_since + 1.0, self.collision_since + COLLISION_FALLBACK_S]
        if self.touch_since is not None:
            times.append(self.touch_since + TOUCH_MAX_S)
        if self.last_press is not None:
            times.append(self.last_press + BUTTON_REPEAT_S)
        later = [x for x in times if x > self.t]
        return min(later) if later else None

    @property
    def hand(self) -> Hand:
        return self.hands[self.active]

    @property
    def ssm(self) -> bool:
        return self.facts.safety_policy == SafetyPolicy.SSM

    def rest_pose(self, name: str) -> Vec3:
        """Where a hand waits: out of the robots' way (WAIT_SSM under ssm, else REST)."""
        return WAIT_SSM[name] if self.ssm else REST[name]

    def _hands_to_wait(self, why: str) -> None:
        """Waiting: the hands (the active one with what it holds) go to their waiting poses,
        unless on their way there or there already."""
        for name, hand in self.hands.items():
            if name != self.active and not self.ssm:
                continue  # the free hand rests at REST anyway (or presses the button)
            if name != self.active and hand.busy:
                continue  # pressing the continue button
            pose = self.rest_pose(name)
            goal = hand.goal() if hand.busy else hand.pos
            if distance(goal, pose) > 0.01:
                hand.cancel()
                hand.do(Move(pose, None, FIXED_PLACE, why))

    def _set(self, phase: Phase, t: float, why: str = "") -> None:
        if phase != self.phase:
            self.log.append(
                (t, f"{self.phase.value} -> {phase.value}" + (f": {why}" if why else ""))
            )
            log.debug("t=%.3f %s -> %s %s", t, self.phase.value, phase.value, why)
        self.phase = phase
        self.phase_since = t

    def _rt(self, factor: float = 1.0) -> float:
        return reaction_time(self.motor, self.rng_rt, factor)

    def _collision_rt(self) -> float:
        """The reflex after a collision: collision_reaction_s, or half the reaction time."""
        if self.collision_reaction_s is None:
            return self._rt(0.5)
        return reaction_draw(self.collision_reaction_s, self.rng_rt)

    def next_part(self, view: TaskView) -> str | None:
        for pid in self.facts.human_sequence:
            if not view.is_placed(pid):
                return pid
        return None

    def _part(self, pid: str) -> PartFacts:
        return self.facts.parts[pid]

    def _object_pos(self, view: TaskView, pid: str) -> Vec3:
        o = view.objects.get(pid)
        if o is not None:
            return o.position
        part = self._part(pid)
        return part.start if part.start is not None else part.target

    def grasp_point(self, view: TaskView, pid: str) -> Vec3:
        size = self._part(pid).size
        return add(self._object_pos(view, pid), (0.0, 0.0, min(size[2] / 2.0, GRASP_HEIGHT_MAX)))

    def deps_done(self, view: TaskView, pid: str) -> bool:
        return all(view.is_placed(a) for a in self._part(pid).after)

    def release_point(self, pid: str) -> tuple[Vec3, float]:
        """Where the hand lets go, and its yaw_rad, so that the held part lands on its target."""
        part = self._part(pid)
        assert self.grasp is not None
        offset, hand_yaw0_rad, obj_yaw0_rad = self.grasp
        delta_rad = math.remainder(math.radians(part.target_yaw_deg) - obj_yaw0_rad, 2.0 * math.pi)
        err = (
            self.rng_place.normal(0.0, self.place_error, size=2)
            if self.place_error > 0
            else np.zeros(2)
        )
        hand = add(part.target, rotate_z_rad(offset, delta_rad))
        return (
            (hand[0] + float(err[0]), hand[1] + float(err[1]), hand[2] + RELEASE_CLEARANCE),
            hand_yaw0_rad + delta_rad,
        )

    # ------------------------------------------------------------------ caution
    def caution_radius(self) -> float:
        return 0.08 + 0.17 * self.caution

    def hitter_in_way(self, view: TaskView) -> str | None:
        """The robot that last hit it, until it has passed (moved and come to rest). From its
        state's status, which changes only where exchanges end: watched every step."""
        if self.bitten is None or self.in_collision:
            return None
        hitter, seen_moving = self.bitten
        if self._under_way(view, hitter):
            self.bitten = (hitter, True)
            return hitter
        if not seen_moving:
            return hitter  # not yet on its way again: a still robot is waited for a while
        self.bitten = None  # it moved and came to rest: passed
        return None

    def danger(self, view: TaskView, goal: Vec3) -> str | None:
        """The robot heading into the region around ``goal``, as this participant can tell at a
        look (caution: the robots' positions and motion, their lit target cues)."""
        if self.caution <= 0.0:
            return None
        radius = self.caution_radius()
        horizon = 0.5 + self.caution
        for rid in sorted(view.robots):
            robot = view.robots[rid]
            if distance(robot.tcp, goal) < radius:
                return rid
            v = view.robot_velocity(robot, self.t)
            speed = math.sqrt(v[0] ** 2 + v[1] ** 2 + v[2] ** 2)
            if speed > 0.02:
                # closest approach of the straight-line extrapolation within the horizon
                rel = (goal[0] - robot.tcp[0], goal[1] - robot.tcp[1], goal[2] - robot.tcp[2])
                s = (rel[0] * v[0] + rel[1] * v[1] + rel[2] * v[2]) / (speed * speed)
                s = min(horizon, max(0.0, s))
                p = add(robot.tcp, (v[0] * s, v[1] * s, v[2] * s))
                if distance(p, goal) < radius:
                    return rid
        if self.facts.anticipation:
            for rid in sorted(self.facts.robots):
                if view.robot_waiting(rid):
                    continue
                if any(distance(p, goal) < radius for p in view.robot_heading_points(rid)):
                    return rid
        return None

    def _under_way(self, view: TaskView, robot: str) -> bool:
        """The robot is on a move (its state says MOVING). Not its TCP's speed: the status
        changes only at ticks the exchanges end on (a move's end is declared, a new one follows
        a command), so waiting for it keeps the timing of one-tick exchanges, as a caution-free
        participant must (docs/ARCHITECTURE.md, "Exchange step")."""
        r = view.robots.get(robot)
        return r is not None and r.status == pb.MOTION_STATUS_MOVING

    def _robot_moving(self, view: TaskView, robot: str) -> bool:
        r = view.robots.get(robot)
        if r is None:
            return False
        v = view.robot_velocity(r, self.t)
        return math.sqrt(v[0] ** 2 + v[1] ** 2 + v[2] ** 2) > STILL_SPEED

    def _held_back(self, t: float, view: TaskView, goal: Vec3) -> bool:
        """True while caution holds this action back (and arranges the reaction afterwards).
        It looks at the robots when the action would start (at go_t, a timer: that tick starts
        an exchange) and, while it holds back, every LOOK_S (declared) and when the wait for a
        still robot runs out (a timer); between two looks the last one holds. So what it sees
        is what one-tick exchanges would show it."""
        if self.hold_expired:  # a robot stood still in the way long enough: go anyway
            return False
        robot = hitter = self.hitter_in_way(view)
        if robot is None:
            if self.hold_since is None:
                if self.go_t is None or t < self.go_t:
                    return False  # not deciding yet (the caller waits for go_t)
            elif not self.held_by_hitter:
                wait_over = self.still_since is not None and t - self.still_since >= self.max_hold
                if self.next_look is not None and t < self.next_look and not wait_over:
                    return True
            self.next_look = self._look_after(t)
            robot = self.danger(view, goal)
        self.held_by_hitter = hitter is not None
        if robot is not None:
            if self.hold_since is None:
                self.hold_since = t
                self.hold_backs.append((t, robot))
                self.log.append((t, f"holding back for {robot}"))
                self._hands_to_wait("wait for the way to clear")
            # A robot moving into the region is waited for as long as it moves there; one that
            # stands still in it (e.g. waiting for something the participant does not see) at
            # most max_hold in all, counted while it stands still.
            bitten = self.bitten is not None and self.bitten[0] == robot
            if self._under_way(view, robot) if bitten else self._robot_moving(view, robot):
                self.still_since = None
                self.go_t = None
                return True
            if self.still_since is None:
                self.still_since = t
            if t - self.still_since < self.max_hold:
                self.go_t = None
                return True
            self.hold_expired = True
            if self.bitten is not None and self.bitten[0] == robot:
                self.bitten = None  # it did not move on: not waited for again
            self.log.append((t, f"{robot} stood still in the way {self.max_hold:g} s: going"))
        if self.hold_since is not None:
            self.hold_since = None
            self.go_t = t + self._rt()  # react to the region clearing
            return True
        return False

    def _action_started(self) -> None:
        self.hold_since = None
        self.still_since = None
        self.hold_expired = False
        self.next_look = None
        self.held_by_hitter = False

    # ------------------------------------------------------------------ the tick
    def step(self, t: float, view: TaskView) -> Sample:
        self.t = t
        self._perceive(t, view)
        self._provoke_check(t, view)
        self._decide(t, view)
        self._press_if_cued(t, view)
        for hand in self.hands.values():
            hand.advance(t)
        self._look(t)
        left, right = self.hands["left"], self.hands["right"]
        return Sample(
            t,
            Pose(HEAD_POS, self.head_q),
            left.pose(),
            right.pose(),
            left.grip,
            right.grip,
        )

    def _perceive(self, t: float, view: TaskView) -> None:
        object_events, task_events = view.drain()
        for e in object_events:
            if e.object == self.part and e.kind == pb.ObjectEvent.KIND_RESTED:
                self.rested = True
        collision_begins = False
        hit_by: str | None = None
        for ev in task_events:
            if ev.kind == pb.TASK_EVENT_KIND_COLLISION:
                self.collision_confirmed = True
                collision_begins = True
                hit_by = ev.robot or hit_by
            elif ev.kind == pb.TASK_EVENT_KIND_CONTINUED:
                self._collision_over(t, "robots continue")
            elif (
                ev.kind == pb.TASK_EVENT_KIND_COLLISION_END
                and self.facts.safety_policy == SafetyPolicy.STOP_COLLIDING
            ):
                self._collision_over(t, "collision ended")
        if view.hand_robot_contacts:  # felt before the orchestrator announces it
            collision_begins = True
            hit_by = min(robot for _hand, robot in view.hand_robot_contacts)
        if collision_begins and not self.in_collision:
            if hit_by is not None:
                self.bitten = (hit_by, False)
            self._collision_begins(t, view)
        self._pull_away(t, view)
        if self.in_collision:
            waited = t - self.collision_since
            if (
                not self.collision_confirmed and not view.hand_robot_contacts and waited > 1.0
            ) or waited > COLLISION_FALLBACK_S:
                self._collision_over(
                    t,
                    "no collision announced" if not self.collision_confirmed else "gave up waiting",
                )

    def _pull_away(self, t: float, view: TaskView) -> None:
        """A hand that keeps touching a robot goes back to rest (a held part goes with it)."""
        if not view.hand_robot_contacts:
            self.touch_since = None
            return
        if self.touch_since is None:
            self.touch_since = t
            return
        if t - self.touch_since < TOUCH_MAX_S:
            return
        self.touch_since = t  # still touching after this move: again later
        for name in sorted({h for h, _robot in view.hand_robot_contacts}):
            hand = self.hands.get(name)
            if hand is None:
                continue
            hand.cancel()
            hand.do(Move(self.rest_pose(name), None, FIXED_PLACE, "pull away"))
            if name == self.active and self.phase != Phase.DONE:
                self._set(Phase.PULLBACK, t, "still touching a robot")

    def _collision_begins(self, t: float, view: TaskView) -> None:
        self.in_collision = True
        self.collision_since = t
        self.provoke_robot = None
        holding = self.part is not None and view.held_by(self.part) == self.active
        hand = self.hand
        if self.ssm:
            # The touched robot stays in its protective stop while a hand is near it: a short
            # pull-back could leave both waiting for each other. Both hands go out of its reach
            # (the active one below, after its reflex).
            self._hands_to_wait("out of the stopped robot's reach")
        hand.cancel()
        if not holding:
            hand.do(Grip(0.0))
        back = (hand.pos[0], max(HAND_Y_MIN, hand.pos[1] + PULLBACK[1]), hand.pos[2] + PULLBACK[2])
        if self.ssm:
            back = self.rest_pose(self.active)
        hand.do(Dwell(self._collision_rt(), "reflex"), Move(back, None, GROSS_WIDTH, "pull back"))
        self._set(Phase.PULLBACK, t, "collision")

    def _collision_over(self, t: float, why: str) -> None:
        if self.in_collision:
            self.log.append((t, f"collision over: {why}"))
        self.in_collision = False
        self.collision_confirmed = False
        self.last_press = None

    def _provoke_check(self, t: float, view: TaskView) -> None:
        if not self.provoke_times or self.in_collision:
            return
        tt = view.task_time(t)
        if tt is None or tt < self.provoke_times[0]:
            return
        interruptible = self.phase in (
            Phase.IDLE,
            Phase.REACT,
            Phase.WAIT_DEPS,
            Phase.HOLD,
            Phase.DONE,
            Phase.WITHDRAW,
        )
        if self.phase in (Phase.REACH, Phase.CARRY):
            interruptible = self.hand.segment is not None and self.hand.pending_grip_change()
        if interruptible and self._start_provoke(t, view, f"at task time {tt:.2f} s"):
            self.provoke_times.pop(0)

    def _start_provoke(self, t: float, view: TaskView, why: str) -> bool:
        hand = self.hand
        if not view.robots:
            return False
        rid = min(sorted(view.robots), key=lambda r: distance(view.robots[r].tcp, hand.pos))
        hand.cancel()
        if not (self.part is not None and view.held_by(self.part) == self.active):
            hand.do(Grip(0.0))
        hand.do(Move(self._provoke_goal(view, rid), None, 0.05, "provoke"))
        self.next_look = self._look_after(t)
        self.provoke_robot = rid
        self._set(Phase.PROVOKE, t, f"reaching into {rid} {why}")
        return True

    @staticmethod
    def _provoke_goal(view: TaskView, rid: str) -> Vec3:
        # just above the tool tip: inside the tool/wrist links' colliders
        return add(view.robots[rid].tcp, (0.0, 0.0, 0.02))

    # ------------------------------------------------------------------ decisions
    def _decide(self, t: float, view: TaskView) -> None:
        hand = self.hand
        ph = self.phase
        if ph == Phase.PULLBACK:
            if not hand.busy:
                if self.part is not None and view.held_by(self.part) == self.active:
                    self.go_t = t + self._rt()
                    self._set(Phase.HOLD, t, "still holding the part")
                else:
                    self._set(Phase.COLLISION_WAIT, t)
            return
        if ph == Phase.COLLISION_WAIT:
            if not self.in_collision:
                self._set(Phase.IDLE, t, "collision over")
                self.go_t = None
                return
            self._maybe_press_button(t, view)
            return
        if ph == Phase.PROVOKE:
            self._provoke_step(t, view)
            return
        if ph in (Phase.IDLE, Phase.DONE):
            self._idle(t, view)
        elif ph == Phase.REACT:
            self._react(t, view)
        elif ph == Phase.REACH:
            self._reach(t, view)
        elif ph == Phase.HOLD:
            self._hold(t, view)
        elif ph == Phase.WAIT_DEPS:
            if self.part is None or view.held_by(self.part) != self.active:
                self._set(Phase.IDLE, t, "part lost")
            elif self.deps_done(view, self.part):
                self.go_t = t + self._rt()
                self._set(Phase.HOLD, t, "dependencies placed")
        elif ph == Phase.CARRY:
            if not hand.busy:
                self.released_at = t
                self.rested = False
                self._set(Phase.RELEASE_CHECK, t)
            elif (
                self.part is not None
                and view.held_by(self.part) != self.active
                and hand.pending_grip_change()
                and hand.segment is not None
            ):
                hand.cancel()
                self._set(Phase.IDLE, t, "part dropped while carrying")
        elif ph == Phase.RELEASE_CHECK:
            self._release_check(t, view)
        elif ph == Phase.WITHDRAW and not hand.busy:
            self._set(Phase.IDLE, t)

    def _idle(self, t: float, view: TaskView) -> None:
        hand = self.hand
        pid = self.next_part(view)
        if pid is None:
            if self.phase != Phase.DONE:
                hand.cancel()
                hand.do(Grip(0.0), Move(self.rest_pose(self.active), 0.0, FIXED_PLACE, "rest"))
                self._set(Phase.DONE, t, "all parts placed")
            return
        if self.phase == Phase.DONE:  # a part came undone? start again
            self._set(Phase.IDLE, t)
        self.part = pid
        if view.held_by(pid) == self.active:
            self._grasped(t, view)
            return
        if view.is_grabbable(pid) and not self.in_collision:
            self.go_t = t + self._rt()
            self._set(Phase.REACT, t, f"{pid} is grabbable")
            return
        # Nothing to do for a while: hands down.
        if t - self.phase_since > 1.0:
            if not hand.busy and distance(hand.pos, self.rest_pose(self.active)) > 0.01:
                hand.do(Move(self.rest_pose(self.active), 0.0, FIXED_PLACE, "rest"))
            if self.ssm:
                self._hands_to_wait("rest")

    def _react(self, t: float, view: TaskView) -> None:
        pid = self.part
        if pid is None or self.in_collision or not view.is_grabbable(pid):
            self._set(Phase.IDLE, t, "nothing to grab")
            return
        goal = self.grasp_point(view, pid)
        above = add(goal, (0.0, 0.0, APPROACH_CLEARANCE))
        if self._held_back(t, view, above):
            return
        if self.go_t is None or t < self.go_t:
            return
        if pid not in self.provoked_parts and self.facts.provoke_probability > 0.0:
            self.provoked_parts.add(pid)
            if self.rng_provoke.random() < self.facts.provoke_probability and self._start_provoke(
                t, view, f"before reaching for {pid}"
            ):
                return
        hand = self.hand
        hand.cancel()
        obj_yaw_rad = (
            view.objects[pid].yaw_rad
            if pid in view.objects
            else math.radians(self._part(pid).start_yaw_deg)
        )
        hand.do(*reach_plan(above, goal, obj_yaw_rad, self.motor, self.stop_above, self.pick_dwell))
        self._action_started()
        self._set(Phase.REACH, t, f"reaching for {pid}")

    def _reach(self, t: float, view: TaskView) -> None:
        pid = self.part
        assert pid is not None
        hand = self.hand
        if (
            view.held_by(pid) == self.active
            and not hand.pending_grip_change()
            and hand.segment is None
            and not hand.plan
        ):
            self._grasped(t, view)
            return
        if hand.busy:
            # the part moved (e.g. still rolling after a missed release): aim again
            if (
                hand.pending_grip_change()
                and any(isinstance(s, Grip) and s.value >= GRIP_CLOSED for s in hand.plan)
                and distance(self.grasp_point(view, pid), self._planned_grasp(hand)) > 0.02
            ):
                self.go_t = t
                self._set(Phase.REACT, t, f"{pid} moved")
            return
        if view.held_by(pid) == self.active:
            self._grasped(t, view)
        elif self._grasp_waited(t) > GRASP_TIMEOUT_S:
            hand.do(Grip(0.0))
            self._set(Phase.IDLE, t, f"{pid} not held after gripping")

    def _grasp_waited(self, t: float) -> float:
        segs = self.hand.segments
        end = segs[-1].t_end if segs else self.phase_since
        return t - end

    @staticmethod
    def _planned_grasp(hand: Hand) -> Vec3:
        moves = [s for s in hand.plan if isinstance(s, Move)]
        if moves:
            return moves[-1].goal
        return hand.goal()

    def _grasped(self, t: float, view: TaskView) -> None:
        pid = self.part
        assert pid is not None
        hand = self.hand
        obj = view.objects[pid]
        self.grasp = (
            (
                hand.pos[0] - obj.position[0],
                hand.pos[1] - obj.position[1],
                hand.pos[2] - obj.position[2],
            ),
            hand.yaw_rad,
            obj.yaw_rad,
        )
        self.go_t = t  # a continuous action: no new reaction time
        self._set(Phase.HOLD, t, f"holding {pid}")

    def _hold(self, t: float, view: TaskView) -> None:
        pid = self.part
        hand = self.hand
        if pid is None or view.held_by(pid) != self.active:
            self._set(Phase.IDLE, t, "part lost")
            return
        if hand.busy:
            return
        if self.grasp is None:
            self._grasped(t, view)
        release, yaw_rad = self.release_point(pid)
        part = self._part(pid)
        carry_z = max(hand.pos[2], release[2] + CARRY_CLEARANCE)
        if not self.deps_done(view, pid):
            if self.ssm:  # holding it beside the body, out of every robot's protective distance
                self._hands_to_wait("wait with the part")
            elif carry_z - hand.pos[2] > 0.01:
                hand.do(
                    Move((hand.pos[0], hand.pos[1], carry_z), None, GROSS_WIDTH, "lift and wait")
                )
            self._set(Phase.WAIT_DEPS, t, f"{pid} waits for {', '.join(part.after)}")
            return
        hover = (release[0], release[1], carry_z)
        if self._held_back(t, view, hover):
            return
        if self.go_t is None or t < self.go_t:
            return
        hand.do(
            *place_plan(
                hand.pos,
                carry_z,
                release,
                yaw_rad,
                2.0 * self.facts.place_tolerance_m,
                self.stop_above,
                self.place_dwell,
            )
        )
        self._action_started()
        self._set(Phase.CARRY, t, f"carrying {pid}")

    def _release_check(self, t: float, view: TaskView) -> None:
        pid = self.part
        assert pid is not None and self.released_at is not None
        hand = self.hand
        if view.is_placed(pid):
            hand.do(
                Move(add(hand.pos, (0.0, 0.0, APPROACH_CLEARANCE)), None, GROSS_WIDTH, "withdraw")
            )
            self.grasp = None
            self._set(Phase.WITHDRAW, t, f"{pid} placed")
            return
        waited = t - self.released_at
        if view.held_by(pid) == self.active and waited > RELEASE_MIN_S:
            self._grasped(t, view)  # never let go (grip ignored?): try placing again
            return
        if waited > RELEASE_MIN_S and (self.rested or waited > RELEASE_RETRY_S):
            self.grasp = None
            self._set(Phase.IDLE, t, f"{pid} missed its target: grab it again")

    def _maybe_press_button(self, t: float, view: TaskView) -> None:
        button = self.facts.continue_button
        if button is None or self.facts.safety_policy != SafetyPolicy.RETREAT_BUTTON:
            return
        if not view.cue_on(CONTINUE_BUTTON_CUE) and t - self.collision_since < 2.0:
            return
        if self.last_press is not None and t - self.last_press < BUTTON_REPEAT_S:
            return
        free = self.hands[self.free]
        if free.busy:
            return
        self.last_press = t
        free.do(
            Dwell(self._rt()),
            Move(add(button, (0.0, 0.0, 0.01)), 0.0, 0.03, "button"),
            Dwell(0.3, "press"),
            Move(self.rest_pose(self.free), 0.0, FIXED_PLACE, "rest"),
        )
        self.log.append((t, "pressing the continue button"))

    def _press_if_cued(self, t: float, view: TaskView) -> None:
        """The continue button's cue is on: press it with the free hand, whatever the active
        hand does (it keeps what it holds); again after BUTTON_REPEAT_S if the cue stays on."""
        if (
            self.facts.continue_button is None
            or self.facts.safety_policy != SafetyPolicy.RETREAT_BUTTON
        ):
            return
        if not view.cue_on(CONTINUE_BUTTON_CUE):
            return
        self._maybe_press_button(t, view)

    def _provoke_step(self, t: float, view: TaskView) -> None:
        hand = self.hand
        rid = self.provoke_robot
        if rid is None or rid not in view.robots or t - self.phase_since > PROVOKE_GIVE_UP_S:
            hand.cancel()
            self._set(Phase.IDLE, t, "gave up provoking")
            return
        if self.next_look is not None and t < self.next_look:
            return  # it looks at the tool every LOOK_S
        self.next_look = self._look_after(t)
        if not hand.busy:  # arrived but no contact yet: follow the tool
            goal = self._provoke_goal(view, rid)
            hand.do(Move(goal, None, 0.02, "provoke"))

    # ------------------------------------------------------------------ head
    def _look(self, t: float) -> None:
        goal = self.hand.goal() if self.hand.busy else self.hand.pos
        # Per tick: the goal and the tick length rarely change, so their look and weight are
        # kept (the same values the formulas give: same inputs, same floats).
        if goal != self._look_goal:
            self._look_goal, self._look_q = goal, look_quat(HEAD_POS, goal)
        dt = max(0.0, t - (self._head_t if self._head_t is not None else t))
        self._head_t = t
        if dt != self._look_dt:
            self._look_dt = dt
            self._look_u = 1.0 - math.exp(-dt / HEAD_TIME_CONSTANT_S) if dt > 0 else 0.0
        u = self._look_u
        self.head_q = slerp(self.head_q, self._look_q, u) if u > 0 else self.head_q

    # ------------------------------------------------------------------ analysis
    def reaches(self) -> list:
        """Every minimum-jerk segment either hand made."""
        return sorted(
            self.hands["left"].segments + self.hands["right"].segments, key=lambda s: s.t0
        )
