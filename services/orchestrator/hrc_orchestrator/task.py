"""The task logic (docs/task-semantics.md) as a pure state machine: no bus, no I/O, no wall
clock (except the one start date string, injectable).

    task = Task(scenario)                       # hrc.scenario.Scenario
    out = task.step(tick, sim_time, inputs)     # per co-simulation tick, inputs of that tick
    out.robot_commands, out.world_commands, out.events, out.cues, out.stop

Same scenario and same inputs give the same outputs: everything is iterated in scenario order or
sorted, never in hash order.
"""

from __future__ import annotations

import datetime as dt
import math
from collections.abc import Callable

from hrc import scenario as sc
from hrc.geometry import Vec3, add, vec3, vec3_from_pb, vec3_to_pb
from hrc.scenario.conventions import (
    CONTINUE_BUTTON_CUE,
    HANDS,
    WAITING_HEIGHT_M,
    WAITING_TEXT,
    outline_cue_id,
    target_cue_id,
    waiting_cue_id,
)
from hrc.ssm import scan_ticks
from hrc.wire import pb

from hrc_orchestrator import events as ev
from hrc_orchestrator.board import Board
from hrc_orchestrator.cues import HUMAN_COLOR, CueBoard
from hrc_orchestrator.exchange import Inputs, Outputs
from hrc_orchestrator.human import HumanAgent
from hrc_orchestrator.robots import Phase, RobotAgent
from hrc_orchestrator.safety import Safety
from hrc_orchestrator.ssm import SsmMonitor
from hrc_orchestrator.watchdog import (
    PARTICIPANT_WAIT_NOTICE_S,
    Watchdog,
    describe,
    unreachable,
    waits_on_participant,
)


def wall_clock_now() -> str:
    """The one wall-clock read of the task: the start date, logged, never computed with."""
    return dt.datetime.now().astimezone().isoformat(timespec="seconds")


