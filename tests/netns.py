"""Hosts for the tests: Linux network namespaces joined by veth pairs (``ip netns``, root only).

Each namespace is a host with its own loopback and its own addresses; a veth pair is the cable
between two of them, and ``ip link set ... down`` pulls it. Addresses are private ones inside
the namespaces made here; nothing here touches the machine's own network, and everything is
removed on exit (the processes still inside first).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import time
from pathlib import Path
from typing import IO

import pytest

SUBNET = "10.213"  # 10.213.<link>.1 and .2, one /30 per cable


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["ip", *args], capture_output=True, text=True, check=check, timeout=30)


def skip_unless_netns() -> None:
    """Skips the test, saying why, where namespaces cannot be made."""
    if shutil.which("ip") is None:
        pytest.skip("needs iproute2's ip to make network namespaces (apt-get install iproute2)")
    if os.geteuid() != 0:
        pytest.skip("needs root to make network namespaces (ip netns): run the tests as root")


class Hosts:
    """Namespaces named ``<tag><host>``; use as a context manager."""

    def __init__(self, tag: str, hosts: list[str], logs: Path) -> None:
        self.ns = {h: f"{tag}{h}" for h in hosts}
        self.logs = logs
        self.procs: list[subprocess.Popen[bytes]] = []
        self._files: list[IO[bytes]] = []
        self._links: dict[tuple[str, str], str] = {}  # (a, b) -> a's end of the cable
        self._made: list[str] = []

    def __enter__(self) -> Hosts:
        skip_unless_netns()
        self.logs.mkdir(parents=True, exist_ok=True)
        for ns in self.ns.values():
            made = _ip("netns", "add", ns, check=False)
            if made.returncode != 0:
                self.close()
                pytest.skip(f"cannot make a network namespace here: {made.stderr.strip()}")
            self._made.append(ns)
            _ip("-n", ns, "link", "set", "lo", "up")
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def cable(self, a: str, b: str) -> tuple[str, str]:
        """A cable between hosts ``a`` and ``b``: returns (a's address, b's address). Each host
        routes every other address through its first cable's far end."""
        n = len(self._links) + 1
        end_a, end_b = f"{self.ns[a]}v{n}", f"{self.ns[b]}v{n}"
        _ip("link", "add", end_a, "type", "veth", "peer", "name", end_b)
        addr = {a: f"{SUBNET}.{n}.1", b: f"{SUBNET}.{n}.2"}
        for host, end in ((a, end_a), (b, end_b)):
            ns = self.ns[host]
            _ip("link", "set", end, "netns", ns)
            _ip("-n", ns, "addr", "add", f"{addr[host]}/30", "dev", end)
            _ip("-n", ns, "link", "set", end, "up")
        for host, other in ((a, b), (b, a)):
            if not any(host in pair for pair in self._links):
                _ip("-n", self.ns[host], "route", "add", "default", "via", addr[other])
        self._links[(a, b)] = end_a
        return addr[a], addr[b]

    def cut(self, a: str, b: str) -> None:
        """Pulls the cable between ``a`` and ``b`` (its end on ``a`` goes down)."""
        _ip("-n", self.ns[a], "link", "set", self._links[(a, b)], "down")

    def start(self, host: str, name: str, argv: list[str]) -> subprocess.Popen[bytes]:
        """``argv`` on ``host``, its output in ``<logs>/<name>.log``."""
        out = (self.logs / f"{name}.log").open("wb")
        self._files.append(out)
        proc = subprocess.Popen(
            ["ip", "netns", "exec", self.ns[host], *argv],  # ip execs argv: the pid is argv's
            stdout=out,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            start_new_session=True,
        )
        self.procs.append(proc)
        return proc

    def log(self, name: str) -> str:
        return (self.logs / f"{name}.log").read_text(errors="replace")

    def pids(self, host: str) -> list[int]:
        """Every process inside ``host``'s namespace."""
        got = _ip("netns", "pids", self.ns[host], check=False)
        return [int(p) for p in got.stdout.split()]

    def close(self) -> None:
        for p in self.procs:
            if p.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(p.pid, signal.SIGKILL)
        for ns in self._made:  # whatever else is still inside
            for pid in [int(p) for p in _ip("netns", "pids", ns, check=False).stdout.split()]:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
        for p in self.procs:
            with contextlib.suppress(subprocess.TimeoutExpired):
                p.wait(10)
        deadline = time.monotonic() + 10
        for ns in self._made:
            while _ip("netns", "del", ns, check=False).returncode != 0:
                if time.monotonic() > deadline:
                    break
                time.sleep(0.1)
        self._made.clear()
        for f in self._files:
            f.close()
        self._files.clear()
