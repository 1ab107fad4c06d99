"""Profiling only: every Python thread of every service under cProfile.

    PYTHONPATH=bench/profile HRC_PROFILE_DIR=/tmp/prof .venv/bin/hrc run scenarios/thesis.toml
    python -c "import pstats; pstats.Stats('/tmp/prof/hrc_orchestrator.<pid>.prof')
               .sort_stats('cumulative').print_stats(40)"

Python imports this module at start-up when its folder is on PYTHONPATH (``hrc run`` passes
its environment to the services). With ``HRC_PROFILE_DIR`` set, a process started as
``python -m <module>`` profiles its main thread and every thread started after (Zenoh's
callback threads, where the steps of the lockstep ticks run), and writes
``<module>.<pid>.prof`` (all threads merged) when it leaves through ``os._exit``, as the
services do (``hrc.service.exit_now``). Without the variable it does nothing. The profiler
costs about twice the Python time it measures: compare shares and call counts, not seconds.
"""

from __future__ import annotations

import os
import sys

_DIR = os.environ.get("HRC_PROFILE_DIR")

if _DIR and "-m" in sys.orig_argv[:-1]:
    import cProfile
    import pstats
    import threading

    _module = sys.orig_argv[sys.orig_argv.index("-m") + 1]
    _profiles: list[cProfile.Profile] = []
    _lock = threading.Lock()

    def _profile_this_thread(*_args: object) -> None:
        # threading.setprofile's hook runs once in each new thread: a profiler of its own
        # replaces it (cProfile is per thread).
        prof = cProfile.Profile()
        with _lock:
            _profiles.append(prof)
        prof.enable()

    threading.setprofile(_profile_this_thread)
    _main = cProfile.Profile()
    _profiles.append(_main)
    _main.enable()
    _exit = os._exit

    def _dump_and_exit(code: int) -> None:
        try:
            with _lock:
                profiles = list(_profiles)
            for prof in profiles:
                prof.disable()
            stats = pstats.Stats(profiles[0])
            for prof in profiles[1:]:
                stats.add(prof)
            stats.dump_stats(os.path.join(_DIR, f"{_module}.{os.getpid()}.prof"))
        except Exception as exc:  # profiling must never change the exit code
            sys.stderr.write(f"profile not written: {exc}\n")
        _exit(code)

    os._exit = _dump_and_exit
