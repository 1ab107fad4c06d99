"""How fast sessions come up at a trial's start: the router and the clients that wait for it."""

from __future__ import annotations

import threading
import time

import zenoh

from hrc.bus import BusConfig
from hrc.ports import free_port


def test_a_client_started_first_connects_soon_after_the_router_listens() -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    connected: list[float] = []

    def client() -> None:
        s = zenoh.open(BusConfig(mode="client", connect=[endpoint], listen=[]).to_zenoh())
        connected.append(time.monotonic())
        s.close()

    t = threading.Thread(target=client)
    t.start()
    time.sleep(0.8)  # the client has tried and retried by now
    listening = time.monotonic()  # the router binds first thing in its open
    router = zenoh.open(BusConfig(mode="router", listen=[endpoint]).to_zenoh())
    t.join(10)
    router.close()
    assert connected, "the client never connected"
    # retries every 50 ms at most (it was 100 ms doubling: the next try came ~0.7 s later here)
    assert connected[0] - listening < 0.3
