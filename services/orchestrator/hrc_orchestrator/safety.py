"""Human-robot collisions (three policies) and robot-robot near collisions: see
docs/task-semantics.md, "Human-robot collisions" and "Near collisions".

Policies on a hand touching a robot:
- ``retreat``: every robot goes to its retreat pose keeping what it holds; when all have arrived
  they resume their interrupted targets (CONTINUED, delay = resume - collision).
- ``retreat_button``: as ``retreat``, but they resume only once a hand has touched the continue
  button after the collision (and all have arrived); the button cue flashes meanwhile.
- ``stop_colliding``: only the touched robot holds, until no hand touches it any more; the other
  robots carry on.
- ``ssm``: speed and separation monitoring (hrc_orchestrator.ssm, docs/safety-ssm.md): each
  robot's speed is scaled from its separation to the participant, a protective stop at the
  protective distance, a resume by itself. No retreat. A touch is a collision as under the other
  policies and keeps the touched robot in its protective stop until the hand has left (CONTINUED
  when it resumes).
Under the retreat policies collisions are handled one at a time (touches during a collision are
not counted). Under ``stop_colliding`` each robot's halt is its own collision, so a hand that
touches the second robot also stops that one (it would be unsafe to let it carry on).

Near collisions: when the inflated volumes of two arms touch, the arm farther from its own current
target holds (tie: the one whose id sorts last, i.e. r2) until the volumes separate. Only an arm
that can move can part the volumes, so the rule never halts the only arm that can move: when one
of the two cannot (it waits at its intermediate pose, is finished, is halted by a hand, is in
a protective stop as sent to it, has arrived at its retreat pose, or reports its target
unreachable), that one holds instead; and
when the arm left moving comes to a stop while the other one holds, they swap.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from hrc.geometry import distance, vec3
from hrc.scenario import SafetyPolicy
from hrc.wire import pb

from hrc_orchestrator import events as ev
from hrc_orchestrator.board import Board
from hrc_orchestrator.robots import HOLD, Motion, Phase, RobotAgent
from hrc_orchestrator.ssm import Change, SsmMonitor, SsmState


@dataclass
class CollisionRecord:
    n: int
    t_s: float
    robot: str
    hand: str
    delay_s: float | None = None
    hand_left: bool = False


@dataclass
class RetreatState:
    """A collision under a retreat policy, from the touch until the robots resume."""

    record: CollisionRecord
    retreat: dict[str, Motion]
    arrived: dict[str, bool] = field(default_factory=dict)
    pressed: bool = False


class Safety:
    def __init__(
        self,
        policy: SafetyPolicy,
        agents: dict[str, RobotAgent],
        board: Board,
        ssm: dict[str, SsmMonitor] | None = None,
    ) -> None:
        self.policy = SafetyPolicy(policy)  # ValueError for a string that is not a policy
        # ssm: one monitor per robot (empty under the other policies)
        self.ssm: dict[str, SsmMonitor] = ssm if self.policy == SafetyPolicy.SSM and ssm else {}
        self.ssm_collided: dict[str, CollisionRecord] = {}  # ssm: robot -> touch until resume
        self.agents = agents
        self.board = board
        # Insertion-ordered dicts used as sets: iteration order never depends on hashing.
        self._hand_touch: dict[tuple[str, str, str], None] = {}
        self._button_touch: dict[str, None] = {}
        self._near_touch: dict[tuple[str, str, str], None] = {}
        self.records: list[CollisionRecord] = []
        self.retreating: RetreatState | None = None
        self.halted: dict[str, CollisionRecord] = {}  # stop_colliding: robot -> its collision
        self.near_yield: dict[tuple[str, str], str] = {}  # pair -> the robot that holds
        self.near_times: list[float] = []

    # ------------------------------------------------------------------ queries
    @property
    def blocks_grab(self) -> bool:
        """During a collision the participant may not grab a new object."""
        return self.retreating is not None or bool(self.halted) or bool(self.ssm_collided)

    @property
    def button_wanted(self) -> bool:
        """The continue button flashes: a retreat_button collision that was not yet confirmed."""
        return (
            self.policy == SafetyPolicy.RETREAT_BUTTON
            and self.retreating is not None
            and not self.retreating.pressed
        )

    def override(self, robot: str) -> Motion | None:
        """What safety makes the robot do instead of its phase goal (None: nothing)."""
        if not self.halted and not self.near_yield and self.retreating is None:
            return None  # the usual case, asked 4 times per tick
        if robot in self.halted:
            return HOLD
        if any(r == robot for r in self.near_yield.values()):
            return HOLD
        if self.retreating is not None and robot in self.retreating.retreat:
            return self.retreating.retreat[robot]
        return None

    @property
    def total_delay(self) -> float:
        return sum(r.delay_s for r in self.records if r.delay_s is not None)

    def _touching(self, robot: str) -> bool:
        return any(k[1] == robot for k in self._hand_touch)

    # ------------------------------------------------------------------ contacts
    def hand_robot(self, c: pb.Contact, t: float, running: bool) -> None:
        hand, robot = c.a, c.b
        if robot not in self.agents:
            return
        key = (hand, robot, c.link)
        if not c.begin:
            self._hand_touch.pop(key, None)
            if not self._touching(robot):
                self._hand_left(robot, t)
            return
        self._hand_touch[key] = None
        if not running:
            return
        if self.policy == SafetyPolicy.SSM:
            self.ssm[robot].touched = True
            if robot not in self.ssm_collided:
                self.ssm_collided[robot] = self._new_record(t, robot, hand, c.link)
        elif self.policy == SafetyPolicy.STOP_COLLIDING:
            if robot not in self.halted:
                rec = self._new_record(t, robot, hand, c.link)
                self.halted[robot] = rec
                self.board.emit(
                    ev.robot_halted(t, robot, f"{hand} hand touches it (collision {rec.n})")
                )
        elif self.retreating is None:
            rec = self._new_record(t, robot, hand, c.link)
            retreat: dict[str, Motion] = {}
            for rid, agent in self.agents.items():
                yaw_deg = (
                    agent.sent.yaw_deg
                    if agent.sent is not None and agent.sent.is_move
                    else (agent.goal.yaw_deg if agent.goal is not None else 0.0)
                )
                retreat[rid] = Motion.detour_to(vec3(agent.cfg.retreat), yaw_deg)
            self.retreating = RetreatState(rec, retreat, {rid: False for rid in self.agents})

    def _new_record(self, t: float, robot: str, hand: str, link: str) -> CollisionRecord:
        rec = CollisionRecord(len(self.records) + 1, t, robot, hand)
        self.records.append(rec)
        self.board.emit(ev.collision(t, rec.n, robot, hand, link))
        return rec

    def _hand_left(self, robot: str, t: float) -> None:
        for rec in self.records:
            if rec.robot == robot and not rec.hand_left:
                rec.hand_left = True
                self.board.emit(ev.collision_end(t, rec.n, robot, rec.hand))
        if robot in self.ssm:
            self.ssm[robot].touched = False  # it resumes by the separation rule (update)
        rec_halted = self.halted.pop(robot, None)
        if rec_halted is not None:
            self._resume(rec_halted, t, robot)

    def button(self, c: pb.Contact, t: float) -> None:
        if not c.begin:
            self._button_touch.pop(c.a, None)
            return
        self._button_touch[c.a] = None
        if self.button_wanted:
            assert self.retreating is not None
            self.retreating.pressed = True
            self.board.emit(ev.button_pressed(t, c.a))

    def robot_robot(self, c: pb.Contact, t: float, running: bool) -> None:
        if c.a not in self.agents or c.b not in self.agents or c.a == c.b:
            return
        a, b = sorted((c.a, c.b))
        key = (a, b, c.link)
        if not c.begin:
            self._near_touch.pop(key, None)
            if not any(k[:2] == (a, b) for k in self._near_touch):
                halted = self.near_yield.pop((a, b), None)
                if halted is not None:
                    n = len(self.near_times)
                    self.board.emit(ev.near_collision_end(t, n, halted))
            return
        already = any(k[:2] == (a, b) for k in self._near_touch)
        self._near_touch[key] = None
        if already or not running:
            return
        d_a, d_b = self._distance_to_target(a), self._distance_to_target(b)
        move_a, move_b = self.can_move(a), self.can_move(b)
        n = len(self.near_times) + 1
        if move_a != move_b:  # never halt the only arm that can move
            halted = b if move_a else a
            why = f"near-collision {n}, {a if move_a else b} is the only arm that can move"
        else:
            # The arm farther from its own target yields; exact tie: the id that sorts last (r2).
            halted = a if d_a > d_b else b
            why = f"near-collision {n}, farther from its target"
        self.near_yield[(a, b)] = halted
        self.near_times.append(t)
        self.board.emit(ev.near_collision(t, n, a, b, halted, d_a, d_b))
        self.board.emit(ev.robot_halted(t, halted, why))

    def can_move(self, robot: str) -> bool:
        """The arm has a motion to make that only a near-collision hold keeps it from."""
        agent = self.agents[robot]
        st = agent.state
        if (
            robot in self.halted
            or self.stopped_at_arm(robot)
            or (
                st is not None
                and st.command_id == agent.sent_id
                and st.status == pb.MOTION_STATUS_UNREACHABLE
            )
        ):
            return False
        if self.retreating is not None and robot in self.retreating.retreat:
            return not self.retreating.arrived.get(robot, False)
        if agent.phase == Phase.SCREWING:
            return True  # the dwell ends by itself, then it moves on
        if agent.phase in (Phase.NOT_STARTED, Phase.WAITING, Phase.FINISHED):
            return False
        return agent.goal is not None and agent.goal.is_move and not agent.reached(agent.goal)

    def swap_stuck_yields(self, t: float) -> None:
        """A held arm whose partner cannot move any more takes over: the partner holds. After
        the phase machines' tick (an arm that just reached a goal has its next one by then)."""
        for pair, held in list(self.near_yield.items()):
            other = pair[1] if pair[0] == held else pair[0]
            if not self.can_move(other) and self.can_move(held):
                self.near_yield[pair] = other
                n = len(self.near_times)
                self.board.emit(
                    ev.robot_halted(
                        t,
                        other,
                        f"near-collision {n}, {held} is the only arm that can move: it goes on",
                    )
                )

    def _distance_to_target(self, robot: str) -> float:
        agent = self.agents[robot]
        tcp = agent.tcp
        target = None
        if self.retreating is not None and robot in self.retreating.retreat:
            target = self.retreating.retreat[robot].target
        elif agent.goal is not None and agent.goal.is_move:
            target = agent.goal.target
        if tcp is None or target is None:
            return 0.0
        return distance(tcp, target)

    # ------------------------------------------------------------------ per tick
    def protective_stop(self, robot: str) -> bool:
        mon = self.ssm.get(robot)
        return mon is not None and mon.state == SsmState.STOPPED

    def stopped_at_arm(self, robot: str) -> bool:
        """The robot's protective stop as sent to it (SsmMonitor.stopped_at_arm)."""
        mon = self.ssm.get(robot)
        return mon is not None and mon.stopped_at_arm

    def observe_separations(self, msg: pb.Separations) -> None:
        for sep in msg.separations:
            mon = self.ssm.get(sep.robot)
            if mon is not None:
                mon.observe(sep.distance_m, sep.body)

    def update_ssm(self, t: float, dt: float, running: bool, tick: int) -> None:
        """Each robot's scale, protective stops and resumes: at its scans, for the separation
        then; between them, a stop for a touch."""
        for rid, mon in self.ssm.items():
            st = self.agents[rid].state
            change = mon.update(t, dt, running, st.tcp_speed if st is not None else 0.0, tick)
            if change is not None:
                self._protective(t, rid, change)
            if mon.due(tick):
                mon.stopped_at_arm = mon.state == SsmState.STOPPED

    def _protective(self, t: float, robot: str, change: Change) -> None:
        if change.stopped:
            self.board.emit(ev.protective_stop(t, robot, change))
            return
        self.board.emit(ev.protective_resume(t, robot, change))
        rec = self.ssm_collided.pop(robot, None)
        if rec is not None:
            self._resume(rec, t, robot)

    def update(self, t: float) -> None:
        """Retreat arrivals, and the resume under the retreat policies."""
        state = self.retreating
        if state is None:
            return
        for rid, agent in self.agents.items():
            if not state.arrived[rid] and agent.reached(state.retreat[rid]):
                state.arrived[rid] = True
                self.board.emit(ev.retreat_reached(t, rid, state.record.n))
        if all(state.arrived.values()) and (self.policy == SafetyPolicy.RETREAT or state.pressed):
            self.retreating = None
            self._resume(state.record, t, "")

    def _resume(self, rec: CollisionRecord, t: float, robot: str) -> None:
        rec.delay_s = t - rec.t_s
        self.board.emit(ev.continued(t, rec.n, rec.delay_s, robot))

    def finalize(self, t: float) -> None:
        """The task ended: collisions still open count their delay up to now."""
        for rec in self.records:
            if rec.delay_s is None:
                rec.delay_s = t - rec.t_s
        self.retreating = None
        self.halted.clear()
        self.ssm_collided.clear()
        self.near_yield.clear()
