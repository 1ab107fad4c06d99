"""The ssm policy's per-robot monitor: scale, protective stop, hysteresis, resume, figures."""

from __future__ import annotations

import pytest

from hrc.scenario import Ssm
from hrc.ssm import (
    allowed_speed,
    loop_ticks,
    protective_distance,
    resume_distance,
    stop_distance,
)

from hrc_orchestrator.ssm import SCALE_STEP, SsmMonitor, SsmState

DT = 1.0 / 240.0
LOOP_TICKS = loop_ticks(1)  # a scan at every tick (the monitor's default)


def test_far_is_full_speed_near_is_scaled() -> None:
    p = Ssm()
    mon = SsmMonitor(p, max_speed=0.5)
    mon.observe(2.0, "")
    assert mon.update(0.0, DT, True) is None
    assert (mon.state, mon.scale) == (SsmState.NORMAL, 1.0)
    sep = protective_distance(p, 0.25)  # room for half the speed
    mon.observe(sep, "left")
    assert mon.update(DT, DT, True) is None
    assert mon.state == SsmState.REDUCED
    assert mon.scale <= allowed_speed(p, sep) / 0.5 + 1e-12  # never above the allowed speed
    # ... for the separation left once the loop's latency has passed (the hand closing in)
    left = sep - p.human_speed * LOOP_TICKS * DT
    assert mon.scale > allowed_speed(p, left) / 0.5 - SCALE_STEP
    assert mon.scale == pytest.approx(0.5, abs=3 * SCALE_STEP)


def test_with_a_scan_every_8_ticks_it_decides_at_the_scans_and_a_touch_stops_it_at_once() -> None:
    p = Ssm()
    mon = SsmMonitor(p, max_speed=0.5, scan=8)
    assert mon.loop_ticks == 10  # the decision reaches the arm a scan later
    mon.observe(2.0, "")
    mon.update(0.0, DT, True, tick=0)
    assert mon.scale == 1.0
    near = protective_distance(p, 0.25)
    mon.observe(near, "left")  # seen between two scans: nothing changes until the next
    for k in range(1, 8):
        assert mon.update(k * DT, DT, True, tick=k) is None
        assert mon.scale == 1.0 and mon.min_separation == 2.0
    mon.update(8 * DT, DT, True, tick=8)
    assert mon.state == SsmState.REDUCED and mon.min_separation == near
    # for the separation left once the longer loop has passed
    left = near - p.human_speed * 10 * DT
    assert mon.scale == pytest.approx(allowed_speed(p, left) / 0.5, abs=SCALE_STEP)
    assert not mon.urgent
    # a separation below the stop distance waits for the scan; a touch does not
    mon.observe(stop_distance(p) - 0.01, "left")
    assert mon.update(9 * DT, DT, True, tick=9) is None
    mon.touched = True
    change = mon.update(10 * DT, DT, True, tick=10)
    assert change is not None and change.stopped and mon.urgent
    assert mon.state == SsmState.STOPPED
    # the hand leaves: it resumes at a scan only
    mon.touched = False
    mon.observe(2.0, "")
    assert mon.update(11 * DT, DT, True, tick=11) is None
    change = mon.update(16 * DT, DT, True, tick=16)
    assert change is not None and not change.stopped and mon.scale == 1.0


def test_stop_at_the_protective_distance_and_resume_with_hysteresis() -> None:
    p = Ssm()
    mon = SsmMonitor(p, max_speed=0.5)
    stop_at = stop_distance(p)
    mon.observe(stop_at - 0.001, "right")
    change = mon.update(1.0, DT, True)
    assert change is not None and change.stopped and change.number == 1
    assert change.body == "right"
    # the stop distance, plus what the hand closes in during the loop's latency
    latency_margin = p.human_speed * LOOP_TICKS * DT
    assert change.protective_distance_m == pytest.approx(stop_distance(p) + latency_margin)
    assert (mon.state, mon.scale) == (SsmState.STOPPED, 0.0)
    # Between the stop distance and the resume distance it stays stopped (no chattering).
    mon.observe((stop_at + resume_distance(p)) / 2, "right")
    for k in range(1, 240):
        assert mon.update(1.0 + k * DT, DT, True) is None
    assert mon.state == SsmState.STOPPED
    mon.observe(resume_distance(p) + 0.001, "right")
    change = mon.update(2.0, DT, True)
    assert change is not None and not change.stopped
    assert change.stopped_s == pytest.approx(1.0)
    assert mon.state != SsmState.STOPPED and mon.scale > 0.0
    assert mon.stops == 1
    assert mon.stop_s == pytest.approx(240 * DT)  # counted per tick, from the tick after the stop


def test_a_touch_keeps_it_stopped_until_the_hand_leaves() -> None:
    mon = SsmMonitor(Ssm(), max_speed=0.5)
    mon.observe(0.0, "left")
    mon.touched = True
    assert mon.update(0.0, DT, True) is not None
    mon.observe(1.0, "left")  # far again, but still touching (separation is per tick)
    assert mon.update(0.1, DT, True) is None
    mon.touched = False
    change = mon.update(0.2, DT, True)
    assert change is not None and not change.stopped


def test_figures_count_only_while_the_task_runs() -> None:
    p = Ssm()
    mon = SsmMonitor(p, max_speed=0.5)
    mon.observe(0.3, "head")
    assert mon.update(0.0, DT, False) is None  # no stop before the start
    assert mon.min_separation is None
    mon.observe(protective_distance(p, 0.2), "head")
    for k in range(240):
        mon.update(k * DT, DT, True)
    assert mon.reduced_s == pytest.approx(240 * DT)  # it was reduced before the first tick
    assert mon.min_separation == pytest.approx(protective_distance(p, 0.2))


def test_a_separation_below_s_p_at_the_actual_speed_stops_the_arm() -> None:
    # ISO/TS 15066 5.5.4: S >= S_p at the speed the arm has, not only at the speed it is capped
    # to next (it may still be slowing down): inside S_p(actual) it is a protective stop.
    p = Ssm()
    mon = SsmMonitor(p, max_speed=0.5)
    sep = protective_distance(p, 0.25)  # the cap allows 0.25 m/s ...
    mon.observe(sep, "left")
    assert mon.update(0.0, DT, True, speed=0.2) is None  # ... and the arm is slower: fine
    assert mon.state == SsmState.REDUCED
    change = mon.update(DT, DT, True, speed=0.4)  # still at 0.4 m/s: S < S_p(0.4)
    assert change is not None and change.stopped
    assert change.protective_distance_m == pytest.approx(protective_distance(p, 0.4))
    assert (mon.state, mon.scale) == (SsmState.STOPPED, 0.0)


@pytest.mark.parametrize("max_speed", [1.0, 1.5])
def test_a_fast_arm_never_stands_still_without_a_protective_stop(max_speed: float) -> None:
    # Rounding the scale down to SCALE_STEP made separations whose allowed speed lies between
    # min_speed and one step of a fast arm's speed a standstill no event accounted for.
    p = Ssm()
    stop_at, step = stop_distance(p), 0.0005
    sep = stop_at
    while sep < stop_at + 0.05:
        mon = SsmMonitor(p, max_speed=max_speed)
        mon.observe(sep, "left")
        change = mon.update(0.0, DT, True)
        if mon.state != SsmState.STOPPED:
            assert change is None and mon.scale > 0.0, sep
            assert mon.scale * max_speed <= allowed_speed(p, sep) + 1e-12
        else:
            assert change is not None and change.stopped, sep
        sep += step
