"""The view's per-robot state stream: rate limit, the state held back, the state held to the end."""

from __future__ import annotations

from hrc.wire import pb

from hrc_logger.series import StateStream


def _state(tick: int, speed: float) -> pb.RobotState:
    st = pb.RobotState(robot="r1", tcp_speed=speed)
    st.header.tick = tick
    st.header.sim_time = tick / 240
    return st


def test_at_most_one_state_per_period_and_the_held_back_one_at_the_end() -> None:
    s: StateStream[pb.RobotState] = StateStream()
    logged = [k for k in range(20) if s.offer(_state(k, 0.1 * k), every=8)]
    assert logged == [0, 8, 16]
    for k in logged:
        s.logged(_state(k, 0.0))
    # 19 was held back by the rate limit; no clock given: nothing more
    assert [st.header.tick for st in s.closing(None)] == [19]
    assert s.closing(None) == []


def test_the_last_state_is_logged_again_at_the_final_clock_tick() -> None:
    # States come on change: an arm that stopped at tick 30 is still there at tick 500.
    s: StateStream[pb.RobotState] = StateStream()
    assert s.offer(_state(30, 0.0), every=8)
    s.logged(_state(30, 0.0))
    (held,) = s.closing((500, 500 / 240))
    assert held.header.tick == 500 and held.header.sim_time == 500 / 240
    assert held.tcp_speed == 0.0 and held.robot == "r1"
    assert s.last is not None and s.last.header.tick == 30  # the original is not changed


def test_nothing_is_repeated_when_the_last_state_is_from_the_final_tick() -> None:
    s: StateStream[pb.RobotState] = StateStream()
    assert s.offer(_state(0, 0.2), every=8)
    s.logged(_state(0, 0.2))
    assert not s.offer(_state(5, 0.3), every=8)
    out = s.closing((5, 5 / 240))
    assert [st.header.tick for st in out] == [5]  # the held-back one, not twice
