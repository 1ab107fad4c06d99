"""Garbage on every subscribed key of every service is counted and logged; ticking goes on."""

from __future__ import annotations

import time

import zenoh

from hrc.services import names

from .conftest import wait_until

SERVICES = names()
GARBAGE = b"\xff" * 12  # an unterminated varint: no message type can decode it


def _concrete(key: str) -> str:
    return key.replace("**", "x").replace("*", "r1")


def test_garbage_everywhere_is_counted_and_the_run_keeps_ticking(trial_factory) -> None:
    trial = trial_factory()
    trial.wait_ticking()
    bus = trial.bus("garbler")
    subscribed = {name: list(trial.stats(name).subscribed) for name in SERVICES}
    for name, keys in subscribed.items():
        assert keys, f"{name} reports no subscriptions"
    targets = sorted({_concrete(k) for keys in subscribed.values() for k in keys})
    before = trial.stats("orchestrator").last_tick
    for key in targets:
        bus.session.put(
            key, GARBAGE, attachment=b"garbler", congestion_control=zenoh.CongestionControl.BLOCK
        )

    def all_counted() -> bool:
        for name, keys in subscribed.items():
            errors = trial.stats(name).decode_errors
            for k in keys:
                if errors.get(_concrete(k), 0) < 1:
                    return False
        return True

    assert wait_until(all_counted, 20, 0.2), {
        n: dict(trial.stats(n).decode_errors) for n in SERVICES
    }
    time.sleep(0.5)
    assert trial.stats("orchestrator").last_tick > before  # still ticking
    trial.stop()
    code, _, err = trial.communicate()
    assert code == 0, err
    for name in SERVICES:
        log = (trial.out / "services" / f"{name}.log").read_text(errors="replace")
        assert "garbler" in log, f"{name} did not log the sender of the garbage"
