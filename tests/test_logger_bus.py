"""The real logger process fed a synthetic session over real Zenoh (issue 7).

This test plays physics (clock ticks, world, run/end), ik_cpp (robot states with joint positions
for r1 and r2), human_input and the orchestrator (scenario queryable, task events with
collisions and near collisions, cues, finishes, TASK FINISHED and the final metrics), each as its
own Zenoh session, and checks the logger's files.
"""

from __future__ import annotations

import json
import subprocess
import sys
import uuid
from collections import Counter
from pathlib import Path

import pytest

from hrc import scenario as sc
from hrc.bus import Bus, BusConfig, Publisher
from hrc.wire import pb

from .conftest import ROOT, free_port, wait_until
from .goldens import THESIS, Finished
from hrc_logger.rrd import summarize

sys.path.insert(0, str(ROOT / "services" / "logger" / "tests"))
from synthetic import ROLES, Outgoing, SyntheticTrial


def read_with_dataframe_api(rrd: Path):  # a pyarrow.Table
    """The recording through rerun's own dataframe API (0.41: a local catalog server and a
    DataFusion reader indexed by the tick timeline)."""
    import rerun as rr

    with rr.server.Server(
        host="127.0.0.1", port=free_port(), datasets={"trial": [str(rrd)]}
    ) as server:
        client = server.client()  # must outlive the reader's materialisation
        return client.get_dataset("trial").reader(index="tick").to_arrow_table()


pytestmark = pytest.mark.slow


class FakeSession:
    """Four Zenoh sessions playing physics, ik_cpp, human_input and the orchestrator."""

    def __init__(self, session: str, port: int, scenario: pb.Scenario) -> None:
        endpoint = f"tcp/127.0.0.1:{port}"
        self.buses: dict[str, Bus] = {}
        for role, name in ROLES.items():
            cfg = (
                BusConfig(session=session, listen=[endpoint])
                if role == "physics"
                else BusConfig(session=session, connect=[endpoint])
            )
            self.buses[role] = Bus(cfg, name)
        phys = self.buses["physics"]
        self.keys = phys.keys
        self.scenario = scenario
        self.scenario.header.session = session
        self.buses["orch"].queryable(self.keys.scenario(), None, lambda _req: self.scenario)
        phys.declare_token()  # the clock master is alive (the logger watches it)
        self.clock = phys.publisher(self.keys.clock(), express=True)
        self.run_end = phys.publisher(self.keys.run_end())

    def publisher(self, o: Outgoing) -> Publisher:
        k = self.keys
        if o.key.startswith("robot_state:"):
            key = k.robot_state(o.key.split(":", 1)[1])
        else:
            key = getattr(k, o.key)()
        return self.buses[o.role].publisher(key)

    def marks(self) -> list[pb.PublishedMark]:
        return [
            m
            for b in self.buses.values()
            for m in b.published_marks()
            if not m.key.endswith("/clock")
        ]

    def close(self) -> None:
        for b in self.buses.values():
            b.close()


def run_synthetic(
    tmp_path: Path, gap_tick: int | None = None, term_tick: int | None = None
) -> tuple[Path, SyntheticTrial, subprocess.CompletedProcess]:
    session = f"lg{uuid.uuid4().hex[:8]}"
    port = free_port()
    scenario = sc.to_proto(sc.load(THESIS, motion_check=False))
    trial = SyntheticTrial(scenario, n_ticks=600)
    out = tmp_path / "trial"
    fake = FakeSession(session, port, scenario)
    log_path = tmp_path / "logger.log"
    with open(log_path, "w") as log_file:
        proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "hrc_logger",
                "--session",
                session,
                "--connect",
                f"tcp/127.0.0.1:{port}",
                "--out",
                str(out),
                "--scenario-timeout",
                "30",
            ],
            stdout=log_file,
            stderr=subprocess.STDOUT,
        )
        try:
            phys = fake.buses["physics"]
            assert wait_until(lambda: "logger" in phys.alive_services(timeout=0.3), timeout=60), (
                log_path.read_text()
            )
            # The logger takes part at once and builds its view meanwhile; this test kills it
            # mid-trial and reads the view, so it starts once the view is there.
            assert wait_until(lambda: "view ready" in log_path.read_text(), timeout=120), (
                log_path.read_text()
            )
            stats = phys.get(fake.keys.stats("logger"), pb.ServiceStats, timeout=5)
            assert stats and stats[0].service == "logger"
            assert fake.keys.task_events() in stats[0].subscribed
            dt = trial.dt
            for k, world, outputs in trial.ticks():
                if k == term_tick:
                    proc.terminate()  # what `hrc run` does to the services when a trial fails
                    break
                for o in world:
                    fake.publisher(o).put(o.msg, k, k * dt)
                tick = pb.ClockTick(
                    mode=pb.CLOCK_MODE_LOCKSTEP,
                    dt=dt,
                    participants=["ik_cpp", "orchestrator", "human_input"],
                )
                tick.published.extend(fake.marks())
                fake.clock.put(tick, k, k * dt)
                for o in outputs:
                    pub = fake.publisher(o)
                    if gap_tick == k and o.key == "task_events":
                        pub.seq += 1  # a lost message: this seq number never goes out
                    pub.put(o.msg, k, k * dt)
            if term_tick is None:
                fake.run_end.put(
                    pb.RunEnd(
                        ok=True,
                        reason="stopped by orchestrator: task finished",
                        ticks=trial.n,
                        sim_time=trial.n * dt,
                        mode=pb.CLOCK_MODE_LOCKSTEP,
                        last_clock_seq=fake.clock.seq,
                    ),
                    trial.n,
                    trial.n * dt,
                )
            rc = proc.wait(timeout=120)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
            fake.close()
    done = subprocess.CompletedProcess(proc.args, rc, log_path.read_text(), "")
    return out, trial, done


