"""How fast sessions come up at a trial's start (the router and the clients that wait for it),
and how their large messages travel."""

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
    # retries every 50 ms at most (it was 100 ms doubling: the next try came ~0.7 s later here);
    # the router's own open is inside the figure, and a loaded machine stretches it
    took = connected[0] - listening
    assert took < 0.5, f"the client connected {took:.2f} s after the router began to listen"


def test_a_router_that_scouts_and_connects_to_nothing_does_not_wait_to_open(tmp_path) -> None:
    """Zenoh's router waits scouting/delay (500 ms by default) in its open for the peers it
    scouts or connects to: a trial's physics has neither, and that was half a second of every
    trial's start. A router that connects somewhere, or a file that sets a delay, keeps it."""
    alone = BusConfig(mode="router", listen=["tcp/127.0.0.1:0"]).to_zenoh()
    assert alone.get_json("scouting/delay") == "0"
    linked = BusConfig(mode="router", connect=["tcp/127.0.0.1:7447"]).to_zenoh()
    assert linked.get_json("scouting/delay") == "null"
    peer = BusConfig(mode="peer").to_zenoh()  # (a peer waits only when it has somewhere to go)
    assert peer.get_json("scouting/delay") == "null"
    own = tmp_path / "z.json5"
    own.write_text("{ scouting: { delay: 200 } }")
    assert (
        BusConfig(mode="router", config_file=str(own)).to_zenoh().get_json("scouting/delay")
        == "200"
    )
    t0 = time.monotonic()
    zenoh.open(alone).close()
    print(f"a lone router opened in {time.monotonic() - t0:.3f} s")


def _shared_memory_maps() -> list[str]:
    with open("/proc/self/maps") as maps:
        return sorted({ln.split()[-1] for ln in maps if ln.rstrip().endswith(".zenoh")})


def test_large_messages_go_over_the_link_and_leave_nothing_in_dev_shm() -> None:
    """Zenoh would put a message of 3 KiB or more (a 32-tick state batch) into shared memory:
    segments that outlived every trial in /dev/shm (49 MB of memory a thesis trial), at the
    receivers of the batches the bus lost on loaded machines. The services turn it off."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = zenoh.open(BusConfig(mode="router", listen=[endpoint]).to_zenoh())
    client = zenoh.open(BusConfig(mode="client", connect=[endpoint], listen=[]).to_zenoh())
    got: list[bytes] = []
    arrived = threading.Event()

    def on_sample(sample: zenoh.Sample) -> None:
        got.append(sample.payload.to_bytes())
        arrived.set()

    try:
        sub = client.declare_subscriber("shm/test", on_sample)
        payload = bytes(range(256)) * 80  # 20 KiB: above Zenoh's 3 KiB threshold
        deadline = time.monotonic() + 30
        while not arrived.is_set() and time.monotonic() < deadline:  # until the route is up
            router.put("shm/test", payload)
            arrived.wait(0.1)
        assert got and got[0] == payload, "the large message did not arrive whole"
        assert _shared_memory_maps() == [], "Zenoh mapped shared memory for the message"
        sub.undeclare()
    finally:
        client.close()
        router.close()
