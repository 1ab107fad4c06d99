import pytest

from hrc.bus import Keys


def test_every_key_lives_under_the_session_prefix() -> None:
    k = Keys("s1")
    built = [
        k.clock(),
        k.clock_ack("ik_cpp"),
        k.run_control("orchestrator"),
        k.run_controls(),
        k.run_end(),
        k.alive("physics"),
        k.stats("logger"),
        k.scenario(),
        k.robot_command("r1"),
        k.robot_state("r2"),
        k.robot_reach(),
        k.human_state(),
        k.world_objects(),
        k.world_contacts(),
        k.world_commands(),
        k.task_events(),
        k.task_indicators(),
        k.task_metrics(),
    ]
    assert all(key.startswith("hrc/s1/") for key in built)
    assert len(set(built)) == len(built)
    assert k.robot_command("r1") == "hrc/s1/robot/r1/command"
    assert k.clock_ack("orchestrator") == "hrc/s1/clock/ack/orchestrator"


@pytest.mark.parametrize("bad", ["", "a/b", "*", "**", "a b", "x$", "é"])
def test_ids_that_would_widen_or_break_a_key_are_refused(bad: str) -> None:
    with pytest.raises(ValueError, match="invalid"):
        Keys(bad)
    with pytest.raises(ValueError, match="robot id"):
        Keys("ok").robot_state(bad)


def test_segments_are_parsed_back() -> None:
    k = Keys("s")
    assert k.last_segment(k.alive("human_input")) == "human_input"
    assert k.robot_of(k.robot_state("r7")) == "r7"