@pytest.fixture(scope="module")
def synthetic_run(
    tmp_path_factory: pytest.TempPathFactory,
) -> tuple[Path, SyntheticTrial, subprocess.CompletedProcess]:
    return run_synthetic(tmp_path_factory.mktemp("logger_bus"))


def test_logger_exits_cleanly_and_reports_its_lag(synthetic_run) -> None:
    out, trial, done = synthetic_run
    assert done.returncode == 0, done.stdout
    stats = json.loads((out / "logger_stats.json").read_text())
    assert stats["seq_gaps"] == 0 and stats["lost_messages"] == 0, done.stdout
    assert stats["ticks"] == trial.n
    assert stats["lag_max_ticks"] >= 0 and stats["lag_mean_ticks"] >= 0
    assert stats["messages"] >= trial.n * 4  # clock, world, 2 robot states, human state per tick
    assert "logger summary" in done.stdout


def test_log_txt_order_and_counts_match_the_metrics(synthetic_run) -> None:
    out, _trial, _ = synthetic_run
    lines = (out / "log.txt").read_text().splitlines()
    metrics = [
        json.loads(line)
        for line in (out / "events.jsonl").read_text().splitlines()
        if json.loads(line)["type"] == "metrics"
    ]
    assert len(metrics) == 1 and metrics[0]["final"], "the final metrics (last tick) were drained"
    m = metrics[0]
    assert lines[0].startswith("SETTINGS: ") and lines[1].endswith(" - TASK STARTED.")
    assert (
        sum(" : Collision " in line for line in lines) == m["collisions"]["human_robot_count"] == 2
    )
    assert sum(" : Near-collision " in line for line in lines) == m["collisions"]["near_count"] == 1
    finishes = [i for i, line in enumerate(lines) if "task FINISHED" in line]
    robot_finishes = [i for i in finishes if " : r1 " in lines[i] or " : r2 " in lines[i]]
    human = [i for i in finishes if " : Human " in lines[i]]
    collisions = [
        i for i, line in enumerate(lines) if " : Collision " in line or " : Near-collision " in line
    ]
    assert len(robot_finishes) == 2 and len(human) == 1
    assert max(collisions) < min(robot_finishes) < max(robot_finishes) < human[0] < len(lines) - 2
    assert lines[-2].endswith(
        f"TASK FINISHED. {m['collisions']['human_robot_count']} total collisions."
    )
    assert lines[-1].endswith(
        f" {m['collisions']['near_count']} total near-collisions between the robots."
    )


def test_events_jsonl_parses_line_by_line_with_the_same_counts(synthetic_run) -> None:
    out, trial, _ = synthetic_run
    records = [json.loads(line) for line in (out / "events.jsonl").read_text().splitlines()]
    kinds = Counter(r["kind"] for r in records if r["type"] == "event")
    assert kinds == trial.expected.event_kinds
    m = next(r for r in records if r["type"] == "metrics")
    assert kinds["COLLISION"] == m["collisions"]["human_robot_count"]
    assert kinds["NEAR_COLLISION"] == m["collisions"]["near_count"]
    assert sum(r["type"] == "cue" for r in records) == trial.expected.cue_changes
    ticks = [r["tick"] for r in records if r["type"] in ("event", "cue")]
    assert ticks == sorted(ticks)


def test_recording_opens_with_reruns_reader_and_covers_the_trial(synthetic_run) -> None:
    out, trial, _ = synthetic_run
    s = summarize(out / "recording.rrd")
    last = trial.n - 1
    for rid in ("r1", "r2"):
        for j in ("j1_base_yaw", "j2_shoulder", "j3_elbow", "j4_wrist_pitch", "j5_wrist_roll"):
            e = s[f"/robot_{rid}/joints/{j}"]
            assert {
                "Transform3D:translation",
                "Transform3D:quaternion",
                "Transform3D:parent_frame",
            } <= e.components
            assert (e.first_tick, e.last_tick) == (0, last), (rid, j)
    for p in trial.sc.parts:
        assert f"/world/targets/{p.id}" in s, p.id
        if p.start_given or p.id in trial.expected.parts_moved:
            assert "Transform3D:translation" in s[f"/world/parts/{p.id}"].components, p.id
    for cid in trial.expected.cue_ids:
        assert "/world/cues/" + cid.replace(":", "/") in s, cid
    assert s["/plots/tcp_speed/r1"].last_tick == last
    assert s["/plots/hand_distance/left/r2"].last_tick == last
    assert s["/events"].last_tick == last  # TASK FINISHED came on the last tick