class Task:
    def __init__(
        self,
        scenario: sc.Scenario,
        *,
        wall_clock: Callable[[], str] = wall_clock_now,
        stall_timeout_s: float | None = None,
    ) -> None:
        self.scenario = scenario
        self.board = Board(scenario)
        self.human = HumanAgent(scenario, self.board)
        self.agents: dict[str, RobotAgent] = {
            rid: RobotAgent(robot, scenario.sequence_of(rid), self.board)
            for rid, robot in scenario.robots.items()
        }
        self.dt = 1.0 / scenario.scenario.tick_hz
        monitors: dict[str, SsmMonitor] = {}
        for rid, robot in scenario.robots.items():
            params = scenario.ssm_of(rid)
            monitors[rid] = SsmMonitor(params, robot.max_tcp_speed, scan_ticks(params, self.dt))
        self.safety = Safety(scenario.conditions.safety_policy, self.agents, self.board, monitors)
        self._sent_scale: dict[str, float] = {rid: 1.0 for rid in scenario.robots}
        self.anticipation = scenario.conditions.anticipation
        self.cue_board = CueBoard()
        self._wall_clock = wall_clock
        self.watchdog = Watchdog(
            scenario.scenario.stall_timeout_s if stall_timeout_s is None else stall_timeout_s,
            live=scenario.participant.input == sc.InputSource.VR,
        )
        self.wall_start = ""
        self.started = False
        self.finished = False  # every agent done and every robot home: the run ends
        self.start_sim_time = 0.0
        # The thesis's end: the human and every robot done (robots at their last placement).
        self.completion_s: float | None = None
        self.completion_home_s: float | None = None  # ... and every robot back home
        self.tick = 0
        self.sim_time = 0.0
        self._grabbable: dict[str, bool] = {}
        # What the grabbable flags and the cues were last computed from: per tick, and they
        # change only with these (see _grabbable_changes, _cue_changes).
        self._grabbable_key: tuple[object, ...] | None = None
        self._cues_key: tuple[object, ...] | None = None
        self._positions: dict[str, Vec3] = {
            p.id: vec3(p.start.xyz) for p in scenario.parts if p.start is not None
        }

    # ------------------------------------------------------------------ time
    @property
    def running(self) -> bool:
        return self.started and not self.finished

    def now(self) -> float:
        """Task time: seconds since the first grab (0 before)."""
        return self.sim_time - self.start_sim_time if self.started else 0.0

    # ------------------------------------------------------------------ the tick
    def step(self, tick: int, sim_time: float, inputs: Inputs, first: bool = True) -> Outputs:
        """``first``: the tick opens an exchange (the inputs of the ticks before it are all
        here; inside an exchange those of its earlier ticks come at its end)."""
        self.tick, self.sim_time = tick, sim_time
        out = Outputs()
        if self.finished or self.watchdog.message:
            return out
        sampling = self.running
        for state in inputs.robot_states:
            agent = self.agents.get(state.robot)
            if agent is not None:
                agent.observe(state)
        for agent in self.agents.values():
            agent.sample_speed(tick, sampling, first)
        if not self.started and not self.human.sequence:
            self._start("")  # nothing to grab: the task starts at once
        for msg in inputs.objects:
            for obj in msg.objects:
                self._positions[obj.id] = vec3_from_pb(obj.pose.position)
            for e in msg.events:
                self._object_event(e)
        for contacts in inputs.contacts:
            for c in contacts.contacts:
                self._contact(c)
        for seps in inputs.separations:
            self.safety.observe_separations(seps)
        t = self.now()
        self.human.update_idle(t, self.running)
        self.safety.update_ssm(t, self.dt, self.running, tick)
        if self.running:
            self.safety.update(t)
            for rid, agent in self.agents.items():
                agent.advance(t, active=self.safety.override(rid) is None)
            self.safety.swap_stuck_yields(t)
            stuck = unreachable(self)
            if stuck:
                self._end_now(out, stuck)
                return out
            agents = self.agents.values()
            if (
                self.completion_s is None
                and self.human.done
                and all(a.completion_s is not None for a in agents)
            ):
                self._complete(t)
            if self.human.done and all(a.finished for a in agents):
                self._finish(t)
                out.stop = "task finished"
        if not self.finished:
            out.robot_commands = self._commands()
        events, world = self.board.drain()
        out.events = events
        out.world_commands = world + self._grabbable_changes()
        out.cues = self._cue_changes()
        if not self.finished:
            fired = self.watchdog.check(sim_time, out)
            if self.watchdog.live:
                self._participant_wait(sim_time, out, fired)
            elif fired:
                self._stall(out)
        return out

    def _participant_wait(self, sim_time: float, out: Outputs, fired: bool) -> None:
        """A live trial: a wait on the person is announced, never a stall; a robot stuck on its
        own still ends the trial."""
        wd = self.watchdog
        quiet = wd.quiet_s(sim_time)
        if not fired and (wd.announced or quiet < PARTICIPANT_WAIT_NOTICE_S):
            return
        what = waits_on_participant(self)
        if not what:
            if fired:
                self._stall(out)
            return
        if not wd.announced:
            wd.announced = what
            out.events.append(ev.participant_wait(self.now(), what, quiet))

    def next_scan_tick(self) -> tuple[int, int]:
        """ssm: the first tick after the last one stepped at which a robot's monitor scans the
        separation, and the ticks from it to the next scan of any robot (the scan period where
        every robot's is the same); (0, 0) under the other policies (TickAck.next_sample_tick,
        sample_period_ticks).

        Where the robots' periods differ, the scans are no grid, and a declared first scan
        alone let the exchange that starts there run past the next one (another robot's), whose
        monitor then decided from the separation of that exchange's first tick. The gap to the
        next scan ends that exchange before it; the grid it implies further on holds only until
        the next ack, which declares the scans after."""
        periods = {mon.scan for mon in self.safety.ssm.values()}
        if not periods:
            return 0, 0
        first = min((self.tick // p + 1) * p for p in periods)
        second = min((first // p + 1) * p for p in periods)
        return first, second - first

    def next_event_tick(self) -> int:
        """The first tick after the last one stepped at which a timer of the task runs out
        (a screw's dwell: the robot then returns), holding the inputs; 0: none
        (TickAck.next_event_tick)."""
        if not self.running:
            return 0
        best = 0
        for agent in self.agents.values():
            end = agent.dwell_end()
            if end is None:
                continue
            # the tick whose task time first passes advance()'s test, as step() computes it
            k = max(self.tick + 1, math.floor((end + self.start_sim_time) / self.dt) - 1)
            while not agent.dwell_over(k * self.dt - self.start_sim_time):
                k += 1
            best = k if best == 0 else min(best, k)
        return best

    def _end_now(self, out: Outputs, msg: str) -> None:
        """A robot cannot go on: end the run now, as a stall would after its timeout."""
        self.watchdog.message = msg
        events, world = self.board.drain()
        out.events = [*events, ev.stalled(self.now(), msg)]
        out.world_commands = world
        out.stalled = msg

    def _stall(self, out: Outputs) -> None:
        """Nothing progressed for the watchdog's timeout: say who waits on what, end."""
        msg = describe(self, self.watchdog.timeout_s)
        self.watchdog.message = msg  # from now on the task does nothing: its numbers stay
        out.events.append(ev.stalled(self.now(), msg))
        out.stalled = msg

    # ------------------------------------------------------------------ inputs
    def _object_event(self, e: pb.ObjectEvent) -> None:
        if e.kind == pb.ObjectEvent.KIND_GRABBED:
            if not self.started and e.object == self.human.first_part and e.holder in HANDS:
                self._start(e.object)
            if self.running:
                self.human.grabbed(e, self.now())
        elif e.kind == pb.ObjectEvent.KIND_RELEASED and self.running:
            self.human.released(e, self.now())
        # SPAWNED / SNAPPED / RESTED and robot grabs confirm what this task commanded.

    def _contact(self, c: pb.Contact) -> None:
        t = self.now()
        if c.kind == pb.CONTACT_KIND_HAND_ENVELOPE:
            self.human.envelope(c)
        elif c.kind == pb.CONTACT_KIND_HAND_ROBOT:
            self.safety.hand_robot(c, t, self.running)
        elif c.kind == pb.CONTACT_KIND_HAND_BUTTON:
            if self.running:
                self.safety.button(c, t)
        elif c.kind == pb.CONTACT_KIND_ROBOT_ROBOT:
            self.safety.robot_robot(c, t, self.running)

    # ------------------------------------------------------------------ start and end
    def _start(self, first_part: str) -> None:
        self.started = True
        self.start_sim_time = self.sim_time
        self.wall_start = self._wall_clock()
        self.board.emit(ev.task_started(self.wall_start, first_part))
        if not self.human.sequence:
            self.human.finish(0.0)
        for agent in self.agents.values():
            agent.start(0.0)

    @property
    def done(self) -> bool:
        """The task is finished in the thesis's sense (the robots may still be heading home)."""
        return self.completion_s is not None

    def _complete(self, t: float) -> None:
        """The thesis's TASK FINISHED: the human and every robot done."""
        self.completion_s = t
        self.board.emit(ev.task_finished(t, len(self.safety.records), len(self.safety.near_times)))

    def _finish(self, t: float) -> None:
        """Every robot is home too: the run ends."""
        self.finished = True
        self.completion_home_s = t
        self.safety.finalize(t)

    # ------------------------------------------------------------------ outputs
    def _commands(self) -> list[pb.RobotCommand]:
        cmds: list[pb.RobotCommand] = []
        for rid, agent in self.agents.items():
            motion = (self.safety.override(rid) if self.running else None) or agent.goal
            # (the goal is most ticks the very object last sent: no field-by-field compare)
            if motion is None or motion is agent.sent or motion == agent.sent:
                continue
            cmd = motion.to_proto(rid, agent.record_sent(motion))
            cmd.holding = bool(agent.carrying)  # (a gripper closes on what the arm carries)
            cmds.append(cmd)
        if self.running:
            for rid, mon in self.safety.ssm.items():
                due = mon.due(self.tick)
                mon.urgent = False
                if due and mon.scale != self._sent_scale[rid]:
                    self._sent_scale[rid] = mon.scale
                    cmds.append(
                        pb.RobotCommand(
                            robot=rid,
                            command_id=self.agents[rid].sent_id,
                            kind=pb.RobotCommand.KIND_SPEED_SCALE,
                            speed_scale=mon.scale,
                        )
                    )
        return cmds

    def _grabbable_changes(self) -> list[pb.WorldCommand]:
        if self.finished:
            return []
        blocked = self.safety.blocks_grab
        # HumanAgent.grabbable depends on these only: unchanged, every flag is as sent.
        key = (self.human.next_part, self.human.held_part, blocked)
        if key == self._grabbable_key:
            return []
        self._grabbable_key = key
        cmds: list[pb.WorldCommand] = []
        for part in self.scenario.parts:
            if part.start is None:  # screws come from the feeder, never grabbable by hand
                continue
            want = part.owner == sc.HUMAN and self.human.grabbable(part.id, blocked)
            if self._grabbable.get(part.id) != want:
                self._grabbable[part.id] = want
                cmds.append(
                    pb.WorldCommand(set_grabbable=pb.SetGrabbable(object=part.id, grabbable=want))
                )
        return cmds

    def _cue_changes(self) -> list[pb.Cue]:
        """The cues that go on or off this tick (the board keeps the rest)."""
        key = self._cue_key()
        if key == self._cues_key:
            return []  # the same desired cues as last tick: no change
        self._cues_key = key
        return self.cue_board.update(self._desired_cues())

    def _cue_key(self) -> tuple[object, ...]:
        """Everything :meth:`_desired_cues` reads that can change (the rest is the scenario)."""
        if self.finished:
            return ("finished",)
        h = self.human
        nxt = h.next_part
        outline = bool(nxt) and not h.held_part and h.grabbable(nxt, self.safety.blocks_grab)
        button = self.safety.button_wanted and self.scenario.workspace.continue_button is not None
        robots: tuple[object, ...] = ()
        if self.anticipation and self.running:
            robots = tuple((a.carrying, a.phase == Phase.WAITING) for a in self.agents.values())
        return (
            self._positions[nxt] if outline else None,
            nxt if outline else "",
            h.held_part if h.target_cue_wanted() else "",
            button,
            robots,
        )

    def _desired_cues(self) -> list[pb.Cue]:
        if self.finished:
            return []
        cues: list[pb.Cue] = []
        nxt = self.human.next_part
        if nxt and not self.human.held_part and self.human.grabbable(nxt, self.safety.blocks_grab):
            cues.append(
                pb.Cue(
                    id=outline_cue_id(nxt),
                    kind=pb.CUE_KIND_OUTLINE,
                    part=nxt,
                    color=HUMAN_COLOR,
                    position=vec3_to_pb(self._positions[nxt]),
                    flashing=True,
                )
            )
        if self.human.target_cue_wanted():
            part = self.board.parts[self.human.held_part]
            cues.append(
                pb.Cue(
                    id=target_cue_id(part.id),
                    kind=pb.CUE_KIND_TARGET,
                    part=part.id,
                    color=HUMAN_COLOR,
                    position=vec3_to_pb(part.target.xyz),
                    flashing=True,
                )
            )
        button = self.scenario.workspace.continue_button
        if self.safety.button_wanted and button is not None:
            cues.append(
                pb.Cue(
                    id=CONTINUE_BUTTON_CUE,
                    kind=pb.CUE_KIND_CONTINUE_BUTTON,
                    position=vec3_to_pb(button),
                    flashing=True,
                )
            )
        if self.anticipation and self.running:
            for rid, agent in self.agents.items():
                color = agent.cfg.color_or_default
                if agent.carrying:
                    part = self.board.parts[agent.carrying]
                    cues.append(
                        pb.Cue(
                            id=target_cue_id(part.id),
                            kind=pb.CUE_KIND_TARGET,
                            part=part.id,
                            robot=rid,
                            color=color,
                            position=vec3_to_pb(part.target.xyz),
                            flashing=True,
                        )
                    )
                if agent.phase == Phase.WAITING:
                    above_base = add(vec3(agent.cfg.base.xyz), (0.0, 0.0, WAITING_HEIGHT_M))
                    cues.append(
                        pb.Cue(
                            id=waiting_cue_id(rid),
                            kind=pb.CUE_KIND_WAITING,
                            robot=rid,
                            color=color,
                            text=WAITING_TEXT,
                            flashing=True,
                            position=vec3_to_pb(above_base),
                        )
                    )
        return cues
