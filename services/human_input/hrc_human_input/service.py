"""The human-input service (``hrc-human-input``).

Publishes the participant (head, hands, grips) as ``pb.HumanState`` on ``human/state`` every
tick, from the scenario's source (scripted | replay | vr) or the one given on the command line;
optionally records what it published in the replay format.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import math
import os
from pathlib import Path

from hrc.bus import Bus, Outcome
from hrc.bus.lockstep import opens_exchange
from hrc.participant.recording import Recorder, Recording, ReplayError, load_recording
from hrc.participant.sample import Sample
from hrc.scenario import InputSource, ScenarioError
from hrc.service import EXIT_BAD_INPUT, Inputs, Service, ServiceExit, fetch_scenario
from hrc.service_table import VR_DEFAULT_WAIT_S, vr_client_url
from hrc.webpage import add_address_options
from hrc.wire import pb

from hrc_human_input import facts as facts_mod
from hrc_human_input.replay import Replayer
from hrc_human_input.scene import RobotFiles, build_scene, scene_cue_json
from hrc_human_input.scripted import ScriptedParticipant
from hrc_human_input.sources import ReplaySource, ScriptedSource, Source, VrSource
from hrc_human_input.stream import WorldMirror, ssm_zones
from hrc_human_input.task_view import TaskView
from hrc_human_input.vr_options import (
    CLIENT_DIST,
    DEFAULT_PORT,
    BridgeConfigError,
    check_bind,
)

log = logging.getLogger("hrc_human_input")


def _load(path: str) -> Recording:
    try:
        rec = load_recording(path)
    except ReplayError as exc:
        raise ServiceExit(str(exc), EXIT_BAD_INPUT) from exc
    log.info("replay file %s: %d samples, %.3f s", path, len(rec.samples), rec.samples[-1].t)
    return rec


class HumanInputService(Service):
    """Samples the source at each tick's time and publishes the participant on change."""

    name = "human_input"

    @classmethod
    def add_arguments(cls, p: argparse.ArgumentParser) -> None:
        p.add_argument(
            "--input",
            choices=[s.value for s in InputSource],
            default=None,
            help="input source (default: the scenario's [participant] input)",
        )
        p.add_argument(
            "--replay",
            default=None,
            metavar="FILE",
            help="replay this recording whatever the scenario's input says",
        )
        p.add_argument(
            "--record",
            default=None,
            metavar="FILE",
            help="record what the source relayed to FILE (replay format, JSONL)",
        )
        add_address_options(
            p,
            host_help="address the VR bridge binds (default 127.0.0.1; anything else needs a "
            "token)",
            port_help=f"port of the VR bridge and its page (default {DEFAULT_PORT}; 0 = any)",
        )
        p.add_argument(
            "--vr-token",
            default=os.environ.get("HRC_VR_TOKEN") or None,
            help="token VR clients must present (env HRC_VR_TOKEN)",
        )
        p.add_argument(
            "--vr-origins",
            default=os.environ.get("HRC_VR_ORIGINS", ""),
            metavar="LIST",
            help="comma-separated origins (https://lab.example:8443) whose pages may connect "
            "besides this host's own (env HRC_VR_ORIGINS); a browser page from anywhere else "
            "is refused",
        )
        p.add_argument(
            "--vr-driver",
            default=os.environ.get("HRC_VR_DRIVER") or None,
            metavar="KEY",
            help="the participant's key (env HRC_VR_DRIVER): only the page opened with "
            "?driver=KEY drives the hands, and again after a reload; every other page spectates "
            "(default: none, the first page drives)",
        )
        p.add_argument(
            "--vr-wait",
            type=float,
            default=float(os.environ.get("HRC_VR_WAIT", VR_DEFAULT_WAIT_S)),
            metavar="S",
            help="input vr: wait up to S seconds for a client before joining the run "
            "(default 300, env HRC_VR_WAIT; 0: do not wait); none came: exit 1 naming the URL",
        )
        p.add_argument(
            "--vr-client-dir",
            type=Path,
            default=CLIENT_DIST,
            metavar="DIR",
            help="the participant client's bundle (index.html + assets/; default the one "
            "scripts/setup.sh builds); missing: a minimal fallback page",
        )
        p.add_argument(
            "--start-timeout",
            type=float,
            default=60.0,
            help="seconds to wait for the scenario (default 60)",
        )

    def __init__(self, args: argparse.Namespace) -> None:
        """Refuses unsafe or broken input before joining the run."""
        super().__init__(args)
        try:
            check_bind(args.vr_host, args.vr_token)
        except BridgeConfigError as exc:
            raise ServiceExit(str(exc), EXIT_BAD_INPUT) from exc
        self.recording: Recording | None = _load(args.replay) if args.replay else None
        self.recorder: Recorder | None = None
        self._last_sent: Sample | None = None
        self._last_k = 0

    def open(self, bus: Bus, stack: contextlib.ExitStack) -> None:
        super().open(bus, stack)
        args = self.args
        keys = bus.keys
        scenario = fetch_scenario(bus, args.start_timeout)
        try:
            facts = facts_mod.from_proto(scenario)
        except ScenarioError as exc:
            raise ServiceExit(f"scenario rejected:\n{exc}", EXIT_BAD_INPUT) from exc
        self.source = self._source(facts, scenario, keys.session, stack)
        if args.record:
            self.recorder = stack.enter_context(
                Recorder(
                    Path(args.record),
                    {
                        "source": self.source.name,
                        "scenario": facts.name,
                        "participant": facts.participant,
                        "seed": facts.seed,
                        "tick_hz": facts.tick_hz,
                        "session": keys.session,
                        "anticipation": facts.anticipation,
                    },
                )
            )
        self.publisher = bus.publisher(keys.human_state())
        self.hand_speed_bound = self.source.hand_speed_bound()
        self._msg = pb.HumanState(hand_speed_bound=self.hand_speed_bound)
        self.dt = 1.0 / facts.tick_hz
        self._last_t = 0.0
        self.keyframe_every = max(1, round(facts.tick_hz))  # once per simulated second
        log.info(
            "participant %r ready (input %s%s)",
            facts.participant,
            self.source.name,
            f", recording to {args.record}" if args.record else "",
        )

    def _source(
        self,
        facts: facts_mod.ScenarioFacts,
        scenario: pb.Scenario,
        session: str,
        stack: contextlib.ExitStack,
    ) -> Source:
        args = self.args
        kind = (
            InputSource.REPLAY
            if args.replay
            else InputSource(args.input)
            if args.input
            else facts.input
        )
        if kind == InputSource.REPLAY:
            if self.recording is None:
                if not facts.replay_file:
                    raise ServiceExit(
                        "input = replay but the scenario names no replay_file "
                        "(and no --replay FILE was given)",
                        EXIT_BAD_INPUT,
                    )
                self.recording = _load(facts.replay_file)
            return ReplaySource(Replayer(self.recording))
        if kind == InputSource.VR:
            return self._vr_source(facts, scenario, session, stack)
        return ScriptedSource(ScriptedParticipant(facts), TaskView(facts))

    def _vr_source(
        self,
        facts: facts_mod.ScenarioFacts,
        scenario: pb.Scenario,
        session: str,
        stack: contextlib.ExitStack,
    ) -> VrSource:
        """The bridge, serving the scene of this scenario; waits for the first client."""
        args = self.args
        files = RobotFiles()
        try:
            scene = build_scene(scenario, files)
        except ScenarioError as exc:
            raise ServiceExit(f"scenario rejected:\n{exc}", EXIT_BAD_INPUT) from exc
        # only a live participant needs the bridge's server (websockets, asyncio: start-up CPU)
        from hrc_human_input.vr_bridge import VrBridge

        bridge = VrBridge(
            args.vr_host,
            args.vr_port,
            args.vr_token,
            hello={
                "session": session,
                "scenario": facts.name,
                "participant": facts.participant,
                "tick_hz": facts.tick_hz,
            },
            scene=scene,
            robot_files=files,
            client_dir=args.vr_client_dir,
            driver_key=args.vr_driver,
            origins=tuple(o.strip() for o in args.vr_origins.split(",") if o.strip()),
        )
        try:
            port = bridge.start()
        except BridgeConfigError as exc:
            raise ServiceExit(str(exc), EXIT_BAD_INPUT) from exc
        stack.callback(bridge.stop)
        # the token stays out of the logs: hrc run prints the URL with it on the console
        url = vr_client_url(args.vr_host, port) + ("?token=..." if args.vr_token else "")
        if args.vr_wait > 0:
            log.info("open %s to take part (waiting up to %g s for it)", url, args.vr_wait)
            if not bridge.wait_for_client(args.vr_wait):
                raise ServiceExit(
                    f"no VR client connected within {args.vr_wait:g} s (--vr-wait): nobody "
                    f"opened {url}"
                )
            log.info("a VR client connected: joining the run")
        else:
            log.info("open %s to take part", url)
        joints = {r["id"]: list(r["joint_names"]) for r in scene["robots"]}
        cues = {c["id"]: scene_cue_json(c) for c in scene["cues"]}
        mirror = WorldMirror(joints, cues, ssm_zones(scenario))
        return VrSource(bridge, mirror, self.bus.publisher(self.bus.keys.human_clients()))

    def register_inputs(self, inputs: Inputs) -> None:
        self._inputs = inputs
        self.source.register_inputs(inputs, self.bus.keys)

    def step(self, tick: pb.ClockTick) -> None:
        k, t = tick.header.tick, tick.header.sim_time
        if opens_exchange(tick):
            self.source.exchange_opened(t)
        sample = self.source.sample(t)
        if sample.t != t:
            sample = sample.at(t)
        # On change, plus a keyframe for late joiners: a participant at rest costs the
        # receivers nothing (they hold the last state).
        last = self._last_sent
        if last is None or not sample.same_as(last) or k % self.keyframe_every == 0:
            # One message filled in place: put() serializes it at once (batched or not).
            msg = self._msg
            sample.into_proto(msg, self.source.name)
            self.publisher.put(msg, k, t)
            self._last_sent = sample
        if self.recorder is not None:
            self.recorder.write(sample)
        self.source.published(k, t, sample)
        self._last_k, self._last_t = k, t

    def next_event_tick(self) -> int:
        """The first tick whose grip may cross GRIP_CLOSED (a grab or a release begins), or the
        tick before one of the source's timers may make it decide."""
        ticks = []
        # the 1e-6 tick margin keeps them lower bounds against rounding
        at = self.source.next_event_s(self._last_t)
        if at is not None:
            ticks.append(math.ceil(at / self.dt - 1e-6))
        decide = self.source.next_decision_s(self._last_t)
        if decide is not None:
            # the tick before: the decision's tick then starts an exchange
            ticks.append(math.ceil(decide / self.dt - 1e-6) - 1)
        return max(self._last_k + 1, min(ticks)) if ticks else 0

    def next_sample_tick(self) -> tuple[int, int]:
        """The first tick at which the source reads its inputs to decide from what it perceives
        (the scripted participant's next look at the robots) and its period in ticks: exchanges
        start there."""
        looks = self.source.next_sample_s(self._last_t)
        if looks is None:
            return 0, 0
        at, period = looks
        # the 1e-6 tick margin: the source looks at the first tick at or after ``at``
        return max(self._last_k + 1, math.ceil(at / self.dt - 1e-6)), period

    def finish(self, outcome: Outcome) -> int | None:
        if isinstance(self.source, VrSource):
            # The last tick's messages (TASK_FINISHED, the final states) came after its step:
            # hand them over so the clients see how the task ended.
            inbox = getattr(getattr(self, "_inputs", None), "inbox", None)
            if inbox is not None:
                inbox.deliver(2**62)
        self.source.ended(outcome.ok, outcome.reason)
        summary = self.source.summary()
        if summary:
            log.info("%s", summary)
        if self.recorder is not None:
            log.info("recorded %d samples to %s", self.recorder.count, self.args.record)
        return None
