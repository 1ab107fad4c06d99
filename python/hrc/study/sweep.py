"""`hrc sweep`: run every trial of a study, here (threads driving `hrc run` processes) or on a
Dask cluster, resumably, and gather one table (docs/studies.md)."""

from __future__ import annotations

import json
import logging
import os
import queue
import shutil
import sys
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path
from typing import IO, Any

from hrc.diskspace import SIMULATED_TRIAL_MB, low_space
from hrc.priority import cpu_slots
from hrc.study.live import SLOTS
from hrc.study.spec import Study
from hrc.study.table import write_table
from hrc.study.trial import (
    MANIFEST,
    Job,
    Manifest,
    Record,
    allow_trials,
    run_job,
    stop_running,
)
from hrc.study.warm import start_worker

log = logging.getLogger(__name__)


class Progress:
    """A progress line with ETA on stderr: redrawn in place on a terminal, one line per finished
    trial otherwise (logs, CI)."""

    def __init__(self, total: int, skipped: int, stream: IO[str] | None = None) -> None:
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty() and not os.environ.get("CI")
        self.total, self.skipped = total, skipped
        self.done = self.failed = 0
        self.t0 = time.monotonic()
        self.stream.write(
            f"sweep: {total} trials, {skipped} done before (kept), {total - skipped} to run\n"
        )
        self.stream.flush()

    def _eta(self) -> str:
        left = self.total - self.skipped - self.done
        if self.done == 0:
            return "ETA --:--"
        per = (time.monotonic() - self.t0) / self.done
        return f"ETA {_clock(per * left)}"

    def update(self, rec: Record) -> None:
        self.done += 1
        self.failed += rec.outcome != "ok"
        n = self.skipped + self.done
        elapsed = _clock(time.monotonic() - self.t0)
        counts = f"{n}/{self.total}" + (f" ({self.failed} not ok)" if self.failed else "")
        if self.tty:
            width = 24
            fill = int(width * n / max(1, self.total))
            bar = "#" * fill + "-" * (width - fill)
            self.stream.write(f"\r[{bar}] {counts}  {elapsed}  {self._eta()}   ")
            if n == self.total:
                self.stream.write("\n")
        else:
            self.stream.write(
                f"sweep: {counts} {rec.trial} {rec.outcome} ({rec.wall_s:.1f} s)  "
                f"elapsed {elapsed}  {self._eta()}\n"
            )
        self.stream.flush()


def _clock(seconds: float) -> str:
    s = round(seconds)
    return (
        f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}" if s >= 3600 else f"{s // 60}:{s % 60:02d}"
    )


WARM_SAYS = "each trial starts as a fork of a warm worker (no interpreter start per trial)"


def _local(jobs: list[Job], workers: int, pin: bool = False) -> Iterator[Record]:
    allow_trials()
    starter = start_worker()  # (None: each trial a new interpreter)
    if starter is not None:
        print(f"sweep: {WARM_SAYS}", file=sys.stderr, flush=True)
    # pin: each parallel trial on CPUs of its own where there are enough (hrc.priority.cpu_slots)
    slots: queue.SimpleQueue[set[int] | None] = queue.SimpleQueue()
    cut = cpu_slots(workers) if pin else None
    for i in range(workers):
        slots.put(cut[i] if cut else None)

    def run_on_free_cpus(job: Job) -> Record:
        cpus = slots.get()  # never waits: a pool thread runs one trial at a time
        try:
            return run_job(job, starter, cpus)
        finally:
            slots.put(cpus)

    pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="trial")
    try:
        futures = [pool.submit(run_on_free_cpus, job) for job in jobs]
        for fut in as_completed(futures):
            yield fut.result()
    except BaseException:  # Ctrl-C, or the caller stopped: no new trial, stop those running
        pool.shutdown(wait=False, cancel_futures=True)
        stop_running()
        raise
    finally:
        pool.shutdown(wait=True)
        if starter is not None:
            starter.close()


