"""Start a Python service by forking ``hrc run`` instead of starting a new interpreter.

A new interpreter costs each Python service ~0.2 CPU-s before it does anything: Python itself,
numpy, pydantic and the scenario models, protobuf, zenoh's bindings. ``hrc run`` has imported all
of these already (it checks the scenario), so a forked child starts with them in memory, shared
copy-on-write, and only imports what is its own (pybullet, rerun). Over a trial's four Python
services that is most of the start-up CPU, the largest fixed cost of a short trial.

The child is made to look and behave as ``python -m <module> ARGS`` would: same command line in
``ps`` and /proc (setproctitle), its log file on stdout and stderr, unbuffered, a fresh logging
configuration, default signal handlers, no exit handlers of the parent, the module run as
``__main__``; its exit code is the module's (``SystemExit``), 1 for an uncaught exception, and an
uncaught ``KeyboardInterrupt`` ends it by SIGINT as it would end an interpreter.

Forking is only safe from a process with one thread (a lock held by another thread at the fork
stays held in the child forever): :func:`can_fork` says whether this process may. Otherwise, or
with ``HRC_SERVICE_START=exec`` (or ``HRC_PROFILE_DIR``, whose profiler hooks a new interpreter's
start-up), services start as new interpreters.
"""

from __future__ import annotations

import atexit
import contextlib
import gc
import io
import logging
import os
import runpy
import signal
import sys
import threading
import traceback
from collections.abc import Callable
from typing import NoReturn

from setproctitle import setproctitle

from hrc.service import flush_output

START_ENV = "HRC_SERVICE_START"  # "exec": always a new interpreter; "fork" or unset: fork if safe


def can_fork() -> bool:
    """This process may start services by forking: Linux, one thread, not told otherwise."""
    if os.environ.get(START_ENV, "fork") == "exec" or os.environ.get("HRC_PROFILE_DIR"):
        return False
    if not sys.platform.startswith("linux") or threading.active_count() != 1:
        return False
    try:
        return len(os.listdir("/proc/self/task")) == 1  # also threads Python does not know of
    except OSError:
        return False


class ForkedProcess:
    """A forked service as ``hrc run``'s service group handles it: the part of
    ``subprocess.Popen``'s interface it uses (``pid``, ``returncode``, ``poll``, ``wait``,
    ``send_signal``, ``kill``)."""

    def __init__(self, pid: int) -> None:
        self.pid = pid
        self.returncode: int | None = None

    def _wait(self, flags: int) -> int | None:
        if self.returncode is None:
            try:
                pid, status = os.waitpid(self.pid, flags)
            except ChildProcessError:  # reaped elsewhere (hrc run reaps with wait4 for its CPU)
                return self.returncode
            if pid:
                self.returncode = os.waitstatus_to_exitcode(status)
        return self.returncode

    def poll(self) -> int | None:
        return self._wait(os.WNOHANG)

    def wait(self) -> int | None:
        return self._wait(0)

    def send_signal(self, sig: int) -> None:
        if self.returncode is None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(self.pid, sig)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)


def fork_service(
    module: str,
    argv: list[str],
    log_fd: int,
    env: dict[str, str],
    in_child: Callable[[], None],
) -> ForkedProcess:
    """Forks; the child runs ``module`` as ``__main__`` with ``argv`` (the whole command line
    it would have had, ``python -m module`` included) and never returns. ``in_child`` runs first
    in the child (``hrc run``'s pre-exec: parent-death signal, signal mask)."""
    flush_output()  # or what is buffered would be written twice
    pid = os.fork()
    if pid == 0:
        child_main(module, argv, log_fd, env, in_child)
    return ForkedProcess(pid)


def _exit_code(exc: SystemExit) -> int:
    if exc.code is None:
        return 0
    if isinstance(exc.code, int):
        return exc.code
    print(exc.code, file=sys.stderr)  # as the interpreter does with sys.exit("message")
    return 1


def child_main(
    module: str,
    argv: list[str],
    log_fd: int,
    env: dict[str, str],
    in_child: Callable[[], None],
    err_fd: int | None = None,
) -> NoReturn:
    """The forked child's life: ``log_fd`` becomes its stdout, and its stderr too unless
    ``err_fd`` is given (the caller's descriptors, closed here once copied)."""
    code = 1
    try:
        # First: it needs the process's environment strings as they were at its start.
        setproctitle(" ".join(argv))
        # What an interpreter gets from exec that a fork keeps from the parent, undone.
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        signal.signal(signal.SIGHUP, signal.SIG_DFL)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        in_child()
        with open(os.devnull, "rb") as null:
            os.dup2(null.fileno(), 0)
        os.dup2(log_fd, 1)
        os.dup2(log_fd if err_fd is None else err_fd, 2)
        os.close(log_fd)
        if err_fd is not None:
            os.close(err_fd)
        os.environ.clear()
        os.environ.update(env)
        for stream in (sys.stdout, sys.stderr):
            if isinstance(stream, io.TextIOWrapper):  # PYTHONUNBUFFERED's effect, after the fact
                stream.reconfigure(line_buffering=True, write_through=True)
        logging.root.handlers.clear()
        logging.root.setLevel(logging.WARNING)
        atexit._clear()  # the parent's (temporary folders, its logging) are not ours
        gc.freeze()  # what the parent made is never garbage here: the collector skips it
        sys.argv = [module, *argv[argv.index(module) + 1 :]]
        runpy.run_module(module, run_name="__main__", alter_sys=True)
        code = 0
    except SystemExit as exc:
        code = _exit_code(exc)
    except KeyboardInterrupt:
        _flush_and_run_exit_handlers()
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        os.kill(os.getpid(), signal.SIGINT)
    except BaseException:
        traceback.print_exc()
        code = 1
    _flush_and_run_exit_handlers()
    os._exit(code)


def _flush_and_run_exit_handlers() -> None:
    with contextlib.suppress(BaseException):
        atexit._run_exitfuncs()
    with contextlib.suppress(BaseException):
        logging.shutdown()
    flush_output()
