"""Entry point of the human-input service (``hrc-human-input``).

Publishes the participant (head, hands, grips) as ``pb.HumanState`` on ``human/state`` every
tick, from the scenario's source (scripted | replay | vr) or the one given on the command line;
optionally records what it published in the replay format.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import sys
from pathlib import Path

from hrc.bus import Bus, LockstepParticipant, add_bus_arguments, bus_config_from_args
from hrc.logsetup import setup_logging
from hrc.scenario import InputSource, ScenarioError
from hrc.wire import pb

from hrc_human_input import facts as facts_mod
from hrc_human_input.replay import Recorder, Recording, ReplayError, Replayer, load_recording
from hrc_human_input.sample import Sample
from hrc_human_input.scripted import ScriptedParticipant
from hrc_human_input.sources import ReplaySource, ScriptedSource, Source, VrSource
from hrc_human_input.task_view import TaskView
from hrc_human_input.vr_bridge import (DEFAULT_HOST, DEFAULT_PORT, BridgeConfigError, VrBridge,
                                       check_bind)

log = logging.getLogger("hrc_human_input")

NAME = "human_input"
EXIT_BAD_INPUT = 2


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="hrc-human-input", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    add_bus_arguments(p)
    p.add_argument("--input", choices=[s.value for s in InputSource], default=None,
                   help="input source (default: the scenario's [participant] input)")
    p.add_argument("--replay", default=None, metavar="FILE",
                   help="replay this recording whatever the scenario's input says")
    p.add_argument("--record", default=None, metavar="FILE",
                   help="record what the source relayed to FILE (replay format, JSONL)")
    p.add_argument("--vr-host", default=os.environ.get("HRC_VR_HOST", DEFAULT_HOST),
                   help="address the VR bridge binds (default 127.0.0.1; anything else needs "
                        "a token)")
    p.add_argument("--vr-port", type=int, default=int(os.environ.get("HRC_VR_PORT", DEFAULT_PORT)),
                   help=f"port of the VR bridge and its page (default {DEFAULT_PORT}; 0 = any)")
    p.add_argument("--vr-token", default=os.environ.get("HRC_VR_TOKEN") or None,
                   help="token VR clients must present (env HRC_VR_TOKEN)")
    p.add_argument("--start-timeout", type=float, default=60.0)
    p.add_argument("--log-level", default=None)
    return p.parse_args(argv)


def _load(path: str) -> Recording | None:
    try:
        rec = load_recording(path)
    except ReplayError as exc:
        log.error("%s", exc)
        print(f"hrc-human-input: {exc}", file=sys.stderr)
        return None
    log.info("replay file %s: %d samples, %.3f s", path, len(rec.samples), rec.samples[-1].t)
    return rec


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    setup_logging(NAME, args.log_level)
    # Refuse unsafe or broken input before joining the run.
    try:
        check_bind(args.vr_host, args.vr_token)
    except BridgeConfigError as exc:
        log.error("%s", exc)
        print(f"hrc-human-input: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    recording: Recording | None = None
    if args.replay:
        recording = _load(args.replay)
        if recording is None:
            return EXIT_BAD_INPUT

    with Bus(bus_config_from_args(args), NAME) as bus, contextlib.ExitStack() as stack:
        try:
            scenario = bus.get_one(bus.keys.scenario(), pb.Scenario, timeout=args.start_timeout)
        except TimeoutError as exc:
            log.error("no scenario: %s", exc)
            return 1
        try:
            facts = facts_mod.from_proto(scenario)
        except ScenarioError as exc:
            log.error("scenario rejected:\n%s", exc)
            return EXIT_BAD_INPUT
        source_kind = (InputSource.REPLAY if args.replay
                       else InputSource(args.input) if args.input else facts.input)
        keys = bus.keys
        participant = LockstepParticipant(bus)
        source: Source
        if source_kind == InputSource.REPLAY:
            if recording is None:
                if not facts.replay_file:
                    log.error("input = replay but the scenario names no replay_file "
                              "(and no --replay FILE was given)")
                    return EXIT_BAD_INPUT
                recording = _load(facts.replay_file)
                if recording is None:
                    return EXIT_BAD_INPUT
            source = ReplaySource(Replayer(recording))
        elif source_kind == InputSource.VR:
            bridge = VrBridge(args.vr_host, args.vr_port, args.vr_token,
                              hello={"session": keys.session, "scenario": facts.name,
                                     "participant": facts.participant,
                                     "tick_hz": facts.tick_hz})
            try:
                bridge.start()
            except BridgeConfigError as exc:
                log.error("%s", exc)
                return EXIT_BAD_INPUT
            stack.callback(bridge.stop)
            source = VrSource(bridge)
        else:
            view = TaskView(facts)
            scripted = ScriptedParticipant(facts)
            participant.input(keys.world_objects(), pb.WorldObjects,
                              lambda _k, m: view.on_objects(m))
            participant.input(keys.world_contacts(), pb.WorldContacts,
                              lambda _k, m: view.on_contacts(m))
            participant.input(keys.robot_states(), pb.RobotState,
                              lambda _k, m: view.on_robot_state(m))
            participant.input(keys.task_indicators(), pb.Indicators,
                              lambda _k, m: view.on_indicators(m))
            participant.input(keys.task_events(), pb.TaskEvent,
                              lambda _k, m: view.on_task_event(m))
            source = ScriptedSource(scripted, view)

        recorder: Recorder | None = None
        if args.record:
            recorder = stack.enter_context(Recorder(Path(args.record), {
                "source": source.name, "scenario": facts.name, "participant": facts.participant,
                "seed": facts.seed, "tick_hz": facts.tick_hz, "session": keys.session,
                "anticipation": facts.anticipation}))
        publisher = bus.publisher(keys.human_state())
        keyframe_every = max(1, round(facts.tick_hz))  # once per simulated second
        last_sent: Sample | None = None

        def step(tick: pb.ClockTick) -> None:
            nonlocal last_sent
            k, t = tick.header.tick, tick.header.sim_time
            sample = source.sample(t)
            if sample.t != t:
                sample = sample.at(t)
            # On change, plus a keyframe for late joiners: a participant at rest costs the
            # receivers nothing (they hold the last state).
            if last_sent is None or not sample.same_as(last_sent) or k % keyframe_every == 0:
                publisher.put(sample.to_proto(source.name), k, t)
                last_sent = sample
            if recorder is not None:
                recorder.write(sample)

        participant.on_tick(step)
        participant.start()
        log.info("participant %r ready (input %s%s)", facts.participant, source.name,
                 f", recording to {args.record}" if args.record else "")
        outcome = participant.run()
        if isinstance(source, ScriptedSource):
            sp = source.participant
            log.info("scripted participant: phase %s, %d reaches, %d hold-backs",
                     sp.phase.value, len(sp.reaches()), len(sp.hold_backs))
        if isinstance(source, VrSource):
            st = source.bridge.stats
            log.info("VR bridge: %d clients, %d samples accepted, %d rejected", st.clients,
                     st.accepted, st.rejected)
        if recorder is not None:
            log.info("recorded %d samples to %s", recorder.count, args.record)
        if not outcome.ok:
            log.error("run ended with an error: %s", outcome.reason)
        return outcome.exit_code


if __name__ == "__main__":
    raise SystemExit(main())