class ClusterError(Exception):
    """The Dask scheduler cannot be reached."""


def _cluster(jobs: list[Job], address: str) -> Iterator[Record]:
    from distributed import Client
    from distributed import as_completed as dask_completed

    try:
        client = Client(address, timeout="30s")
    except (OSError, TimeoutError) as exc:
        raise ClusterError(f"cannot reach the Dask scheduler at {address}: {exc}") from exc
    with client:
        # one task a trial, under its own key; a task that fails becomes a failed record
        futures = [
            client.submit(run_job, job, key=f"trial-{job.trial}-{job.input_hash}", pure=False)
            for job in jobs
        ]
        index = {fut.key: i for i, fut in enumerate(futures)}
        for fut in dask_completed(futures):
            if fut.status == "error":
                job = jobs[index[fut.key]]
                reason = f"the cluster could not run it: {fut.exception()!r}"
                yield Record(job.trial, job.input_hash, "failed", reason, None)
            else:
                yield fut.result()


def sweep(
    study: Study,
    out: Path,
    *,
    workers: int = 0,
    cluster: str | None = None,
    timeout_s: float = 900.0,
    progress: Callable[[Record], None] | None = None,
    view: bool = True,
    pin: bool = False,
) -> list[Record]:
    """Run the trials of `study` not already done in `out`; write the manifest, the tables and
    a copy of the study; return every trial's record (in the study's order). `view=False`: the
    trials keep no 3D recording (`hrc power`'s pool, whose trials only give their metrics).
    `pin`: each parallel trial on CPUs of its own (`hrc sweep --pin`), faster on a machine that
    runs nothing else, far slower beside other work (docs/studies.md)."""
    write_study_files(study, out)
    manifest = Manifest(out / MANIFEST)
    todo = [t for t in study.trials if not manifest.done(t)]
    skipped = len(study.trials) - len(todo)
    log.info("%d trials: %d to run, %d done before", len(study.trials), len(todo), skipped)
    if (warning := low_space(out, len(todo), SIMULATED_TRIAL_MB)) is not None:
        log.warning("%s", warning)
    bar = Progress(len(study.trials), skipped)
    jobs = [
        Job(
            t.id,
            str(out.resolve()),
            t.scenario_text,
            t.seed,
            t.input_hash,
            timeout_s,
            study.record and t.person.replay is None,
            view,
        )
        for t in todo
    ]
    if jobs:
        stream = _cluster(jobs, cluster) if cluster else _local(jobs, workers or _cores(), pin)
        for rec in stream:
            manifest.put(rec)
            bar.update(rec)
            if progress is not None:
                progress(rec)
    records = [manifest.records[t.id] for t in study.trials]
    write_table(study, records, out)
    return records


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def write_study_files(study: Study, out: Path) -> None:
    """`study.toml` (a copy) and `study.json` (what `hrc report` needs) in the study folder."""
    out.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(study.path, out / "study.toml")
    (out / "study.json").write_text(json.dumps(describe(study), indent=1), encoding="utf-8")


def describe(study: Study) -> dict[str, Any]:
    """What `hrc report` needs to know about the study (beside the table)."""
    live = study.live
    asked = {slot: getattr(live, slot) for slot in SLOTS} if live else {}
    return {
        "name": study.name,
        "scenario": str(study.scenario),
        "design": study.design,
        "repetitions": study.repetitions,
        "seeds": study.seeds,
        "factors": study.factors,
        "participants": [p.id for p in study.people],
        "participant_parameters": list(study.dists),
        "trials": len(study.trials),
        "live_participants": live.participants if live else [],
        "between": live.between if live else [],  # the live participants' between factors
        "questionnaires": {
            q.id: {
                "title": q.title,
                "when": when,
                "scores": q.score_names(),
                "items": [i.id for i in q.items if i.kind in ("scale", "likert")],
            }
            for when, qs in asked.items()
            for q in qs
        },
    }
