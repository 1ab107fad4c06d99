"""The ``hrc`` command: run trials, validate scenarios, benchmarks and bus tools.

Why one file of over 600 lines: the parser of every subcommand, so their options are read and
kept consistent in one place; each command's body only parses and calls the library.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import math
import os
import re
import secrets
import sys
import time
from pathlib import Path

from hrc import privacy
from hrc.logsetup import setup_logging
from hrc.service_table import VR_DEFAULT_PORT, VR_DEFAULT_WAIT_S
from hrc.webpage import add_address_options

log = logging.getLogger("hrc")

# hrc deploy-access's link lease: a host cut off is gone for the others within it (several hosts)
DEPLOY_LEASE_S = 0.5


def _warn_if_exposed(folder: Path) -> None:
    if (why := privacy.exposed(folder)) is not None:
        print(f"warning: {why}", file=sys.stderr)


def _is_study(path: str) -> bool:
    """A study file (its `[study]` table) rather than a scenario; False if it cannot be read
    (the scenario's loader then says why)."""
    import tomllib

    try:
        with open(path, "rb") as f:
            return "study" in tomllib.load(f)
    except (OSError, tomllib.TOMLDecodeError):
        return False


def _cmd_validate(args: argparse.Namespace) -> int:
    from hrc import scenario as sc

    if _is_study(args.scenario):  # a study file: checked as hrc sweep and hrc session read it
        from hrc.study import StudyError, load_study

        try:
            st = load_study(args.scenario, motion_check=not args.no_reach)
        except StudyError as exc:
            print(str(exc), file=sys.stderr)
            print(f"{len(exc.problems)} problem(s) found", file=sys.stderr)
            return 1
        live = f", {len(st.live.participants)} live participants" if st.live else ""
        print(
            f"{args.scenario}: ok (study {st.name}: {len(st.conditions)} conditions, "
            f"{len(st.trials)} simulated or replayed trials{live})"
        )
        return 0
    try:
        s = sc.load(args.scenario, motion_check=not args.no_reach)
    except sc.ScenarioError as exc:
        print(str(exc), file=sys.stderr)
        print(f"{len(exc.problems)} problem(s) found", file=sys.stderr)
        return 1
    n_parts = len(s.parts)
    print(f"{args.scenario}: ok ({s.scenario.name}: {len(s.robots)} robots, {n_parts} parts)")
    return 0


def _say(message: str) -> None:
    """To stderr, if there still is one (a closed terminal sends SIGHUP, then fails writes)."""
    with contextlib.suppress(OSError, ValueError):
        print(message, file=sys.stderr, flush=True)


def _cmd_run(args: argparse.Namespace) -> int:
    # Before numpy's import, here and (inherited) in every service: OpenBLAS's thread pool costs
    # ~30 ms of CPU per import, and a trial's small matrices never use it (its five processes
    # share the cores anyway).
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    on = ""  # the CPUs it keeps to, in its first line
    if args.cpus is not None:
        from hrc.priority import CpuListError, format_cpus, parse_cpus

        try:  # before any service starts: each inherits it
            cpus = parse_cpus(args.cpus)
        except CpuListError as exc:
            print(f"{exc}; nothing was started", file=sys.stderr)
            return 2
        os.sched_setaffinity(0, cpus)
        on = f", on CPUs {format_cpus(cpus)}"
    from hrc import scenario as sc
    from hrc.cli.summary import print_summary
    from hrc.ports import free_port
    from hrc.scenario.models import NAME_PATTERN
    from hrc.scenario.resolved import resolve
    from hrc.trial import (
        Terminated,
        TrialOptions,
        VrOptions,
        default_trial_dir,
        run_trial,
        stop_on_signals,
    )
    from hrc.trial.options import web_viewer_url, write_scenario_copy

    try:
        s = sc.load(args.scenario, motion_check=not args.no_reach_check)
    except sc.ScenarioError as exc:
        print(str(exc), file=sys.stderr)
        print(
            f"scenario rejected: {len(exc.problems)} problem(s); nothing was started",
            file=sys.stderr,
        )
        return 2
    for name in ("ticks", "max_ticks"):
        if getattr(args, name) < 0:
            print(
                f"--{name.replace('_', '-')} must be >= 0, got {getattr(args, name)}",
                file=sys.stderr,
            )
            return 2
    if args.ticks and args.max_ticks:
        print("give --ticks (exact length) or --max-ticks (a cap), not both", file=sys.stderr)
        return 2
    if args.participant is not None and not re.fullmatch(NAME_PATTERN, args.participant):
        print(
            f"--participant {args.participant!r}: a letter or digit, then letters, digits, _ . -",
            file=sys.stderr,
        )
        return 2
    live = (args.input or s.participant.input.value) == sc.InputSource.VR.value and not args.replay
    mode = args.mode or ("realtime" if live else "lockstep")
    vr: VrOptions | None = None
    if live:
        token = os.environ.get("HRC_VR_TOKEN") or None
        # the participant's link carries this key: their page drives, every other one watches
        driver = os.environ.get("HRC_VR_DRIVER") or secrets.token_urlsafe(9)
        os.environ["HRC_VR_DRIVER"] = driver  # the services inherit it
        vr = VrOptions(args.vr_host, args.vr_port, args.vr_wait, driver)
        if mode != "realtime":
            print(
                "note: a live participant in lockstep mode: simulation time will not follow "
                "the wall clock",
                file=sys.stderr,
            )
        wait = f"waiting up to {args.vr_wait:g} s for it" if args.vr_wait > 0 else "not waiting"
        who = args.participant or s.participant.name
        print(
            f"live VR trial, participant {who}: open {vr.url(token)} ({wait}); the task clock "
            f"starts on the first grab\n  spectators (the experimenter): {vr.url(token, False)}",
            flush=True,
        )
    if args.seed is not None and not 0 <= args.seed < 2**64:
        print(f"--seed must be in [0, 2^64), got {args.seed}", file=sys.stderr)
        return 2
    replay = Path(args.replay).resolve() if args.replay else None
    resolved = resolve(
        s, seed=args.seed, replay=replay, source=args.input, participant=args.participant
    )
    trial_dir = (
        Path(args.out)
        if args.out
        else default_trial_dir(
            Path("runs"), resolved.scenario.participant.name, resolved.folder_name()
        )
    )
    _warn_if_exposed(trial_dir)
    try:
        # the services load this copy: the trial folder holds exactly what ran
        scenario_copy = write_scenario_copy(trial_dir, resolved)
    except OSError as exc:
        print(f"cannot write the scenario into {trial_dir}: {exc}", file=sys.stderr)
        return 2
    opts = TrialOptions(
        scenario=scenario_copy.resolve(),
        out=trial_dir,
        mode=mode,
        seed=args.seed,
        ticks=args.ticks,
        max_ticks=args.max_ticks,
        session=args.session,
        port=args.port,
        unix_socket=not args.tcp,
        lowlatency=bool(args.lowlatency),
        barrier_timeout_s=args.barrier_timeout,
        stall_timeout_s=args.stall_timeout,
        connect=args.connect or [],
        validated=True,
        viewer=args.viewer,
        web=args.web,
        record=Path(args.record).resolve() if args.record else None,
        view=not args.no_view,
        replay=replay,
        input=args.input,
        vr=vr,
        participant=resolved.scenario.participant.name,
        parts_total=len(resolved.scenario.parts),
    )
    if args.no_view and (args.viewer or args.web):
        print("--no-view leaves nothing for --viewer or --web to show", file=sys.stderr)
        return 2
    if args.web_port:
        if not 0 < args.web_port < 65536:
            print(f"--web-port must be a port number, got {args.web_port}", file=sys.stderr)
            return 2
        opts.web_port, opts.grpc_port = args.web_port, free_port()
    print(f"trial {s.scenario.name!r} ({mode}{on}) -> {trial_dir}", flush=True)
    if args.web:
        print(f"rerun web viewer: {web_viewer_url(opts)}", flush=True)
    try:
        stop_on_signals()
        result = run_trial(opts, trial_dir)
    except KeyboardInterrupt:  # run_trial has stopped the services on its way out
        _say(f"trial interrupted; files so far in {trial_dir}")
        return 130
    except Terminated as exc:  # likewise
        _say(f"trial stopped by {exc}; files so far in {trial_dir}")
        return 128 + exc.signum
    if not result.ok:
        print(f"trial FAILED: {result.message}", file=sys.stderr)
        return result.exit_code
    print_summary(trial_dir, result)
    return 0


def _cmd_sweep(args: argparse.Namespace) -> int:
    from hrc.study import StudyError, load_study, sweep
    from hrc.study.sweep import ClusterError
    from hrc.trial import Terminated, stop_on_signals

    try:
        study = load_study(args.study, motion_check=not args.no_reach)
    except StudyError as exc:
        print(str(exc), file=sys.stderr)
        print(f"study rejected: {len(exc.problems)} problem(s); nothing was run", file=sys.stderr)
        return 2
    if args.workers < 0 or args.trial_timeout <= 0:
        print("--workers must be >= 0 and --trial-timeout > 0", file=sys.stderr)
        return 2
    out = Path(args.out) if args.out else Path("runs") / "studies" / study.name
    _warn_if_exposed(out)
    where = f"cluster {args.cluster}" if args.cluster else f"{args.workers or 'all'} workers"
    print(f"study {study.name!r}: {len(study.trials)} trials ({where}) -> {out}", flush=True)
    try:
        stop_on_signals()  # SIGTERM/SIGHUP stop the trials in progress, as Ctrl-C does
        records = sweep(
            study,
            out,
            workers=args.workers,
            cluster=args.cluster,
            timeout_s=args.trial_timeout,
            view=not args.no_view,
            pin=args.pin,
        )
    except KeyboardInterrupt:
        print(
            f"sweep interrupted; finished trials are kept in {out} (run again to resume)",
            file=sys.stderr,
        )
        return 130
    except Terminated as exc:
        print(f"sweep stopped by {exc}; finished trials are kept in {out}", file=sys.stderr)
        return 128 + exc.signum
    except ClusterError as exc:
        print(f"sweep: {exc}", file=sys.stderr)
        return 2
    bad = [r for r in records if r.outcome != "ok"]
    print(f"{len(records) - len(bad)} ok, {len(bad)} not ok; table: {out / 'trials.parquet'}")
    for r in bad:
        print(f"  {r.trial}: {r.outcome}: {r.reason.splitlines()[0] if r.reason else ''}")
    return 0


def _cmd_power(args: argparse.Namespace) -> int:
    from hrc.study import StudyError, power
    from hrc.study.power import PowerError, PowerSettings, answer, run_power
    from hrc.study.sweep import ClusterError
    from hrc.trial import Terminated, stop_on_signals

    # what the command line leaves out, the module's defaults give
    given = {k: v for k, v in vars(args).items() if v is not None}
    try:
        ns = tuple(sorted({int(v) for v in given["n"].split(",") if v.strip()}))
    except KeyError:
        ns = power.DEFAULT_NS
    except ValueError:
        print(f"--n: a list of whole numbers such as 4,8,12 (got {args.n!r})", file=sys.stderr)
        return 2
    settings = PowerSettings(
        args.effect,
        given.get("outcome", power.DEFAULT_OUTCOME),
        ns,
        given.get("sims", power.DEFAULT_SIMS),
        given.get("alpha", power.DEFAULT_ALPHA),
        given.get("target", power.DEFAULT_TARGET),
        args.seed,
    )
    pool = given.get("pool", power.DEFAULT_POOL)
    problems = [
        text
        for bad, text in (
            (not ns or min(ns) < 2, "--n: every N at least 2"),
            (pool == 1 or pool < 0, "--pool: at least 2 (0: the study's own participants)"),
            (settings.sims < 1, "--sims: at least 1"),
            (not 0 < settings.alpha < 1, "--alpha: between 0 and 1"),
            (not 0 < settings.target <= 1, "--target: above 0, at most 1"),
            (args.workers < 0 or args.trial_timeout <= 0, "--workers >= 0, --trial-timeout > 0"),
        )
        if bad
    ]
    if problems:
        print("\n".join(problems), file=sys.stderr)
        return 2
    name = Path(args.study).stem
    out = Path(args.out) if args.out else Path("runs") / "power" / name
    _warn_if_exposed(out)
    try:
        stop_on_signals()
        result = run_power(
            Path(args.study),
            out,
            settings,
            pool=pool,
            workers=args.workers,
            cluster=args.cluster,
            timeout_s=args.trial_timeout,
            motion_check=not args.no_reach,
        )
    except StudyError as exc:
        print(str(exc), file=sys.stderr)
        print(f"study rejected: {len(exc.problems)} problem(s); nothing was run", file=sys.stderr)
        return 2
    except (PowerError, ClusterError) as exc:
        print(f"power: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"power interrupted; the pool's finished trials are kept in {out}", file=sys.stderr)
        return 130
    except Terminated as exc:
        print(f"power stopped by {exc}; finished trials are kept in {out}", file=sys.stderr)
        return 128 + exc.signum
    print(f"{answer(result)}.")
    print(f"{result.wall_s:.0f} s; curve and table: {out / 'power.html'}")
    return 0


def _cmd_session(args: argparse.Namespace) -> int:
    from hrc.session.run import Options, Session, SessionEnd
    from hrc.session.web import check_bind
    from hrc.study import StudyError, load_study
    from hrc.trial import Terminated, stop_on_signals

    try:
        study = load_study(args.study, motion_check=not args.no_reach)
    except StudyError as exc:
        print(str(exc), file=sys.stderr)
        print(f"study rejected: {len(exc.problems)} problem(s); nothing was run", file=sys.stderr)
        return 2
    token = os.environ.get("HRC_VR_TOKEN") or None
    problem = check_bind(args.host, token)
    if problem:
        print(f"session: {problem}", file=sys.stderr)
        return 2
    out = Path(args.out) if args.out else Path("runs") / "studies" / study.name
    _warn_if_exposed(out)
    opts = Options(out, args.host, args.port, args.vr_port, token, args.page_mode or "")
    try:
        session = Session(study, args.participant, opts)
    except (SessionEnd, ValueError) as exc:
        print(f"session: {exc}", file=sys.stderr)
        return getattr(exc, "code", 2)
    try:
        stop_on_signals()
        return session.run()
    except KeyboardInterrupt:
        _say(f"session interrupted; resume with the same command (saved in {session.path})")
        return 130
    except Terminated as exc:
        _say(f"session stopped by {exc}; resume with the same command (saved in {session.path})")
        return 128 + exc.signum
    except OSError as exc:
        print(f"session: {exc}", file=sys.stderr)
        return 2


def _cmd_report(args: argparse.Namespace) -> int:
    from hrc.study.report import ReportError, write_report

    try:
        page = write_report(Path(args.sweep_dir))
    except ReportError as exc:
        print(f"report: {exc}", file=sys.stderr)
        return 2
    print(f"report: {page}")
    return 0


def _cmd_alive(args: argparse.Namespace) -> int:
    from hrc.bus import Bus, access, bus_config_from_args

    cfg = access.as_tool(bus_config_from_args(args))
    cfg.listen = []
    with Bus(cfg, "probe") as bus:
        deadline = time.monotonic() + args.wait
        while True:
            if args.service in bus.alive_services(timeout=0.5):
                print(f"{args.service}: alive")
                return 0
            if time.monotonic() >= deadline:
                print(f"{args.service}: not alive in session {cfg.session!r}", file=sys.stderr)
                return 1
            time.sleep(0.2)


def _cmd_router(args: argparse.Namespace) -> int:
    import zenoh

    from hrc.bus.access import log_refusals
    from hrc.bus.config import without_shared_memory

    log_refusals()  # a link refused for want of credentials: a line on standard output
    cfg = without_shared_memory(
        zenoh.Config.from_file(args.config) if args.config else zenoh.Config()
    )
    cfg.insert_json5("mode", '"router"')
    if args.listen:
        cfg.insert_json5("listen/endpoints", json.dumps(args.listen))
    with zenoh.open(cfg) as session:
        log.info("zenoh router %s up; Ctrl-C to stop", session.info.zid())
        try:
            while True:
                time.sleep(3600)
        except KeyboardInterrupt:
            return 0


def _cmd_deploy_files(args: argparse.Namespace) -> int:
    from hrc.cli import deploy_files

    return deploy_files.main(args)


def _cmd_deploy_access(args: argparse.Namespace) -> int:
    from hrc.cli import deploy_access

    return deploy_access.main(args)


def _cmd_services(_args: argparse.Namespace) -> int:
    from hrc import service_table

    for svc in service_table.SERVICES:
        program = f"python -m {svc.module}" if svc.module else f"build/{svc.binary}"
        print(f"{svc.name:<13} {svc.role.value:<13} {program:<26} {svc.description}")
        for need in svc.needs:
            print(f"{'':<14}needs {need}")
    return 0


def _cmd_fit(args: argparse.Namespace) -> int:
    from hrc.cli import fit

    return fit.run(args)


def _cmd_robot_add(args: argparse.Namespace) -> int:
    from hrc.paths import project_root
    from hrc.robot.add import RobotError, add

    try:
        tcp = [float(v) for v in args.tcp.split(",")]
        if len(tcp) != 3 or not all(math.isfinite(v) for v in tcp):
            raise ValueError
    except ValueError:
        print(f"hrc robot add: --tcp {args.tcp!r}: expected X,Y,Z in metres", file=sys.stderr)
        return 2
    pairs: dict[str, str] = {}
    for a in args.arg:
        key, sep, value = a.partition(":=")
        if not sep or not key:
            print(f"hrc robot add: --arg {a!r}: expected NAME:=VALUE (xacro's)", file=sys.stderr)
            return 2
        pairs[key] = value
    try:
        report = add(
            Path(args.source),
            Path(args.out) if args.out else None,
            args.name,
            [Path(p) for p in args.packages],
            pairs,
            args.base,
            args.tip,
            tcp,
            None if args.no_board else Path(args.board or project_root() / "scenarios/thesis.toml"),
        )
    except RobotError as exc:
        print(f"hrc robot add: {exc}", file=sys.stderr)
        return 2
    print(report.markdown(), end="")
    board = f", {report.board.name}" if report.board else ""
    print(f"written: {report.urdf.parent} ({report.urdf.name}, meshes/, report.md{board})")
    if report.board_error:
        print(f"hrc robot add: the board: {report.board_error}", file=sys.stderr)
        return 1
    return 0


def _cmd_bench(args: argparse.Namespace) -> int:
    from hrc import bench

    return bench.main(args)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="hrc", description=__doc__)
    p.add_argument("--log-level", default=None, help="DEBUG, INFO, WARNING (default) ...")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("run", help="run one trial with all five services")
    r.add_argument("scenario", help="scenario TOML file")
    r.add_argument(
        "--out",
        default=None,
        help="trial folder (default runs/<date>/<participant>/<scenario>_<condition>/)",
    )
    r.add_argument(
        "--mode",
        choices=["lockstep", "realtime"],
        default=None,
        help="clock mode (default: realtime with a live VR participant, else lockstep)",
    )
    r.add_argument(
        "--input",
        choices=["scripted", "replay", "vr"],
        default=None,
        help="the participant's input, whatever the scenario says (vr: a live trial)",
    )
    add_address_options(
        r,
        host_help="live trial: the bridge's address (non-loopback needs HRC_VR_TOKEN)",
        port_help=f"live trial: the bridge's port, the page's URL (default {VR_DEFAULT_PORT})",
    )
    r.add_argument(
        "--vr-wait",
        type=float,
        default=VR_DEFAULT_WAIT_S,
        metavar="S",
        help="live trial: wait up to S s for the participant's client, then fail (default 300; "
        "0: start without one)",
    )
    r.add_argument(
        "--participant",
        default=None,
        metavar="ID",
        help="the participant's id (default the scenario's [participant] name): in the trial "
        "folder's path, metrics.json and the logs",
    )
    r.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
    r.add_argument(
        "--ticks",
        type=int,
        default=0,
        help="run exactly N ticks, even past the task's end (default: until the task ends)",
    )
    r.add_argument(
        "--max-ticks",
        type=int,
        default=0,
        help="stop after N ticks at the latest; the task's end stops it earlier",
    )
    r.add_argument("--viewer", action="store_true", help="spawn the rerun viewer live")
    r.add_argument("--web", action="store_true", help="serve the rerun web viewer")
    r.add_argument(
        "--web-port",
        type=int,
        default=0,
        help="with --web: serve the viewer on this port (default 9090; its data port is then "
        "a free one instead of 9877)",
    )
    r.add_argument("--record", default=None, help="record the participant's input to FILE (JSONL)")
    r.add_argument(
        "--no-view",
        action="store_true",
        help="no 3D recording (recording.rrd): the logs, events and metrics as always",
    )
    r.add_argument(
        "--replay", default=None, help="replay a recording instead of the scenario's input"
    )
    r.add_argument(
        "--cpus",
        default=None,
        metavar="LIST",
        help="run the trial's processes on these CPUs only (e.g. 0, 0-3 or 0,2): "
        "`hrc sweep --pin` gives each of its parallel trials CPUs of its own",
    )
    r.add_argument("--session", default=None, help="session id (default: random)")
    r.add_argument("--port", type=int, default=0, help="loopback port physics listens on (0: free)")
    r.add_argument(
        "--tcp",
        action="store_true",
        help="the services talk over TCP loopback (the --port) instead of a Unix socket",
    )
    ll = r.add_mutually_exclusive_group()
    ll.add_argument(
        "--lowlatency",
        action="store_true",
        help="the participants use Zenoh's low-latency transport (20-25 %% more idle lockstep "
        "ticks per second; a scenario too large for it falls back). Its router runs without "
        "QoS, and on such a link Zenoh stops delivering to a logger that was stopped for a few "
        'seconds (docs/ARCHITECTURE.md, "Observers")',
    )
    ll.add_argument(
        "--no-lowlatency",
        action="store_true",
        help="Zenoh's standard transport (the default)",
    )
    r.add_argument(
        "--connect",
        action="append",
        default=None,
        metavar="ENDPOINT",
        help="also connect every service to this Zenoh endpoint (router, shared bus)",
    )
    r.add_argument(
        "--barrier-timeout",
        type=float,
        default=10.0,
        help="seconds a participant may take for one tick (realtime: may go on "
        "missing its deadlines)",
    )
    r.add_argument(
        "--stall-timeout",
        type=float,
        default=None,
        metavar="S",
        help="end the trial after S simulated seconds without progress (default: "
        "the scenario's stall_timeout_s, 60; 0: never)",
    )
    r.add_argument(
        "--no-reach-check",
        action="store_true",
        help="skip the motion check of the scenario (a move may then fail at run "
        "time: the watchdog ends the trial naming it)",
    )
    r.set_defaults(func=_cmd_run)

    v = sub.add_parser("validate", help="check a scenario or study file and report every problem")
    v.add_argument("scenario", help="a scenario file, or a study file (its [study] table)")
    v.add_argument(
        "--no-reach",
        action="store_true",
        help="skip the motion check (every robot move planned by the IK service)",
    )
    v.set_defaults(func=_cmd_validate)

    sw = sub.add_parser("sweep", help="run every trial of a study (docs/studies.md)")
    sw.add_argument("study", help="study TOML file")
    sw.add_argument("--out", default=None, help="sweep folder (default runs/studies/<name>/)")
    sw.add_argument(
        "--workers", type=int, default=0, help="trials at a time on this machine (0: one a core)"
    )
    sw.add_argument(
        "--cluster",
        default=None,
        metavar="ADDRESS",
        help="run the trials on a Dask scheduler, e.g. tcp://10.0.0.5:8786",
    )
    sw.add_argument(
        "--trial-timeout",
        type=float,
        default=900.0,
        metavar="S",
        help="wall seconds one trial may take before it is stopped and recorded failed",
    )
    sw.add_argument(
        "--no-reach", action="store_true", help="skip the motion check of the resolved scenarios"
    )
    sw.add_argument(
        "--no-view",
        action="store_true",
        help="the trials keep no 3D recording (recording.rrd; the same events, logs, metrics "
        "and table, for about a fifth less CPU)",
    )
    sw.add_argument(
        "--pin",
        action="store_true",
        help="each parallel trial on CPUs of its own (hrc run --cpus): a tenth to a fifth "
        "faster on a machine that runs nothing else, far slower beside other work",
    )
    sw.set_defaults(func=_cmd_sweep)

    pw = sub.add_parser(
        "power",
        help="how many participants a study needs: power by simulation (docs/studies.md)",
    )
    pw.add_argument("study", help="study TOML file")
    pw.add_argument("--effect", required=True, metavar="FACTOR", help="the factor to detect")
    # (the defaults are hrc.study.power's, given in docs/studies.md)
    pw.add_argument("--outcome", help="the outcome (default task_completion_s)")
    pw.add_argument("--n", help="study sizes, e.g. 4,6,8,10 (the default)")
    pw.add_argument(
        "--pool",
        type=int,
        help="simulated participants (default 20; 0: the study's own, e.g. a pilot's twins)",
    )
    pw.add_argument("--sims", type=int, help="studies drawn per N (default 200)")
    pw.add_argument("--alpha", type=float, help="significance level (default 0.05)")
    pw.add_argument("--target", type=float, help="the power wanted (default 0.8)")
    pw.add_argument("--seed", type=int, default=1, help="seed of the draws from the pool")
    pw.add_argument("--out", default=None, help="folder (default runs/power/<study>/)")
    pw.add_argument(
        "--workers", type=int, default=0, help="trials at a time on this machine (0: one a core)"
    )
    pw.add_argument("--cluster", default=None, metavar="ADDRESS", help="a Dask scheduler")
    pw.add_argument(
        "--trial-timeout", type=float, default=900.0, metavar="S", help="wall seconds a trial"
    )
    pw.add_argument(
        "--no-reach", action="store_true", help="skip the motion check of the resolved scenarios"
    )
    pw.set_defaults(func=_cmd_power)

    ss = sub.add_parser(
        "session", help="run a live participant's session of a study (docs/studies.md)"
    )
    ss.add_argument("study", help="study TOML file with a [live] table")
    ss.add_argument("--participant", required=True, metavar="ID", help="a [live] participant id")
    ss.add_argument("--out", default=None, help="study folder (default runs/studies/<name>/)")
    add_address_options(
        ss,
        host_flag="--host",
        host_help="address of the session's page and of each trial's bridge (non-loopback needs "
        "HRC_VR_TOKEN)",
    )
    ss.add_argument("--port", type=int, default=8770, help="the session page's port (8770)")
    ss.add_argument(
        "--vr-port",
        type=int,
        default=0,
        help="the trials' bridge port (default: one free at the first trial, kept for all)",
    )
    ss.add_argument(
        "--page-mode",
        choices=["desktop", "xr"],
        default=None,
        help="the mode in the printed link (default: the page picks: xr where WebXR is)",
    )
    ss.add_argument("--no-reach", action="store_true", help="skip the motion check")
    ss.set_defaults(func=_cmd_session)

    rp = sub.add_parser("report", help="write report.html for a sweep folder")
    rp.add_argument("sweep_dir")
    rp.set_defaults(func=_cmd_report)

    from hrc.bus import add_bus_arguments

    a = sub.add_parser("alive", help="exit 0 if SERVICE's liveliness token is on the bus")
    a.add_argument("service")
    a.add_argument(
        "--wait",
        type=float,
        default=5.0,
        help="keep trying for this many seconds (default 5: a fresh session needs a "
        "moment to learn the tokens)",
    )
    add_bus_arguments(a)
    a.set_defaults(func=_cmd_alive)

    ro = sub.add_parser("router", help="run a Zenoh router (for several hosts)")
    ro.add_argument(
        "--config",
        default=None,
        help="Zenoh JSON5 config: a session's router.json5 from `hrc deploy-access` (its "
        "credentials and access control), or deploy/zenoh-router.json5 (none: a trusted "
        "network only)",
    )
    ro.add_argument("--listen", action="append", default=None, metavar="ENDPOINT")
    ro.set_defaults(func=_cmd_router)

    se = sub.add_parser("services", help="list the services of a session (the service table)")
    se.set_defaults(func=_cmd_services)

    d = sub.add_parser(
        "deploy-files",
        help="write deploy/process-compose.yaml and deploy/compose.yaml from the service table",
    )
    d.add_argument(
        "--check", action="store_true", help="write nothing; exit 1 if a file is out of date"
    )
    d.set_defaults(func=_cmd_deploy_files)

    da = sub.add_parser(
        "deploy-access",
        help="write the Zenoh credentials of a deployed session (deploy/; docs/access.md)",
    )
    da.add_argument("--session", required=True, help="the session id (HRC_SESSION of deploy/)")
    da.add_argument(
        "--out", required=True, metavar="DIR", help="the folder to write (made mode 0700)"
    )
    da.add_argument(
        "--lease-s",
        type=float,
        default=DEPLOY_LEASE_S,
        metavar="S",
        help="how long a silent link stays open (Zenoh's lease; default %(default)g s; the "
        "logger keeps Zenoh's 10 s): a host cut off ends the run after about this long plus 1 s",
    )
    da.set_defaults(func=_cmd_deploy_access)

    f = sub.add_parser(
        "fit",
        help="each person's scripted-participant parameters from their recorded trials",
        description="Fit the scripted participant's parameters to recorded trials: a study "
        "folder (every participant with recordings) or one person's trial folders. Writes "
        "fitted.toml for a study's participants.fitted (docs/participant-model.md).",
    )
    f.add_argument("folders", nargs="+", metavar="FOLDER", help="a study folder, or trial folders")
    f.add_argument("--participant", default=None, help="whose trial folders these are")
    f.add_argument(
        "--where",
        action="append",
        metavar="KEY=VALUE",
        help="only the study's trials whose table column KEY is VALUE (repeatable)",
    )
    f.add_argument("--out", default=None, metavar="FILE", help="default: FOLDER/fitted.toml")
    f.add_argument("--json", action="store_true", help="print one JSON object")
    f.set_defaults(func=_cmd_fit)

    rb = sub.add_parser("robot", help="bring a lab's own robot (robots/README.md)")
    rsub = rb.add_subparsers(dest="robot_command", required=True)
    ra = rsub.add_parser(
        "add", help="a description package, URDF or xacro file made into a robot folder"
    )
    ra.add_argument("source", help="a URDF, a xacro file, or a description package's folder")
    ra.add_argument("--out", default=None, help="the robot's folder (default robots/NAME)")
    ra.add_argument("--name", default=None, help="default: the description's robot name")
    ra.add_argument(
        "--packages",
        action="append",
        default=[],
        metavar="DIR",
        help="a folder holding ROS packages: $(find PKG) and package://PKG/ (repeatable)",
    )
    ra.add_argument(
        "--arg", action="append", default=[], metavar="NAME:=VALUE", help="a xacro argument"
    )
    ra.add_argument("--base", default=None, metavar="LINK", help="the chain's base (guessed)")
    ra.add_argument("--tip", default=None, metavar="LINK", help="the chain's tip (guessed)")
    ra.add_argument(
        "--tcp", default="0,0,0", metavar="X,Y,Z", help="the tool centre point in the tip's frame"
    )
    ra.add_argument(
        "--board",
        default=None,
        metavar="SCENARIO",
        help="lay this scenario's board out for the arm (default scenarios/thesis.toml)",
    )
    ra.add_argument("--no-board", action="store_true", help="no board scenario")
    ra.set_defaults(func=_cmd_robot_add)

    b = sub.add_parser("bench", help="benchmarks that print their figures")
    b.add_argument(
        "what",
        choices=["bus", "ik", "physics", "client", "trial", "participant", "fit", "aligned"],
    )
    b.add_argument("--json", action="store_true", help="print one JSON object")
    b.add_argument("--n", type=int, default=0, help="samples / ticks (0: the benchmark's default)")
    b.add_argument(
        "--urdf", default=None, metavar="FILE", help="ik: benchmark this description's chain alone"
    )
    b.add_argument("--base", default=None, metavar="LINK", help="ik --urdf: the chain's base link")
    b.add_argument("--tip", default=None, metavar="LINK", help="ik --urdf: the chain's tip link")
    b.set_defaults(func=_cmd_bench)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    setup_logging("hrc", args.log_level or "WARNING")
    try:
        privacy.apply()  # participant data private by default (docs/access.md)
    except ValueError as exc:
        print(f"hrc: {exc}", file=sys.stderr)
        return 2
    code = int(args.func(args))
    if argv is None and args.func is _cmd_run:
        # The trial is over and its files are written: leave without the interpreter's teardown
        # (numpy, pydantic, zenoh's runtime: 50-600 ms after the summary on a busy machine).
        # Only as a program (argv None): a caller of main([...]) gets the code back.
        from hrc.service import exit_now

        exit_now(code)
    return code


if __name__ == "__main__":
    raise SystemExit(main())
