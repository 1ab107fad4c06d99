"""The warm worker of a sweep (the caller's side and the protocol: ``hrc.study.warm``): imports
what ``hrc run`` needs once, then forks one ``hrc run`` per request, each run as
``python -m hrc.cli.main ...`` would be, and reports each one's end with its CPU."""

from __future__ import annotations

import contextlib
import json
import os
import selectors
import signal
import socket
import sys
from collections.abc import Callable
from typing import NoReturn

from hrc.study.warm import ANSWER_TIMEOUT_S, HEADER, MODULE, READY


def _import_what_hrc_run_needs() -> None:
    # What `hrc run` imports before it starts its services (hrc.cli.main's _cmd_run), and
    # pybullet, which physics (forked from it) imports first thing.
    import pybullet  # noqa: F401

    import hrc.cli.main
    import hrc.cli.summary
    import hrc.ports
    import hrc.scenario
    import hrc.scenario.resolved
    import hrc.trial
    import hrc.trial.options  # noqa: F401


def serve(socket_path: str) -> int:
    """The worker's life: imports, then one fork per connection until stdin closes."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    _import_what_hrc_run_needs()
    from hrc.trial.prefork import START_ENV, can_fork

    if not can_fork():
        threads = len(os.listdir("/proc/self/task"))
        print(f"warm worker: cannot fork here ({threads} threads, or {START_ENV} / profiling)")
        return 1
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    listener.bind(socket_path)
    listener.listen(64)
    wake_r, wake_w = os.pipe()
    os.set_blocking(wake_w, False)
    signal.set_wakeup_fd(wake_w)
    signal.signal(signal.SIGCHLD, lambda _s, _f: None)  # wakes the selector (wakeup fd)
    sel = selectors.DefaultSelector()
    sel.register(listener, selectors.EVENT_READ, "accept")
    sel.register(wake_r, selectors.EVENT_READ, "child")
    sel.register(sys.stdin, selectors.EVENT_READ, "stdin")
    trials: dict[int, socket.socket] = {}  # pid -> its caller's connection
    print(READY, flush=True)
    while True:
        for key, _mask in sel.select():
            if key.data == "stdin":
                if not os.read(sys.stdin.fileno(), 4096):
                    return 0  # the sweep ended: running trials end with us (parent death)
            elif key.data == "child":
                with contextlib.suppress(BlockingIOError):
                    os.read(wake_r, 4096)
                _reap(trials)
            else:
                conn, _addr = listener.accept()
                pid = _start(conn, lambda: _close_in_child(listener, sel, wake_r, wake_w, trials))
                if pid is not None:
                    trials[pid] = conn
        _reap(trials)


def _reap(trials: dict[int, socket.socket]) -> None:
    while trials:
        try:
            pid, status, ru = os.wait4(-1, os.WNOHANG)
        except ChildProcessError:
            return
        if not pid:
            return
        conn = trials.pop(pid, None)
        if conn is None:
            continue
        answer = {"exit": os.waitstatus_to_exitcode(status), "cpu_s": ru.ru_utime + ru.ru_stime}
        with contextlib.suppress(OSError):
            conn.sendall(json.dumps(answer).encode() + b"\n")
        conn.close()


def _close_in_child(
    listener: socket.socket,
    sel: selectors.BaseSelector,
    wake_r: int,
    wake_w: int,
    trials: dict[int, socket.socket],
) -> None:
    """What a trial must not hold of the worker: its listener, its wakeup pipe, and the other
    trials' connections (a copy kept open would hide the worker's end from their callers)."""
    for other in trials.values():
        other.close()
    signal.set_wakeup_fd(-1)
    signal.signal(signal.SIGCHLD, signal.SIG_DFL)
    sel.close()
    listener.close()
    os.close(wake_r)
    os.close(wake_w)


def _start(conn: socket.socket, close_worker: Callable[[], None]) -> int | None:
    """Reads one request and forks its trial; the pid (None for a request it could not read,
    whose connection is closed)."""
    try:
        conn.settimeout(ANSWER_TIMEOUT_S)
        head, fds, _flags, _addr = socket.recv_fds(conn, HEADER.size, 2)
        if len(head) != HEADER.size or len(fds) != 2:
            raise ValueError(f"a request without its header and two files ({len(fds)} files)")
        (size,) = HEADER.unpack(head)
        body = bytearray()
        while len(body) < size:
            chunk = conn.recv(size - len(body))
            if not chunk:
                raise ValueError("a request cut short")
            body += chunk
        req = json.loads(body)
        argv, cwd, env = list(req["argv"]), str(req["cwd"]), dict(req["env"])
        umask = int(req["umask"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        print(f"warm worker: a request refused: {exc}", file=sys.stderr, flush=True)
        conn.close()
        return None
    from hrc.service import flush_output

    flush_output()  # or what is buffered would be written twice
    led_r, led_w = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(led_r)
        _trial_child(conn, close_worker, argv, cwd, env, umask, fds, led_w)
    for fd in (*fds, led_w):
        os.close(fd)
    # Its pid goes out once it leads its session: a caller's killpg at once must reach it. (EOF
    # if it died before: it is reaped as any other.)
    os.read(led_r, 1)
    os.close(led_r)
    conn.settimeout(None)
    # (a caller that left: the trial still runs to its end, and is reaped)
    with contextlib.suppress(OSError):
        conn.sendall(json.dumps({"pid": pid}).encode() + b"\n")
    return pid


def _trial_child(
    conn: socket.socket,
    close_worker: Callable[[], None],
    argv: list[str],
    cwd: str,
    env: dict[str, str],
    umask: int,
    fds: list[int],
    led_w: int,
) -> NoReturn:
    from hrc.trial.prefork import child_main

    try:
        os.setsid()  # as subprocess's start_new_session: the caller stops it with killpg
        os.close(led_w)  # (the worker may answer now)
        conn.close()
        close_worker()
        os.chdir(cwd)
        os.umask(umask)
        # run as __main__ afresh, as `python -m` does (runpy warns of a copy already imported)
        sys.modules.pop(MODULE, None)
    except BaseException:
        os._exit(1)
    child_main(MODULE, argv, fds[0], env, lambda: None, err_fd=fds[1])


def main() -> int:
    if len(sys.argv) != 2:
        print("usage: the warm worker takes its socket's path", file=sys.stderr)
        return 2
    return serve(sys.argv[1])


if __name__ == "__main__":
    sys.exit(main())
