"""Two real Zenoh sessions on loopback, one listening and one connecting."""

from __future__ import annotations

import time
import uuid
from collections.abc import Iterator

import pytest

from hrc.bus import Bus, BusConfig
from hrc.ports import free_port  # tests import it from here too


@pytest.fixture
def session_id() -> str:
    return f"u{uuid.uuid4().hex[:8]}"


@pytest.fixture
def endpoint() -> str:
    return f"tcp/127.0.0.1:{free_port()}"


@pytest.fixture
def bus_pair(session_id: str, endpoint: str) -> Iterator[tuple[Bus, Bus]]:
    a = Bus(BusConfig(session=session_id, listen=[endpoint]), "alpha")
    b = Bus(BusConfig(session=session_id, connect=[endpoint]), "beta")
    time.sleep(0.3)  # let the link come up
    try:
        yield a, b
    finally:
        b.close()
        a.close()


def wait_until(pred, timeout: float = 5.0, step: float = 0.01) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if pred():
            return True
        time.sleep(step)
    return pred()