def test_a_sequence_gap_is_reported_and_counted(tmp_path: Path) -> None:
    out, _trial, done = run_synthetic(tmp_path, gap_tick=300)
    assert done.returncode == 0, done.stdout
    stats = json.loads((out / "logger_stats.json").read_text())
    assert stats["seq_gaps"] == 1 and stats["lost_messages"] == 1
    assert (
        "sequence gap on hrc/" in done.stdout and "/task/events from 'orchestrator'" in done.stdout
    )
    assert "ERROR" in done.stdout


def test_sigterm_mid_trial_closes_every_file_readable(tmp_path: Path) -> None:
    out, _trial, done = run_synthetic(tmp_path, term_tick=320)
    assert done.returncode == 1, done.stdout  # the run did not end normally
    lines = (out / "log.txt").read_text().splitlines()
    assert lines[0].startswith("SETTINGS: ") and lines[1].endswith(" - TASK STARTED.")
    assert sum(" : Collision " in line for line in lines) == 1  # the one at tick 250
    assert "RUN ENDED WITH AN ERROR: terminated by SIGTERM" in lines[-1]
    records = [json.loads(line) for line in (out / "events.jsonl").read_text().splitlines()]
    assert Counter(r["kind"] for r in records if r["type"] == "event")["COLLISION"] == 1
    s = summarize(out / "recording.rrd")
    assert 200 <= s["/robot_r1/joints/j1_base_yaw"].last_tick < 320
    assert json.loads((out / "logger_stats.json").read_text())["seq_gaps"] == 0


@pytest.mark.e2e
def test_full_thesis_trial_logger_outputs(thesis_trial: Finished) -> None:
    out = thesis_trial.folder
    assert thesis_trial.returncode == 0, thesis_trial.stdout + thesis_trial.stderr
    metrics = thesis_trial.metrics
    lines = thesis_trial.log_lines
    assert lines[0].startswith("SETTINGS: ") and lines[1].endswith(" - TASK STARTED.")
    assert lines[-2].startswith(
        f"{metrics['task']['completion_s']:.3f} sec : TASK FINISHED"
    ) and lines[-2].endswith("total collisions."), lines[-2]
    assert lines[-1].endswith(
        f" {metrics['collisions']['near_count']} total near-collisions between the robots."
    )
    col = metrics["collisions"]
    assert sum(" : Collision " in line for line in lines) == col["human_robot_count"]
    assert sum(" : Near-collision " in line for line in lines) == col["near_count"]
    assert sum("task FINISHED" in line and " : Human " not in line for line in lines) == len(
        metrics["robots"]
    )
    assert sum(" : Human - task FINISHED" in line for line in lines) == 1
    records = thesis_trial.events
    kinds = Counter(r["kind"] for r in records if r["type"] == "event")
    assert kinds["COLLISION"] == col["human_robot_count"]
    assert kinds["NEAR_COLLISION"] == col["near_count"]
    # rerun's own reader: joint transforms of both robots over the whole trial, parts, cues
    import pyarrow.compute as pc

    table = read_with_dataframe_api(out / "recording.rrd")
    cols = table.column_names
    ticks = metrics["run"]["ticks"]
    for rid in metrics["robots"]:
        for j in ("j1_base_yaw", "j5_wrist_roll"):
            col = f"/robot_{rid}/joints/{j}:Transform3D:quaternion"
            assert col in cols, col
            seen = pc.filter(table.column("tick"), pc.is_valid(table.column(col)))
            assert pc.min(seen).as_py() <= 1 and pc.max(seen).as_py() >= ticks - 2, (col, seen)
    for pid in metrics["parts"]:
        assert any(c.startswith(f"/world/parts/{pid}:") for c in cols), pid
    assert any(c.startswith("/world/cues/") for c in cols)
    s = summarize(out / "recording.rrd")
    for rid in metrics["robots"]:
        e = s[f"/robot_{rid}/joints/j1_base_yaw"]
        assert e.first_tick is not None and e.first_tick <= 1 and e.last_tick >= ticks - 2, (
            rid,
            e.first_tick,
            e.last_tick,
        )
    for pid in metrics["parts"]:
        assert f"/world/parts/{pid}" in s, pid
    assert any(e.startswith("/world/cues/") for e in s)
    stats = json.loads((out / "logger_stats.json").read_text())
    assert stats["seq_gaps"] == 0
    print(
        f"e2e thesis trial: {ticks} ticks in {metrics['run']['wall_s']:.1f} s; logger lag mean "
        f"{stats['lag_mean_ticks']} max {stats['lag_max_ticks']} ticks"
    )
