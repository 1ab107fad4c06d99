"""hrc run on the empty scenario: five processes, lockstep ticks, metrics.json (issue 2)."""

from __future__ import annotations

import json
import subprocess
import threading

from hrc.bus.clock import REALTIME_EXCHANGE_MAX_S
from hrc.wire import pb

from .conftest import HRC, ROOT, wait_until


def test_hrc_run_empty_runs_2000_lockstep_ticks_and_writes_metrics(tmp_path, ik_bin) -> None:
    out = tmp_path / "trial"
    proc = subprocess.run(
        [HRC, "run", str(ROOT / "scenarios" / "empty.toml"), "--out", str(out), "--ticks", "2000"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    m = json.loads((out / "metrics.json").read_text())
    assert m["run"]["ticks"] == 2000
    assert m["run"]["mode"] == "lockstep"
    assert m["run"]["wall_s"] > 0
    assert m["scenario"] == "empty"
    # every service ran as its own process and left its own log
    for name in ("physics", "orchestrator", "ik_cpp", "human_input", "logger"):
        assert (out / "services" / f"{name}.log").exists(), name
    assert "2000 ticks" in proc.stdout


def test_hrc_run_sees_the_end_of_a_run_of_one_tick(tmp_path, ik_bin) -> None:
    """physics's first tick waits for hrc run's own session (--watchers), which must see
    run/end: from it come the run's reason on a failure, the logger's priority lifted at the
    end, and the phases of services/timing.json. The shortest run ends before anything else
    could have subscribed."""
    out = tmp_path / "trial"
    proc = subprocess.run(
        [HRC, "run", str(ROOT / "scenarios" / "empty.toml"), "--out", str(out), "--ticks", "1"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    t = json.loads((out / "services" / "timing.json").read_text())
    assert t["run_s"] is not None and t["start_s"] is not None, t
    assert set(t["exit_by_service_s"]) == {
        "physics",
        "ik_cpp",
        "orchestrator",
        "human_input",
        "logger",
    }


def test_the_five_services_are_separate_processes_that_all_take_part(trial_factory) -> None:
    trial = trial_factory()
    trial.wait_ticking()
    pids = trial.service_pids()
    assert sorted(pids) == sorted(["physics", "orchestrator", "ik_cpp", "human_input", "logger"])
    assert len(set(pids.values())) == 5
    for name in pids:
        s = trial.stats(name)
        assert s.service == name
        # the logger handles its first tick once its view is built (seconds, under load)
        assert name == "physics" or wait_until(
            lambda n=name: trial.stats(n).ticks_seen > 0, timeout=60, step=0.2
        ), name
    trial.stop()
    code, _out, err = trial.communicate()
    assert code == 0, err
    m = json.loads((trial.out / "metrics.json").read_text())
    assert m["run"]["ticks"] > 0 and "stopped by experimenter" in m["run"]["end_reason"]


def test_an_idle_trial_sends_states_only_as_one_keyframe_per_simulated_second(
    trial_factory,
) -> None:
    # Robots at home and a participant with nothing to do: their states do not change, so per
    # tick only the clock and the acks flow; a keyframe per simulated second keeps late joiners
    # (like this test) informed.
    trial = trial_factory()
    trial.wait_ticking()
    bus = trial.bus()
    lock = threading.Lock()
    clock: list[int] = []
    states: dict[str, list[int]] = {"r1": [], "r2": [], "human": []}

    def on_state(key: str, msg) -> None:
        with lock:
            states[msg.robot if key != bus.keys.human_state() else "human"].append(msg.header.tick)

    bus.subscribe(bus.keys.robot_states(), pb.RobotState, on_state)
    bus.subscribe(bus.keys.human_state(), pb.HumanState, on_state)
    # The clock only once every state subscription is known to deliver (a keyframe of each came):
    # a keyframe after the first clock tick seen must not fall before one of them took effect.
    assert wait_until(lambda: all(states.values()), timeout=60), states
    bus.subscribe(bus.keys.clock(), pb.ClockTick, lambda _k, m: clock.append(m.header.tick))
    # (the scripted participant's head settles within its first ~5 simulated seconds; the test
    # may join late, so it watches at least 5 simulated seconds itself)
    assert wait_until(
        lambda: clock and clock[-1] >= max(10 * 240, clock[0] + 5 * 240), timeout=120
    ), "too few ticks"
    trial.stop()
    code, _out, err = trial.communicate()
    assert code == 0, err
    with lock:
        first, last = clock[0], clock[-1]
        seconds = [k for k in range(first + 1, last) if k % 240 == 0]
        for robot in ("r1", "r2"):
            inside = [k for k in states[robot] if first < k < last]
            assert inside == seconds, (robot, inside, seconds)
        inside = [k for k in states["human"] if first < k < last]
        quiet_from = max((k for k in inside if k % 240), default=first)
        assert last - quiet_from > 3 * 240, f"the participant still moved at tick {quiet_from}"
        assert [k for k in inside if k > quiet_from] == [k for k in seconds if k > quiet_from], (
            inside
        )


def test_realtime_mode_is_paced_by_the_wall_clock(tmp_path, ik_bin) -> None:
    out = tmp_path / "rt"
    proc = subprocess.run(
        [
            HRC,
            "run",
            str(ROOT / "scenarios" / "empty.toml"),
            "--out",
            str(out),
            "--ticks",
            "480",
            "--mode",
            "realtime",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    run = json.loads((out / "metrics.json").read_text())["run"]
    assert run["mode"] == "realtime" and run["ticks"] == 480
    # never ahead of the wall clock: an exchange starts no sooner than its first tick's time, so
    # the last one (a headset frame's ticks at most: 478-479) at 478/240 s or later (bounded by
    # 479/240, this failed by 2 ms on a lightly loaded machine)
    span = int(REALTIME_EXCHANGE_MAX_S * 240 + 1e-9)
    assert span == 2
    assert run["wall_s"] >= (480 - span) / 240
    assert "deadline_misses" in run


def test_a_bad_scenario_starts_nothing_and_names_the_problem(tmp_path, ik_bin) -> None:
    bad = tmp_path / "bad.toml"
    text = (ROOT / "scenarios" / "empty.toml").read_text().replace("tick_hz = 240", "tick_hz = -5")
    assert "tick_hz = -5" in text
    bad.write_text(text)
    out = tmp_path / "never"
    proc = subprocess.run(
        [HRC, "run", str(bad), "--out", str(out)], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 2
    assert "tick_hz" in proc.stderr
    assert not out.exists()


def test_bench_bus_prints_the_figures_as_one_json_object(ik_bin) -> None:
    # The shape the issue asks for; the figures themselves are the benchmark's business.
    proc = subprocess.run(
        [HRC, "bench", "bus", "--json", "--n", "300"], capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    assert sorted(result) == ["lockstep_lowlatency_ticks_per_s", "lockstep_ticks_per_s", "rtt_us"]
    assert sorted(result["rtt_us"]) == ["py_cpp", "py_py"]
    for pair in result["rtt_us"].values():
        assert sorted(pair) == ["p50", "p99"] and 0 < pair["p50"] <= pair["p99"]
    assert result["lockstep_ticks_per_s"] > 0 and result["lockstep_lowlatency_ticks_per_s"] > 0
