"""Free loopback TCP ports that no two processes of this machine are given at once.

A trial's physics listens on a port ``hrc run`` chose before starting it. Testing a port with
``bind`` and closing it leaves a window until physics binds it, in which another trial (a sweep
runs several at a time) could test and choose the same port. So a port is also reserved: a POSIX
record lock on its byte of one file that every process picking ports shares
(``/tmp/hrc-ports.lock``). Another process's pick skips it while the lock is held; the kernel
drops the lock when the holder ends, however it ends (a SIGKILL too), so nothing goes stale.
Within one process a set does the same (record locks never conflict with their own process).

A pick holds its reservation until :func:`release_port` or the end of the process.
"""

from __future__ import annotations

import contextlib
import fcntl
import logging
import os
import random
import socket
import threading
from pathlib import Path

log = logging.getLogger(__name__)

LOCK_FILE = Path("/tmp/hrc-ports.lock")
ATTEMPTS = 400

_lock = threading.Lock()
_held: set[int] = set()
_fd: int | None = None


def _ephemeral_range() -> tuple[int, int]:
    try:
        with open("/proc/sys/net/ipv4/ip_local_port_range") as f:
            lo, hi = (int(x) for x in f.read().split())
            return lo, hi
    except (OSError, ValueError):
        return 32768, 60999


def pick_range() -> range:
    """The ports picks come from: the 12,000 below the ephemeral range (see free_port)."""
    lo, _hi = _ephemeral_range()
    return range(max(1024, lo - 12000), lo)


def _lock_fd() -> int | None:
    """The shared lock file, opened once per process (closing any descriptor of it would drop
    all of this process's locks on it); None where it cannot be opened."""
    global _fd
    if _fd is None:
        try:
            _fd = os.open(LOCK_FILE, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
            # other users' trials share it (the umask took bits); another user's is shared
            with contextlib.suppress(PermissionError):
                os.fchmod(_fd, 0o666)
        except OSError as exc:
            log.warning("ports are not reserved across processes (%s: %s)", LOCK_FILE, exc)
            return None
    return _fd


def _reserve(port: int) -> bool:
    """Takes ``port``'s reservation; False if another process (or this one) holds it."""
    if port in _held:
        return False
    fd = _lock_fd()
    if fd is not None:
        try:
            fcntl.lockf(fd, fcntl.LOCK_EX | fcntl.LOCK_NB, 1, port)
        except OSError:
            return False
    _held.add(port)
    return True


def _unreserve(port: int) -> None:
    if port in _held:
        _held.discard(port)
        if _fd is not None:
            fcntl.lockf(_fd, fcntl.LOCK_UN, 1, port)


def release_port(port: int) -> None:
    """Ends this process's reservation of ``port`` (its user has bound it, or is done)."""
    with _lock:
        _unreserve(port)


def _bindable(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


def free_port() -> int:
    """A free loopback port below the ephemeral range, reserved for this process.

    Below the ephemeral range because an outgoing connection of any process could be given a
    port from that range between our pick and the bind; ports below it are only ever taken by an
    explicit bind.
    """
    candidates = pick_range()
    rng = random.Random()
    with _lock:
        for _ in range(ATTEMPTS):
            port = rng.choice(candidates)
            if not _reserve(port):
                continue
            if _bindable(port):
                return port
            _unreserve(port)
    raise OSError(f"no free loopback port below {candidates.stop} after {ATTEMPTS} tries")
