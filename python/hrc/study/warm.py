"""A sweep's warm worker: one process that has imported what ``hrc run`` needs and starts each
trial by forking itself, instead of a new interpreter per trial.

A trial's ``hrc run`` spends ~0.4 CPU-s starting Python and importing numpy, pydantic and the
scenario models, protobuf and zenoh before it does anything (and its services are forked from it,
so they share those imports: ``hrc.trial.prefork``). A sweep of thousands of trials paid that for
every one. The warm worker pays it once per sweep: each trial is a fork of a process that has
only imported modules, run exactly as ``python -m hrc.cli.main run ...`` would run it (the same
command line, environment, working folder, stdout and stderr, exit code), so a trial's events,
metrics and logs are what a new interpreter gives, by construction.

Protocol (one Unix-socket connection per trial): the caller sends its stdout and stderr files
(SCM_RIGHTS) with an 8-byte length, then the JSON request (argv, cwd, env, umask); the worker forks
and answers ``{"pid": N}`` (a session leader: the caller stops the trial with ``killpg``), then
``{"exit": code, "cpu_s": ...}`` when the trial has ended (its CPU with its services', from
wait4). A worker that ends first closes the connection: the trial ends with it (``hrc run``
stops when its parent dies) and the caller reports that. The worker ends when the caller's end
of its stdin closes (the sweep ended, however).

Forking is only safe from a process with one thread: a worker that finds more after its imports
says so and exits, and the sweep starts its trials as new interpreters instead.

This module is the caller's side; the worker is ``hrc.cli.warm_worker`` (it imports the command
line's modules, which stand above the study's).
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import selectors
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import IO

from hrc.priority import carry_niceness
from hrc.trial.prefork import START_ENV as SERVICE_START_ENV

log = logging.getLogger(__name__)

READY = "warm worker: ready"
HEADER = struct.Struct("!Q")
START_TIMEOUT_S = 60.0  # the worker's imports; a loaded machine takes seconds
ANSWER_TIMEOUT_S = 30.0  # a fork's answer (its pid)
MODULE = "hrc.cli.main"  # what a trial runs
WORKER_MODULE = "hrc.cli.warm_worker"  # the worker itself (it imports what MODULE needs)


# "exec": trials start as new interpreters, not from a warm worker (as with HRC_SERVICE_START)
START_ENV = "HRC_SWEEP_START"


class WarmError(Exception):
    """The warm worker could not start, or a trial could not be started through it."""


# ------------------------------------------------------------------ caller's side
def _read_line(conn: socket.socket, buf: bytearray, deadline: float | None) -> bytes | None:
    """One line from ``conn`` (None at EOF); TimeoutError past ``deadline`` (monotonic)."""
    while b"\n" not in buf:
        if deadline is not None:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError
            conn.settimeout(left)
        else:
            conn.settimeout(None)
        chunk = conn.recv(4096)  # (TimeoutError past the deadline: socket.timeout is one)
        if not chunk:
            return None
        buf += chunk
    line, _, rest = bytes(buf).partition(b"\n")
    buf[:] = rest
    return line


class WarmProcess:
    """A trial started through the warm worker, as run_job handles it: the part of
    ``subprocess.Popen``'s interface it uses (``pid``, ``returncode``, ``wait``,
    ``communicate``)."""

    def __init__(self, argv: list[str], conn: socket.socket, out: IO[bytes], err: IO[bytes]):
        self.args = argv
        self._conn = conn
        self._out, self._err = out, err
        self._buf = bytearray()
        self.returncode: int | None = None
        self.cpu_s = 0.0  # the trial's CPU with its services' (once it has ended)
        self.lost = ""  # why the trial could not be followed to its end (the worker ended)
        try:
            line = _read_line(conn, self._buf, time.monotonic() + ANSWER_TIMEOUT_S)
        except TimeoutError:
            line = None
        if line is None:
            self.close()
            raise WarmError("the warm worker did not start the trial (no answer)")
        self.pid = int(json.loads(line)["pid"])

    def wait(self, timeout: float | None = None) -> int:
        if self.returncode is not None:
            return self.returncode
        deadline = None if timeout is None else time.monotonic() + timeout
        try:
            line = _read_line(self._conn, self._buf, deadline)
        except TimeoutError:
            raise subprocess.TimeoutExpired(self.args, timeout or 0.0) from None
        if line is None:  # the worker ended: its trials end with it (parent-death signal)
            self.lost = "hrc sweep's warm worker ended during the trial"
            self.returncode = -int(signal.SIGTERM)
        else:
            answer = json.loads(line)
            self.returncode = int(answer["exit"])
            self.cpu_s = float(answer["cpu_s"])
        self._conn.close()
        return self.returncode

    def communicate(self, timeout: float | None = None) -> tuple[str, str]:
        """Waits for the end (TimeoutExpired past ``timeout``), then its stdout and stderr."""
        self.wait(timeout)
        out, err = (self._read(f) for f in (self._out, self._err))
        if self.lost:
            err += f"\n{self.lost}\n"
        return out, err

    @staticmethod
    def _read(f: IO[bytes]) -> str:
        if f.closed:
            return ""
        f.seek(0)
        text = f.read().decode("utf-8", errors="replace")
        f.close()
        return text

    def close(self) -> None:
        for f in (self._conn, self._out, self._err):
            with contextlib.suppress(OSError):
                f.close()


class WarmStarter:
    """The warm worker of one sweep (a context manager): :meth:`popen` starts a trial through
    it. Thread-safe: each trial has a connection of its own."""

    def __init__(self) -> None:
        self._dir = tempfile.TemporaryDirectory(prefix="hrc-warm-")
        self.socket_path = str(Path(self._dir.name) / "warm.sock")
        env = dict(os.environ, OPENBLAS_NUM_THREADS=os.environ.get("OPENBLAS_NUM_THREADS", "1"))
        # Its own session: a Ctrl-C at the terminal reaches the sweep, which stops the trials
        # itself (stop_running); the worker leaves when its stdin closes.
        self._proc = subprocess.Popen(
            [sys.executable, "-m", WORKER_MODULE, self.socket_path],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,  # its first line says it is ready
            env=env,
            start_new_session=True,
        )
        carry_niceness(self._proc.pid)  # `nice hrc sweep`: its trials' `hrc run` are nice too
        self.cpu_s = 0.0  # the worker's CPU with its trials' (after close)
        assert self._proc.stdout is not None
        line = _first_line(self._proc.stdout, START_TIMEOUT_S)
        if line != READY:
            self.close()
            raise WarmError(f"the warm worker did not start: {line or 'no word from it'}")

    def popen(self, argv: list[str], cwd: str | None = None) -> WarmProcess:
        """Starts ``argv`` (``python -m hrc.cli.main ...``) as a fork of the worker, with this
        process's environment and working folder (or ``cwd``)."""
        if MODULE not in argv:
            raise WarmError(f"the warm worker runs {MODULE} only, not {argv}")
        # what a new process started from here inherits (the file-creation mask: participant
        # data is private, hrc.privacy)
        here = {
            "argv": argv,
            "cwd": cwd or os.getcwd(),
            "env": dict(os.environ),
            "umask": _umask(),
        }
        request = json.dumps(here).encode()
        out = tempfile.TemporaryFile()
        err = tempfile.TemporaryFile()
        conn = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            conn.settimeout(ANSWER_TIMEOUT_S)
            conn.connect(self.socket_path)
            socket.send_fds(conn, [HEADER.pack(len(request))], [out.fileno(), err.fileno()])
            conn.sendall(request)
        except OSError as exc:
            for f in (conn, out, err):
                f.close()
            raise WarmError(f"the warm worker cannot be reached: {exc}") from exc
        return WarmProcess(argv, conn, out, err)

    def alive(self) -> bool:
        return self._proc.poll() is None

    def close(self) -> None:
        """Ends the worker (its stdin closes; trials still running end with it)."""
        if self._proc.stdin is not None:
            with contextlib.suppress(OSError):
                self._proc.stdin.close()
        try:
            _pid, _status, ru = os.wait4(self._proc.pid, 0)
            self._proc.returncode = os.waitstatus_to_exitcode(_status)
            self.cpu_s = ru.ru_utime + ru.ru_stime
        except ChildProcessError:
            pass
        if self._proc.stdout is not None:
            self._proc.stdout.close()
        self._dir.cleanup()

    def __enter__(self) -> WarmStarter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _umask() -> int:
    """This process's file-creation mask, read without setting it (os.umask sets it, for every
    thread at once)."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    raise WarmError("no Umask in /proc/self/status")


def _first_line(stream: IO[bytes], timeout_s: float) -> str:
    sel = selectors.DefaultSelector()
    sel.register(stream, selectors.EVENT_READ)
    buf = b""
    deadline = time.monotonic() + timeout_s
    try:
        while b"\n" not in buf:
            left = deadline - time.monotonic()
            if left <= 0 or not sel.select(left):
                return buf.decode(errors="replace").strip() or f"no word in {timeout_s:g} s"
            chunk = os.read(stream.fileno(), 4096)
            if not chunk:
                break
            buf += chunk
    finally:
        sel.close()
    return buf.decode(errors="replace").split("\n", 1)[0].strip()


def start_worker() -> WarmStarter | None:
    """A warm worker, or None where it cannot start or is not wanted (``HRC_SWEEP_START=exec``,
    or ``HRC_SERVICE_START=exec``): the trials then start as new interpreters, with the same
    outputs and 0.2-0.4 CPU-s more each."""
    if "exec" in (os.environ.get(START_ENV), os.environ.get(SERVICE_START_ENV)):
        return None
    if not sys.platform.startswith("linux"):
        return None
    try:
        return WarmStarter()
    except (WarmError, OSError) as exc:
        log.warning("%s: each trial starts as a new interpreter", exc)
        return None
