"""The logger, an observer, stays on Zenoh's standard transport even when a deployment asks every
service for the low-latency one (HRC_ZENOH_LOWLATENCY): only there may the router drop what a
stopped logger cannot take, instead of holding the clock. A participant keeps what it asks."""

from __future__ import annotations

import pytest

from hrc.service import bus_config, parse_args

from hrc_logger.service import LoggerService


@pytest.mark.parametrize("how", ["flag", "environment"])
def test_the_logger_never_takes_the_low_latency_transport(
    how: str, monkeypatch: pytest.MonkeyPatch, tmp_path
) -> None:
    argv = ["--out", str(tmp_path)]
    if how == "flag":
        argv.append("--zenoh-lowlatency")
    else:
        monkeypatch.setenv("HRC_ZENOH_LOWLATENCY", "1")
    args = parse_args(LoggerService, argv)
    assert args.zenoh_lowlatency  # asked for ...
    assert bus_config(LoggerService, args).lowlatency is False  # ... and not given


def test_a_participant_keeps_the_low_latency_transport(monkeypatch: pytest.MonkeyPatch) -> None:
    from hrc_human_input.service import HumanInputService

    monkeypatch.setenv("HRC_ZENOH_LOWLATENCY", "1")
    args = parse_args(HumanInputService, [])
    assert bus_config(HumanInputService, args).lowlatency is True
