"""``hrc bench trial``: what a whole trial costs (issue 15), from one run of each board.

For the thesis trial (``scenarios/thesis.toml``) and for a board three times as large (the
thesis's 18 parts plus 36 spare parts lying on the table, generated here), it runs ``hrc run``
as a user would and reports:

- ``realtime_factor``: simulated / wall seconds of the run phase (metrics.json ``run``);
- ``end_to_end_s``: wall seconds of the whole ``hrc run`` (start-up, run, the logger's files);
  ``phases_s``: where they went (``<trial>/services/timing.json``: prepare, start, run, end);
- ``cpu_s`` and ``cpu_s_per_sim_s``: CPU seconds of ``hrc run`` and every service (user +
  system), in all and per simulated second; ``cpu_s_by_service``;
- ``exchanges``, ``mean_span``: clock exchanges and ticks per exchange;
- ``us_per_exchange_by_service``: each service's CPU microseconds per exchange;
- ``cosim_us_per_tick``: run-phase wall microseconds per tick; ``raw_physics_us_per_tick``: the
  physics bench's tick of the same board measured right after it; ``ratio`` of the two;
- ``raw_physics_cpu_s_per_sim_s``: the physics bench's CPU per simulated second, and
  ``cpu_ratio``: the trial's CPU per simulated second over it (what a trial costs beyond its
  physics: the bus, the other services, start-up).

And the floor under ``cpu_ratio`` (``floor``, measured in the same run): the services' start-up
(``startup_cpu_s``: ``hrc run`` of ``scenarios/empty.toml`` for 10 ticks) and one bare exchange
(``bare_exchange_cpu_us``: the same scenario with one-tick exchanges, 2,000 ticks more: a clock
tick to every service and their acks, nothing computed); per board ``floor_cpu_ratio``, the
ratio the trial would have if every service's own work cost nothing: (start-up + exchanges x
bare exchange + raw physics) / raw physics.

And ``study`` (the thesis trial as a sweep runs it, ``STUDY_TRIALS`` times in a row through one
warm worker, ``hrc.study.warm``: no interpreter start per trial): ``cpu_s_per_trial`` (the
worker's CPU with all its trials', its own start-up shared by them), ``us_per_exchange_by_service``
(the services' mean over the trials) and, under ``thesis``, ``study_cpu_ratio``: that CPU per
simulated second over raw physics's, as ``cpu_ratio`` is for a lone ``hrc run``.

And, under ``thesis``, ``no_view_cpu_s`` and ``no_view_cpu_ratio``: the same lone trial with
``hrc run --no-view`` (no 3D recording: ``hrc power``'s pool, ``hrc sweep --no-view``), over the
same raw physics.

And ``busy``: the thesis trial again beside one busy process per core (a build, another trial):
its run phase (``run_wall_s``, ``realtime_factor``) and ``slowdown``, its run-phase wall over the
quiet run's. An observer that got no CPU at all there (the logger under SCHED_IDLE in lockstep)
held the clock to its window: 20x slower, 2026-11-29.

Figures only, never asserted (the machine's load moves them; CPU seconds move least).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from hrc import service_table
from hrc.bus.clock import exchange_counts
from hrc.paths import project_root

THESIS = "scenarios/thesis.toml"
SPARE_PARTS = 36  # 18 + 36 = 54 parts: three times the thesis board


def board_3x_toml(thesis: Path) -> str:
    """The thesis scenario plus 36 spare parts (2 cm cubes, the human's, last in the human's
    sequence, each placed where it lies) in two rows on the table behind the participant's
    parts: at rest, as most of a board is at any moment."""
    lines = [
        thesis.read_text(),
        "\n# ---- 36 spare parts (hrc bench trial: a board 3x the thesis's)\n",
    ]
    for i in range(SPARE_PARTS):
        row, col = divmod(i, SPARE_PARTS // 2)
        x = -0.38 + col * (0.76 / (SPARE_PARTS // 2 - 1))
        y = -0.58 - 0.06 * row
        lines.append(
            f'\n[[parts]]\nid = "X{i + 1:02d}"\nowner = "human"\nkind = "spare"\n'
            f"size = [0.02, 0.02, 0.02]\n"
            f"start = {{ xyz = [{x:.4f}, {y:.4f}, 0.01], yaw = 0 }}\n"
            f"target = {{ xyz = [{x:.4f}, {y:.4f}, 0.01], yaw = 0 }}\n"
        )
    text = "".join(lines)
    spares = ", ".join(f'"X{i + 1:02d}"' for i in range(SPARE_PARTS))
    human = re.search(r"^human = \[(.*)\]$", text, re.MULTILINE)
    if human is None:
        raise ValueError(f"{thesis}: no human sequence to extend")
    return text.replace(human.group(0), f"human = [{human.group(1)}, {spares}]")


def one_tick_toml(text: str, name: str) -> str:
    """Scenario ``text`` (file ``name``) with one-tick exchanges (``max_exchange_ticks = 1``)."""
    if "\n[scenario]\n" not in text:
        raise ValueError(f"{name}: no [scenario] table")
    return text.replace("\n[scenario]\n", "\n[scenario]\nmax_exchange_ticks = 1\n", 1)


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def hrc_run(scenario: Path, out: Path, options: list[str]) -> tuple[float, float]:
    """``hrc run scenario --out out OPTIONS`` as a user would: its wall seconds and the CPU
    seconds of it and its services; RuntimeError with its output when it fails."""
    argv = [sys.executable, "-m", "hrc.cli.main", "run", str(scenario), "--out", str(out)]
    cpu0, t0 = _children_cpu(), time.monotonic()
    proc = subprocess.run(
        [*argv, *options], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    wall, cpu = time.monotonic() - t0, _children_cpu() - cpu0
    if proc.returncode != 0:
        raise RuntimeError(f"hrc run {scenario} failed ({proc.returncode}):\n{proc.stdout}")
    return wall, cpu


def raw_physics_us(scenario: Path, n: int) -> float:
    argv = [sys.executable, "-m", f"{service_table.service('physics').module}.bench", "--json"]
    argv += ["--scenario", str(scenario), "--n", str(n)]
    out = subprocess.run(argv, stdout=subprocess.PIPE, text=True, check=True).stdout
    return float(json.loads(out)["us_per_tick"])


def service_figures(out: Path) -> tuple[dict[str, float], int | None]:
    """A trial folder's CPU-s by service (user + system) and its exchanges (None if physics's
    log does not say)."""
    by_service = {
        name: v["user_s"] + v["system_s"]
        for name, v in json.loads((out / "services" / "cpu.json").read_text()).items()
    }
    counts = exchange_counts((out / "services" / "physics.log").read_text())
    return by_service, counts[1] if counts else None


def measure(scenario: Path, out: Path, physics_n: int, max_ticks: int = 0) -> dict[str, Any]:
    """One ``hrc run`` of ``scenario`` into ``out`` (at most ``max_ticks``), then the physics
    bench of the same board."""
    wall, cpu = hrc_run(scenario, out, ["--max-ticks", str(max_ticks)] if max_ticks else [])
    run = json.loads((out / "metrics.json").read_text())["run"]
    cpu_by_service, found = service_figures(out)
    by_service = {name: round(v, 3) for name, v in cpu_by_service.items()}
    timing = json.loads((out / "services" / "timing.json").read_text())
    ticks = int(run["ticks"])
    exchanges = found if found is not None else ticks
    sim_s = run["wall_s"] * run["realtime_factor"]
    cosim_us = run["wall_s"] / ticks * 1e6
    raw_us = raw_physics_us(scenario, physics_n)
    raw_cpu = raw_us * 1e-6 * ticks / sim_s
    return {
        "scenario": str(scenario),
        "ticks": ticks,
        "sim_s": round(sim_s, 3),
        "run_wall_s": round(run["wall_s"], 3),
        "realtime_factor": round(run["realtime_factor"], 2),
        "end_to_end_s": round(wall, 3),
        "phases_s": {
            k.removesuffix("_s"): v for k, v in timing.items() if k != "exit_by_service_s"
        },
        "exit_after_run_end_s": timing["exit_by_service_s"],
        "cpu_s": round(cpu, 3),
        "cpu_s_per_sim_s": round(cpu / sim_s, 4),
        "cpu_s_by_service": by_service,
        "exchanges": exchanges,
        "mean_span": round(ticks / max(1, exchanges), 2),
        "us_per_exchange_by_service": {
            n: round(v / max(1, exchanges) * 1e6) for n, v in by_service.items()
        },
        "cosim_us_per_tick": round(cosim_us, 1),
        "raw_physics_us_per_tick": round(raw_us, 1),
        "ratio": round(cosim_us / raw_us, 2),
        # the physics bench is one thread that never waits: its wall per tick is its CPU
        "raw_physics_cpu_s_per_sim_s": round(raw_cpu, 4),
        "cpu_ratio": round(cpu / sim_s / raw_cpu, 2),
    }


FLOOR_TICKS = 2000


@contextlib.contextmanager
def busy_cores() -> Iterator[int]:
    """One process per core that only spins (at the normal priority) for the block."""
    n = len(os.sched_getaffinity(0))
    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]
    try:
        yield n
    finally:
        for h in hogs:
            h.kill()
            h.wait()


def measure_busy(scenario: Path, out: Path, quiet: dict[str, Any]) -> dict[str, Any]:
    """The trial again beside a busy process per core: its run phase, and how much slower."""
    with busy_cores() as n:
        hrc_run(scenario, out, [])
    run = json.loads((out / "metrics.json").read_text())["run"]
    return {
        "busy_processes": n,
        "run_wall_s": round(run["wall_s"], 3),
        "realtime_factor": round(run["realtime_factor"], 2),
        "slowdown": round(run["wall_s"] / quiet["run_wall_s"], 2),
    }


STUDY_TRIALS = 3


def measure_study(scenario: Path, tmpdir: Path, lone: dict[str, Any]) -> dict[str, Any]:
    """``STUDY_TRIALS`` runs of ``scenario`` through one warm worker, one after the other."""
    from hrc.study.warm import WarmStarter

    by_service: dict[str, float] = {}
    exchanges = 0
    with WarmStarter() as ws:
        for i in range(STUDY_TRIALS):
            out = tmpdir / f"study-{i}"
            argv = [sys.executable, "-m", "hrc.cli.main", "run", str(scenario), "--out", str(out)]
            proc = ws.popen(argv)
            _stdout, stderr = proc.communicate(timeout=600)
            if proc.returncode != 0:
                raise RuntimeError(f"hrc run {scenario} failed ({proc.returncode}):\n{stderr}")
            cpu, found = service_figures(out)
            exchanges += found or 0
            for name, v in cpu.items():
                by_service[name] = by_service.get(name, 0.0) + v
    per_trial = ws.cpu_s / STUDY_TRIALS
    raw = lone["raw_physics_cpu_s_per_sim_s"] * lone["sim_s"]
    return {
        "trials": STUDY_TRIALS,
        "cpu_s_per_trial": round(per_trial, 3),
        "us_per_exchange_by_service": {
            n: round(v / max(1, exchanges) * 1e6) for n, v in by_service.items()
        },
        "study_cpu_ratio": round(per_trial / raw, 2),
    }


def measure_floor(empty: Path, tmpdir: Path) -> dict[str, float]:
    """Start-up and one bare exchange, from two runs of the one-tick empty scenario."""
    _wall, startup = hrc_run(empty, tmpdir / "floor-start", ["--ticks", "10"])
    _wall, longer = hrc_run(empty, tmpdir / "floor-long", ["--ticks", str(10 + FLOOR_TICKS)])
    return {
        "startup_cpu_s": round(startup, 3),
        "bare_exchange_cpu_us": round((longer - startup) / FLOOR_TICKS * 1e6),
    }


def floor_ratio(f: dict[str, Any], floor: dict[str, float]) -> float:
    raw = f["raw_physics_cpu_s_per_sim_s"] * f["sim_s"]
    least = floor["startup_cpu_s"] + f["exchanges"] * floor["bare_exchange_cpu_us"] * 1e-6
    return round(float((least + raw) / raw), 2)


def run(args: argparse.Namespace) -> int:
    root = project_root()
    n = getattr(args, "n", 0) or 2000
    with tempfile.TemporaryDirectory(prefix="hrc-bench-trial-") as tmp:
        tmpdir = Path(tmp)
        board = tmpdir / "board-3x.toml"
        board.write_text(board_3x_toml(root / THESIS))
        thesis = measure(root / THESIS, tmpdir / "thesis", n)
        # as many ticks as the thesis trial took: the same work, on a board 3x as large
        figures = {
            "thesis": thesis,
            "board_3x": measure(board, tmpdir / "board-3x", n, thesis["ticks"]),
        }
        empty = tmpdir / "empty-one-tick.toml"
        # (its idle exchanges would span many ticks)
        empty.write_text(
            one_tick_toml((root / "scenarios" / "empty.toml").read_text(), "empty.toml")
        )
        floor = measure_floor(empty, tmpdir)
        for f in figures.values():
            f["floor_cpu_ratio"] = floor_ratio(f, floor)
        figures["floor"] = floor
        figures["study"] = measure_study(root / THESIS, tmpdir, thesis)
        thesis["study_cpu_ratio"] = figures["study"]["study_cpu_ratio"]
        _wall, no_view = hrc_run(root / THESIS, tmpdir / "thesis-no-view", ["--no-view"])
        thesis["no_view_cpu_s"] = round(no_view, 3)
        thesis["no_view_cpu_ratio"] = round(
            no_view / thesis["sim_s"] / thesis["raw_physics_cpu_s_per_sim_s"], 2
        )
        figures["busy"] = measure_busy(root / THESIS, tmpdir / "thesis-busy", thesis)
    if getattr(args, "json", False):
        print(json.dumps(figures))
        return 0
    print(
        f"floor: start-up {floor['startup_cpu_s']} CPU-s, a bare exchange "
        f"{floor['bare_exchange_cpu_us']} CPU-us (every service, nothing computed)"
    )
    study = figures["study"]
    print(
        f"thesis in a study ({study['trials']} trials through one warm worker): "
        f"{study['cpu_s_per_trial']} CPU-s per trial, CPU ratio {study['study_cpu_ratio']}; "
        f"CPU us per exchange: {study['us_per_exchange_by_service']}"
    )
    busy = figures["busy"]
    print(
        f"thesis beside {busy['busy_processes']} busy processes: run phase {busy['run_wall_s']} s "
        f"= {busy['realtime_factor']}x real time, {busy['slowdown']}x the quiet run's"
    )
    for name, f in figures.items():
        if name in ("floor", "busy", "study"):
            continue
        print(
            f"{name}: {f['ticks']} ticks ({f['sim_s']} s simulated) in {f['exchanges']} exchanges"
        )
        print(
            f"  run phase {f['run_wall_s']} s = {f['realtime_factor']}x real time; "
            f"end to end {f['end_to_end_s']} s"
        )
        print(f"  phases (s): {f['phases_s']}")
        print(f"  exits after run/end (s): {f['exit_after_run_end_s']}")
        print(
            f"  CPU {f['cpu_s']} s = {f['cpu_s_per_sim_s']} CPU-s per simulated s; raw physics "
            f"{f['raw_physics_cpu_s_per_sim_s']}; CPU ratio {f['cpu_ratio']} (floor "
            f"{f['floor_cpu_ratio']}: start-up and bare exchanges only)"
        )
        if "no_view_cpu_ratio" in f:
            print(
                f"  without the view (--no-view): CPU {f['no_view_cpu_s']} s, CPU ratio "
                f"{f['no_view_cpu_ratio']}"
            )
        print(f"  CPU us per exchange: {f['us_per_exchange_by_service']}")
        print(
            f"  co-simulated tick {f['cosim_us_per_tick']} us, raw physics tick "
            f"{f['raw_physics_us_per_tick']} us, ratio {f['ratio']}"
        )
    return 0
