"""Garbage on every subscribed key of every service is counted and logged; ticking goes on.

The garbage comes with the credentials of a user allowed to put on the key (hrc.bus.access): from
anyone else the router drops it before any service sees it (tests/test_intruders.py). Keys only
physics, the router itself, may publish cannot be reached from outside at all."""

from __future__ import annotations

import time
from pathlib import Path

import zenoh

from hrc.bus import Bus, Keys, access
from hrc.bus.bus import MAX_STANDARD_BYTES
from hrc.service_table import CLOCK_MASTER, names
from hrc.wire import pb

from .conftest import wait_until

SERVICES = names()
GARBAGE = b"\xff" * 12  # an unterminated varint: no message type can decode it


def _concrete(key: str) -> str:
    """A key a subscription on ``key`` receives: a robot's, the orchestrator's stop, ik_cpp's
    ack (every key a put may reach has an owner: access control denies all others)."""
    if key.endswith("/run/control/*"):
        return key.replace("*", "orchestrator")
    if key.endswith("/clock/ack/*"):
        return key.replace("*", "ik_cpp")
    return key.replace("**", "x").replace("*", "r1")


def test_garbage_everywhere_is_counted_and_the_run_keeps_ticking(trial_factory) -> None:
    trial = trial_factory()
    trial.wait_ticking()
    subscribed = {name: list(trial.stats(name).subscribed) for name in SERVICES}
    for name, keys in subscribed.items():
        assert keys, f"{name} reports no subscriptions"
    targets = sorted({_concrete(k) for keys in subscribed.values() for k in keys})
    table = access.publishers(Keys(trial.session))
    folder = trial.bus_config().config_file
    assert folder is not None
    buses: dict[str, Bus] = {}
    reachable: set[str] = set()
    before = trial.stats("orchestrator").last_tick
    try:
        for key in targets:
            allowed = [
                sorted(who - {CLOCK_MASTER})
                for expr, who in table.items()
                if zenoh.KeyExpr(expr).intersects(zenoh.KeyExpr(key))
            ]
            user = allowed[0][0] if allowed and allowed[0] else None
            if allowed and user is None:
                continue  # physics's own key: nobody may put on it from outside
            assert user is not None, f"{key}: a key nobody may put on, yet subscribed to"
            if user not in buses:
                cfg = trial.bus_config()
                cfg.config_file = str(Path(folder).with_name(f"{user}.json5"))
                buses[user] = Bus(cfg, "garbler")
            buses[user].session.put(
                key,
                GARBAGE,
                attachment=b"garbler",
                congestion_control=zenoh.CongestionControl.BLOCK,
            )
            reachable.add(key)

        def all_counted() -> bool:
            for name, keys in subscribed.items():
                errors = trial.stats(name).decode_errors
                for k in keys:
                    if _concrete(k) in reachable and errors.get(_concrete(k), 0) < 1:
                        return False
            return True

        assert wait_until(all_counted, 20, 0.2), [
            (n, k)
            for n, ks in subscribed.items()
            for k in ks
            if _concrete(k) in reachable and trial.stats(n).decode_errors.get(_concrete(k), 0) < 1
        ]
    finally:
        for b in buses.values():
            b.close()
    # every service got some: each listens on at least one key others publish
    for name, keys in subscribed.items():
        assert any(_concrete(k) in reachable for k in keys), (name, keys)

    time.sleep(0.5)
    assert trial.stats("orchestrator").last_tick > before  # still ticking
    trial.stop()
    code, _, err = trial.communicate()
    assert code == 0, err
    for name in SERVICES:
        log = (trial.out / "services" / f"{name}.log").read_text(errors="replace")
        assert "garbler" in log, f"{name} did not log the sender of the garbage"


def test_a_message_above_the_size_limit_is_refused_counted_and_named(trial_factory) -> None:
    """Well-formed 20 MiB messages from their keys' owners' credentials (no service sends one:
    a put refuses above MAX_STANDARD_BYTES), to physics (Python) and ik_cpp (C++): each is
    refused unread, counted in the receiver's stats and logged with its size; the run goes on
    (such a message was taken, counted nowhere)."""
    trial = trial_factory()
    trial.wait_ticking()
    keys = Keys(trial.session)
    human, command = pb.HumanState(), pb.RobotCommand(robot="r1")
    folder = trial.bus_config().config_file
    assert folder is not None
    before = trial.stats("orchestrator").last_tick
    sent: dict[str, int] = {}  # receiver -> size
    for receiver, owner, key, msg in (
        ("physics", "human_input", keys.human_state(), human),
        ("ik_cpp", "orchestrator", keys.robot_command("r1"), command),
    ):
        msg.header.session, msg.header.sender = trial.session, "x" * (20 * 1024 * 1024)
        payload = msg.SerializeToString()
        assert len(payload) > MAX_STANDARD_BYTES
        cfg = trial.bus_config()
        cfg.config_file = str(Path(folder).with_name(f"{owner}.json5"))
        with Bus(cfg, "oversize") as bus:
            # (blocking: with Zenoh's default, drop, a loaded machine's full queue drops some of
            # its 320 fragments, and with them the message)
            bus.session.put(
                key,
                payload,
                attachment=b"oversize",
                congestion_control=zenoh.CongestionControl.BLOCK,
            )
            sent[receiver] = len(payload)
            counted = wait_until(
                lambda r=receiver, k=key: trial.stats(r).decode_errors.get(k, 0) >= 1, 60
            )
        assert counted, trial.stats(receiver)
    assert wait_until(lambda: trial.stats("orchestrator").last_tick > before, 10)  # ticking
    trial.stop()
    code, _, err = trial.communicate()
    assert code == 0, err[-3000:]
    for receiver, size in sent.items():
        log = (trial.out / "services" / f"{receiver}.log").read_text(errors="replace")
        said = [line for line in log.splitlines() if "oversize" in line]
        assert said and f"{size} bytes, above the" in said[0], (receiver, said)
