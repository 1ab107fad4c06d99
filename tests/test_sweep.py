"""`hrc sweep` and `hrc report` end to end: real trials (five services each) of a small study on
minimal.toml, here and on a local Dask cluster; resume; a trial that stalls; the report page;
a trial started from the sweep's warm worker gives the files of a fresh `hrc run`."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pandas as pd
import pytest

from hrc.browser import headless_chromium, output_dir
from hrc.priority import parse_cpus
from hrc.study.sweep import WARM_SAYS

from .conftest import HRC, free_port, strip_fields, wait_until
from .goldens import MINIMAL
from .netns import Hosts

pytestmark = [pytest.mark.slow, pytest.mark.e2e]

STUDY = f"""
[study]
name = "mini-2x2x2"
scenario = "{MINIMAL}"

[factors]
"robots.*.max_tcp_speed" = [0.5, 1.0]
"conditions.anticipation" = [true, false]

[participants]
n = 2
seed_base = 1000
reaction_time_s = {{ dist = "normal", mean = 0.4, sd = 0.08, min = 0.15, max = 0.9 }}
peak_hand_speed = {{ dist = "normal", mean = 1.0, sd = 0.15, min = 0.5, max = 1.6 }}
caution = {{ dist = "uniform", min = 0.0, max = 1.0 }}
"""
DASK = str(Path(sys.executable).with_name("dask"))
# wall-clock fields legitimately differ between two runs of the same trial
WALL = {"wall_s", "run.wall_s", "run.realtime_factor"}


def _sweep(*args: str, timeout: float = 280) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, CI="1")  # plain progress lines
    return subprocess.run(
        [HRC, "sweep", *args], capture_output=True, text=True, timeout=timeout, env=env
    )


# a trial's wall-clock fields (events' wall_time, the run's wall_s and real-time factor); the
# end reason stays compared (goldens.WALL drops it)
WALL_FIELDS = {"wall_time", "wall_s", "realtime_factor"}
_STAMP = re.compile(r"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d ")  # log.txt's wall-clock lines


def assert_as_a_fresh_run(out: Path, trial: str, tmp: Path) -> None:
    """The sweep's files of ``trial`` (started as a fork of its warm worker) are those of `hrc
    run` of its resolved scenario and seed in a new interpreter: the same events, metrics and
    text log, wall-clock fields aside."""
    seed = int(pd.read_parquet(out / "trials.parquet").set_index("trial").loc[trial, "seed"])
    fresh = tmp / f"fresh-{trial}"
    argv = [HRC, "run", str(out / "resolved" / f"{trial}.toml"), "--out", str(fresh)]
    run = subprocess.run(
        [*argv, "--seed", str(seed), "--no-reach-check"],
        capture_output=True,
        text=True,
        timeout=180,
        env=dict(os.environ, HRC_SWEEP_START="exec"),
    )
    warm = out / "trials" / trial
    ok = json.loads((warm / "metrics.json").read_text())["run"]["ok"]
    assert (run.returncode == 0) == ok, (ok, run.returncode, run.stderr[-2000:])
    a, b = ((d / "events.jsonl").read_text().splitlines() for d in (warm, fresh))
    assert [strip_fields(json.loads(x), WALL_FIELDS) for x in a] == [
        strip_fields(json.loads(x), WALL_FIELDS) for x in b
    ], f"{trial}: events.jsonl differs from a fresh run's"
    a, b = (strip_fields(json.loads((d / "metrics.json").read_text()), WALL_FIELDS)
            for d in (warm, fresh))  # fmt: skip
    assert a == b, f"{trial}: metrics.json differs from a fresh run's"
    a, b = ((d / "log.txt").read_text().splitlines() for d in (warm, fresh))
    assert [_STAMP.sub("", x) for x in a] == [_STAMP.sub("", x) for x in b], f"{trial}: log.txt"


@pytest.fixture(scope="module")
def study_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("study") / "mini.toml"
    path.write_text(STUDY)
    return path


@pytest.fixture(scope="module")
def local_sweep(study_file: Path) -> tuple[Path, subprocess.CompletedProcess[str]]:
    out = study_file.parent / "local"
    # without the 3D recordings: the cluster's sweep below keeps them, and gives the same table
    # each trial on a CPU of its own (--pin; the comparison with a fresh run covers it too)
    proc = _sweep(str(study_file), "--out", str(out), "--workers", "2", "--no-view", "--pin")
    assert proc.returncode == 0, proc.stderr
    return out, proc


def test_a_2x2x2_study_gives_8_rows_with_factors_participants_and_metrics(local_sweep) -> None:
    out, proc = local_sweep
    df = pd.read_parquet(out / "trials.parquet")
    csv = pd.read_csv(out / "trials.csv")
    assert len(df) == 8 and len(csv) == 8
    bad = df[df["outcome"] != "ok"]
    assert bad.empty, "\n".join(f"{r.trial}: {r.outcome}: {r.reason}" for r in bad.itertuples())
    assert set(df["trial"]) == {
        f"speed{s}_ant{a}_P0{p}_r1" for s in ("0.5", "1") for a in (True, False) for p in (1, 2)
    }
    assert sorted(df["robots.*.max_tcp_speed"].unique()) == [0.5, 1.0]
    assert set(df["conditions.anticipation"]) == {True, False}
    assert set(df["participant"]) == {"P01", "P02"}
    for col in ("participant.reaction_time_s", "participant.caution", "seed", "repetition"):
        assert df[col].notna().all(), col
    # metrics.json read generically: its fields are columns, lists counted
    assert df["task.completion_s"].gt(0).all()
    assert "robots.r1.avg_tcp_speed_mps" in df and "collisions.human_robot" in df
    # each trial ran at its own speed: faster robots finish their part sooner
    r1 = df.groupby("robots.*.max_tcp_speed")["robots.r1.completion_s"].mean()
    assert r1[1.0] < r1[0.5]
    for trial in df["trial"]:
        assert (out / "trials" / trial / "metrics.json").is_file()
        assert not (out / "trials" / trial / "recording.rrd").exists(), f"{trial}: --no-view"
    assert (out / "study.toml").read_text() == STUDY
    assert "8 trials, 0 done before (kept), 8 to run" in proc.stderr
    assert proc.stderr.count("ETA") == 8


def test_each_of_two_parallel_trials_runs_on_a_cpu_of_its_own(local_sweep) -> None:
    # (the outputs are those of a fresh run all the same: the test below)
    n = len(os.sched_getaffinity(0))  # the sweep's, as it inherits them
    if n < 2:
        pytest.skip("one CPU: nothing to share out")
    out, _ = local_sweep
    on: dict[str, str] = {}
    for trial in sorted((out / "trials").iterdir()):
        first = (trial / "hrc-run.log").read_text().splitlines()[0]
        found = re.search(r", on CPUs ([\d,-]+)\)", first)
        assert found, f"{trial.name}: not held to CPUs of its own: {first}"
        on[trial.name] = found.group(1)
    # two workers: the CPUs cut in two, the first two trials (at once) on both halves
    assert len(set(on.values())) == 2, on
    assert all(len(parse_cpus(c)) in (n // 2, n - n // 2) for c in on.values()), on


def test_a_trial_from_the_warm_worker_gives_a_fresh_runs_files(local_sweep, tmp_path) -> None:
    out, proc = local_sweep
    assert WARM_SAYS in proc.stderr, proc.stderr  # (else this compares two fresh runs)
    assert_as_a_fresh_run(out, "speed0.5_antTrue_P02_r1", tmp_path)


def test_a_second_run_resumes_without_rerunning_any_trial(local_sweep, study_file) -> None:
    out, _ = local_sweep
    manifest = json.loads((out / "manifest.json").read_text())["trials"]
    stamps = {p: p.stat().st_mtime_ns for p in (out / "trials").glob("*/metrics.json")}
    assert len(stamps) == 8
    again = _sweep(str(study_file), "--out", str(out), "--workers", "2", timeout=60)
    assert again.returncode == 0, again.stderr
    assert "8 trials, 8 done before (kept), 0 to run" in again.stderr
    assert "ETA" not in again.stderr
    assert json.loads((out / "manifest.json").read_text())["trials"] == manifest
    assert {p: p.stat().st_mtime_ns for p in stamps} == stamps
    assert len(pd.read_parquet(out / "trials.parquet")) == 8


def test_a_stalled_trial_is_recorded_and_the_sweep_goes_on(tmp_path: Path) -> None:
    # a participant who waits 10 s before every move, in a trial whose watchdog allows 1 s
    # without progress: the orchestrator ends it as stalled; the other condition runs normally
    study = tmp_path / "stall.toml"
    study.write_text(
        f'[study]\nname = "stall"\nscenario = "{MINIMAL}"\ndesign = "list"\n\n'
        '[[conditions]]\n"participant.reaction_time_s" = 10.0\n"scenario.stall_timeout_s" = 1.0\n'
        '[[conditions]]\n"participant.reaction_time_s" = 0.4\n"scenario.stall_timeout_s" = 60.0\n'
        "[participants]\nn = 1\n"
    )
    out = tmp_path / "out"
    proc = _sweep(str(study), "--out", str(out), "--workers", "2")
    assert proc.returncode == 0, proc.stderr
    df = pd.read_parquet(out / "trials.parquet").set_index("trial")
    assert len(df) == 2
    stalled = df.loc["rt10_stall1_P01_r1"]
    assert stalled["outcome"] == "stalled", stalled["reason"]
    assert "stalled for 1 s" in stalled["reason"]
    assert stalled["exit_code"] != 0 and not stalled["task.finished"]
    assert df.loc["rt0.4_stall60_P01_r1", "outcome"] == "ok"
    # by default each trial keeps its 3D recording
    assert (out / "trials" / "rt0.4_stall60_P01_r1" / "recording.rrd").stat().st_size > 10_000
    assert "rt10_stall1_P01_r1: stalled" in proc.stdout
    assert WARM_SAYS in proc.stderr, proc.stderr
    # the run ends right after the stall's tick (mid-exchange here: the stall, sent as an abort,
    # once ended it after the exchange's first tick or after its own tick, by timing)
    evs = [
        json.loads(line)
        for line in (out / "trials" / "rt10_stall1_P01_r1" / "events.jsonl")
        .read_text()
        .splitlines()
    ]
    stall = next(e for e in evs if e.get("kind") == "STALLED")
    end = next(e for e in evs if e.get("type") == "run_end")
    assert end["tick"] == stall["tick"] + 1, (stall["tick"], end["tick"])
    assert_as_a_fresh_run(out, "rt10_stall1_P01_r1", tmp_path)  # a trial that fails, too
    # a resumed sweep keeps it: its inputs have not changed and it ended (deterministically)
    again = _sweep(str(study), "--out", str(out), timeout=60)
    assert "2 done before (kept), 0 to run" in again.stderr
    report = subprocess.run([HRC, "report", str(out)], capture_output=True, text=True, timeout=120)
    assert report.returncode == 0, report.stderr
    page = (out / "report.html").read_text()
    assert "rt10_stall1_P01_r1" in page and "stalled for 1 s" in page


def dask_worker(scheduler: str, name: str, host: str, folder: Path) -> list[str]:
    """A single-threaded Dask worker named ``name`` listening on ``host``."""
    return [
        *(DASK, "worker", scheduler, "--nthreads", "1", "--nworkers", "1", "--host", host),
        *("--name", name, "--local-directory", str(folder), "--no-dashboard"),
    ]


def assert_same_table(local: Path, out: Path) -> None:
    """The sweep in ``out`` ran all 8 trials and gives ``local``'s table (wall times aside)."""
    a = pd.read_parquet(local / "trials.parquet").sort_values("trial").reset_index(drop=True)
    b = pd.read_parquet(out / "trials.parquet").sort_values("trial").reset_index(drop=True)
    assert list(b["outcome"]) == ["ok"] * 8
    keep = [c for c in a.columns if c not in WALL]
    assert keep == [c for c in b.columns if c not in WALL]
    pd.testing.assert_frame_equal(a[keep], b[keep])


@pytest.fixture()
def dask_cluster(tmp_path: Path) -> Iterator[str]:
    """A Dask scheduler and 2 single-threaded workers on loopback, as processes."""
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    logs = [open(tmp_path / f"dask-{i}.log", "w") for i in range(3)]
    procs = [
        subprocess.Popen(
            [DASK, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
            stdout=logs[0],
            stderr=subprocess.STDOUT,
        )
    ]
    try:
        for i in (1, 2):
            procs.append(
                subprocess.Popen(
                    dask_worker(address, f"w{i}", "127.0.0.1", tmp_path / f"w{i}"),
                    stdout=logs[i],
                    stderr=subprocess.STDOUT,
                )
            )
        from distributed import Client

        with Client(address, timeout="30s") as client:
            client.wait_for_workers(2, timeout=60)
        yield address
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        for f in logs:
            f.close()


def test_the_cluster_gives_the_same_table_as_the_local_run(
    local_sweep, study_file, dask_cluster: str
) -> None:
    local, _ = local_sweep
    out = study_file.parent / "cluster"
    proc = _sweep(str(study_file), "--out", str(out), "--cluster", dask_cluster)
    assert proc.returncode == 0, proc.stderr
    manifest = json.loads((out / "manifest.json").read_text())["trials"]
    assert all(r["host"] for r in manifest.values())
    assert_same_table(local, out)  # (the local sweep's trials ran without their views)
    assert all((out / "trials" / t / "recording.rrd").is_file() for t in manifest), manifest


def test_the_report_has_every_section_and_reads_well(local_sweep) -> None:
    out, _ = local_sweep
    t0 = time.monotonic()
    proc = subprocess.run([HRC, "report", str(out)], capture_output=True, text=True, timeout=240)
    assert proc.returncode == 0, proc.stderr
    page = (out / "report.html").read_text()
    for section in (
        "Outcomes by factor level",
        "Task completion",
        "Human completion",
        "Human idle",
        "Robot idle",
        "Human\u2013robot collisions",
        "Total collision delay",
        "Near collisions",
        "Average TCP speed",
        "Interactions",
        "max_tcp_speed \u00d7 anticipation",
        "Mixed-effects models",
        "Failed trials",
    ):
        assert section in page, section
    figures = sorted(p.name for p in (out / "figures").glob("*.png"))
    assert "means_task_completion_s.png" in figures and any("interaction" in f for f in figures)
    shots = output_dir("report")
    with headless_chromium() as browser:
        tab = browser.new_page(viewport={"width": 1200, "height": 900})
        tab.goto((out / "report.html").as_uri())
        broken = tab.evaluate(
            "[...document.images].filter(i => !i.complete || i.naturalWidth === 0).length"
        )
        tab.screenshot(path=str(shots / "report.png"), full_page=True)
    assert broken == 0
    print(f"report in {time.monotonic() - t0:.1f} s; screenshot {shots / 'report.png'}")


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_stopped_sweep_stops_its_trials_and_keeps_what_finished(
    study_file: Path, tmp_path: Path, sig: int
) -> None:
    out = tmp_path / "stopped"
    proc = subprocess.Popen(
        [HRC, "sweep", str(study_file), "--out", str(out), "--workers", "2", "--no-reach"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    # wait until both trials' services are up, then stop the sweep
    assert wait_until(lambda: len(list((out / "trials").glob("*/services/*.log"))) >= 10, 120)
    proc.send_signal(sig)
    _out, err = proc.communicate(timeout=60)
    assert proc.returncode == (130 if sig == signal.SIGINT else 128 + sig), err
    assert "finished trials are kept" in err
    assert wait_until(lambda: not _processes_under(out), 10), _processes_under(out)


def _processes_under(folder: Path) -> list[str]:
    """Command lines of running processes that name ``folder`` (a trial's hrc run, its services)."""
    found = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            cmd = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
        except OSError:
            continue
        if str(folder) in cmd:
            found.append(cmd)
    return found


@pytest.mark.timeout(600)
def test_a_cluster_over_three_hosts_gives_the_same_table(
    local_sweep, study_file, tmp_path: Path
) -> None:
    """The scheduler (and the sweep) on one host, a worker on each of two more, joined by
    cables (network namespaces, tests/netns.py): the table is the local run's."""
    out = study_file.parent / "hosts"
    with Hosts(f"hrs{os.getpid() % 100000}", ["s", "w1", "w2"], tmp_path / "logs") as hosts:
        s1, w1 = hosts.cable("s", "w1")
        _s2, w2 = hosts.cable("s", "w2")
        address = f"tcp://{s1}:8786"
        hosts.start("s", "scheduler", [DASK, "scheduler", "--host", s1, "--no-dashboard"])
        for name, addr in (("w1", w1), ("w2", w2)):
            hosts.start(name, name, dask_worker(address, name, addr, tmp_path / name))

        def joined() -> bool:
            log = hosts.log("scheduler")
            return all(f"Register worker addr: tcp://{a}:" in log for a in (w1, w2))

        assert wait_until(joined, 120, 0.2), hosts.log("scheduler")[-3000:]
        idle = {w: len(hosts.pids(w)) for w in ("w1", "w2")}  # the worker and its nanny
        busiest = dict(idle)
        sweep = hosts.start(
            "s", "sweep", [HRC, "sweep", str(study_file), "--out", str(out), "--cluster", address]
        )
        deadline = time.monotonic() + 400
        while sweep.poll() is None:  # watch each worker host run trials (hrc run + 5 services)
            if time.monotonic() > deadline:
                pytest.fail(f"the sweep still runs after 400 s:\n{hosts.log('sweep')[-3000:]}")
            for w in busiest:
                busiest[w] = max(busiest[w], len(hosts.pids(w)))
            time.sleep(0.2)
        assert sweep.returncode == 0, hosts.log("sweep")[-3000:]
    assert all(busiest[w] >= idle[w] + 4 for w in idle), (idle, busiest)
    assert_same_table(local_sweep[0], out)
