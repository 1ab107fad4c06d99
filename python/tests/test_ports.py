"""hrc.ports: no two processes of the machine are given the same port while both hold it."""

from __future__ import annotations

import socket
import subprocess
import sys

from hrc import ports

PICKER = """
import sys
from hrc.ports import free_port
print(free_port(), flush=True)
sys.stdin.read()  # hold the reservation until the test is done
"""


def test_two_hundred_parallel_picks_never_collide() -> None:
    # 200 processes pick at once and hold what they got; without the reservation, 200 picks
    # among the 12,000 ports below the ephemeral range collide with a probability of about 80 %
    # (the birthday bound), since a pick's test bind is closed at once.
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", PICKER],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        for _ in range(200)
    ]
    try:
        got = [int(p.stdout.readline()) for p in procs]  # type: ignore[union-attr]
    finally:
        for p in procs:
            p.communicate(timeout=60)  # closes stdin: the picker ends
    assert len(got) == 200
    assert len(set(got)) == 200, sorted(p for p in got if got.count(p) > 1)


def test_a_pick_skips_ports_this_process_holds_and_release_frees_them() -> None:
    a, b = ports.free_port(), ports.free_port()
    assert a != b
    assert not ports._reserve(a)
    ports.release_port(a)
    assert ports._reserve(a)  # free again (in this process and, by its lock, in others)
    ports.release_port(a)
    ports.release_port(b)


def test_a_port_in_use_is_never_picked() -> None:
    taken: list[socket.socket] = []
    try:
        # occupy a band of ports, then pick many times: none of the band is returned
        for port in ports.pick_range()[:200]:
            s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                s.close()
                continue
            taken.append(s)
        busy = {s.getsockname()[1] for s in taken}
        picked = [ports.free_port() for _ in range(300)]
        assert not busy & set(picked)
        for p in picked:
            ports.release_port(p)
    finally:
        for s in taken:
            s.close()
