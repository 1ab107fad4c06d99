"""`hrc power STUDY --effect FACTOR`: how many participants a study needs, by simulation
(docs/studies.md, "Power by simulation").

A pool of simulated participants (drawn from the study's `[participants]` distributions, or its
fitted twins) runs every condition of the study, each trial with a seed of its own
(`study.seeds = "trial"`: a person's noise differs from one trial to the next, so a comparison
between conditions is not spared it). That is an ordinary `hrc sweep` into `<out>/pool/`:
resumable, local or on a Dask cluster; without 3D recordings (`hrc run --no-view`). Then, for
each study size N, `sims` studies of N participants are drawn from the pool without
replacement and the study's own model (the one `hrc report` fits: a mixed model with a random
intercept per participant) is fitted to each; the power at N is the share of studies whose
test of the factor (Wald, jointly over its levels) has p < alpha, with its Monte-Carlo interval
(Wilson, 95 %). A participant's trials do not depend on who else takes part, so every N reuses
the same pool: the cost is the pool's trials, not N x sims of them.

The pool is a sample of the population too: where N comes near the pool's size the studies share
most of their people and lean towards the pool's own result (a warning says so above half of it).
"""

from __future__ import annotations

import html
import logging
import math
import sys
import time
import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import IO, TYPE_CHECKING

import numpy as np

from hrc.atomic import write_json_atomic, write_text_atomic
from hrc.study.report import (
    CSS,
    OUTCOMES,
    ReportError,
    _label,
    _load,
    _table,
    analysis_frame,
    fit_formula,
    model_data,
)

if TYPE_CHECKING:
    import pandas as pd

log = logging.getLogger(__name__)

DEFAULT_POOL = 20
DEFAULT_NS = (4, 6, 8, 10)
DEFAULT_SIMS = 200
DEFAULT_ALPHA = 0.05
DEFAULT_TARGET = 0.8
DEFAULT_OUTCOME = "task_completion_s"
POOL = "pool"  # the pool's sweep folder inside the power folder
Z95 = 1.959964


class PowerError(Exception):
    """What `hrc power` was asked cannot be answered (a factor or outcome the study lacks)."""


@dataclass(frozen=True)
class PowerSettings:
    effect: str  # the factor whose effect is tested (a key of the study's factors)
    outcome: str = DEFAULT_OUTCOME  # an outcome's name (hrc.study.report.OUTCOMES)
    ns: tuple[int, ...] = DEFAULT_NS
    sims: int = DEFAULT_SIMS
    alpha: float = DEFAULT_ALPHA
    target: float = DEFAULT_TARGET
    seed: int = 1  # of the draws of studies from the pool


@dataclass
class PowerPoint:
    n: int
    sims: int
    significant: int
    power: float
    low: float  # Monte-Carlo interval of the power (Wilson, 95 %)
    high: float
    not_fitted: int  # studies whose model could not be fitted (counted as not significant)
    # per level of the factor (vs its reference): mean and 2.5 / 97.5 % of the estimates
    effects: dict[str, tuple[float, float, float]] = field(default_factory=dict)


@dataclass
class PowerResult:
    study: str
    settings: PowerSettings
    reference: str  # the factor's reference level
    levels: list[str]
    pool: int  # participants in the pool with at least one ok trial
    trials: int  # ok trials of the pool
    pool_effects: dict[str, float]  # the estimates on the whole pool
    pool_p: float | None
    points: list[PowerPoint]
    smallest_n: int | None  # the smallest N whose power reaches the target
    notes: list[str]
    wall_s: float = 0.0


def wilson(k: int, n: int) -> tuple[float, float]:
    """95 % Wilson interval of a proportion k / n."""
    if n == 0:
        return 0.0, 1.0
    p = k / n
    z2 = Z95 * Z95
    centre = (p + z2 / (2 * n)) / (1 + z2 / n)
    half = Z95 * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n)) / (1 + z2 / n)
    # (at k = 0 and k = n an end is exactly 0 or 1; the float sum misses it by a rounding)
    low = 0.0 if k == 0 else max(0.0, centre - half)
    high = 1.0 if k == n else min(1.0, centre + half)
    return low, high


def check_effect(effect: str, factors: list[str]) -> None:
    """PowerError unless `effect` is one of the study's factors."""
    if effect not in factors:
        raise PowerError(
            f"--effect {effect!r} is not a factor of the study "
            f"(its factors: {', '.join(factors) or 'none'})"
        )


def effect_test(
    data: pd.DataFrame,
    outcome: str,
    factors: list[str],
    levels: dict[str, list[str]],
    effect: str,
) -> tuple[float, dict[str, float]] | None:
    """The study's model fitted to `data`: the p-value of `effect` (Wald, jointly over its
    levels) and its estimate per level against the reference; None when it cannot be fitted
    (too few trials, the factor at one level, a degenerate fit)."""
    m = model_data(data, outcome, factors, levels)
    key = next(k for k, v in m.names.items() if v == effect)
    if m.problem or f"C({key})" not in m.formula:
        return None
    # statsmodels' first import puts its own "always" filter for its convergence warnings in
    # front of the filters: imported inside the block below (the report's fit imports it late),
    # it would print them through the "ignore" of the first fit (`hrc power`'s output, a test's)
    import statsmodels.formula.api  # noqa: F401

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # boundary fits and the like: counted, not printed
        try:
            res, _method, _var = fit_formula(m.formula, m.d, [])  # the report's own fit
            names = list(res.params.index)
            terms = [t for t in names if t.startswith(f"C({key})[T.")]
            if not terms:
                return None
            estimates = np.asarray([res.params[t] for t in terms], dtype=float)
            if hasattr(res, "ssr") and res.ssr <= 1e-12 * float((m.d["y"] ** 2).sum()):
                # no noise left at all (a robot-bound task time): any difference is certain
                p = 0.0 if np.abs(estimates).max() > 1e-9 * float(m.d["y"].abs().max()) else 1.0
            else:
                r = np.zeros((len(terms), len(names)))
                for i, t in enumerate(terms):
                    r[i, names.index(t)] = 1.0
                p = float(res.wald_test(r, scalar=True).pvalue)
        except (np.linalg.LinAlgError, ValueError, IndexError, ZeroDivisionError):
            return None
    if not math.isfinite(p):
        return None
    prefix = len(f"C({key})[T.")
    return p, {t[prefix:-1]: float(res.params[t]) for t in terms}


def power_curve(
    data: pd.DataFrame,
    factors: list[str],
    levels: dict[str, list[str]],
    settings: PowerSettings,
    progress: IO[str] | None = None,
) -> tuple[list[PowerPoint], tuple[float, dict[str, float]] | None]:
    """Power at each N of `settings.ns` from the pool in `data` (the analysis frame of its ok
    trials), and the test on the whole pool."""
    import pandas as pd

    people = np.array(sorted(data["participant"].astype(str).unique()))
    by_person = {p: data[data["participant"].astype(str) == p] for p in people}
    rng = np.random.default_rng(settings.seed)
    effect, outcome = settings.effect, settings.outcome
    points = []
    for n in settings.ns:
        significant = not_fitted = 0
        estimates: dict[str, list[float]] = {}
        t0 = time.monotonic()
        for _ in range(settings.sims):
            chosen = rng.choice(people, size=n, replace=False)
            sample = pd.concat([by_person[p] for p in chosen])
            result = effect_test(sample, outcome, factors, levels, effect)
            if result is None:
                not_fitted += 1
                continue
            p, est = result
            significant += p < settings.alpha
            for level, value in est.items():
                estimates.setdefault(level, []).append(value)
        low, high = wilson(significant, settings.sims)
        points.append(
            PowerPoint(
                n,
                settings.sims,
                significant,
                significant / settings.sims,
                low,
                high,
                not_fitted,
                {
                    lv: (
                        float(np.mean(v)),
                        float(np.percentile(v, 2.5)),
                        float(np.percentile(v, 97.5)),
                    )
                    for lv, v in estimates.items()
                },
            )
        )
        if progress is not None:
            pt = points[-1]
            progress.write(
                f"power: N = {n}: {pt.power:.2f} [{pt.low:.2f}, {pt.high:.2f}] "
                f"({settings.sims} studies, {time.monotonic() - t0:.1f} s)\n"
            )
            progress.flush()
    return points, effect_test(data, outcome, factors, levels, effect)


def analyse(
    pool_dir: Path, settings: PowerSettings, progress: IO[str] | None = None
) -> PowerResult:
    """The power curve from a pool's sweep folder (its `trials.parquet` and `study.json`)."""
    df, meta = _load(pool_dir)
    data, factors, levels = analysis_frame(df, meta)
    check_effect(settings.effect, factors)
    names = [o.name for o in OUTCOMES]
    if settings.outcome not in names:
        raise PowerError(f"--outcome {settings.outcome!r}: one of {', '.join(names)}")
    if settings.outcome not in data:
        raise PowerError(f"the pool's table has no {settings.outcome!r} (no trial ended ok?)")
    data = data.dropna(subset=[settings.outcome])
    pool = int(data["participant"].nunique())
    notes = []
    bad = df[df["outcome"] != "ok"]
    if len(bad):
        which = ", ".join(f"{t} ({o})" for t, o in zip(bad["trial"], bad["outcome"], strict=True))
        notes.append(
            f"{len(bad)} of the pool's {len(df)} trials did not end ok and are left out: {which} "
            "(their reasons: the pool's trials.csv)"
        )
    too_big = [n for n in settings.ns if n > pool]
    if too_big:
        raise PowerError(
            f"N = {too_big[0]} is more than the pool's {pool} participants with usable trials: "
            f"give --pool of at least {max(settings.ns)} (or smaller --n)"
        )
    if any(n > pool / 2 for n in settings.ns):
        notes.append(
            f"N above half the pool ({pool}) draws studies that share most of their people: "
            "there the curve leans towards the pool's own result; a larger --pool tells"
        )
    points, whole = power_curve(data, factors, levels, settings, progress)
    reached = [pt.n for pt in points if pt.power >= settings.target]
    levels_of = levels[settings.effect]
    return PowerResult(
        study=str(meta.get("name", pool_dir.name)),
        settings=settings,
        reference=levels_of[0],
        levels=levels_of,
        pool=pool,
        trials=len(data),
        pool_effects=whole[1] if whole else {},
        pool_p=whole[0] if whole else None,
        points=points,
        smallest_n=min(reached) if reached else None,
        notes=notes,
    )


# ---------------------------------------------------------------- output


def write_outputs(result: PowerResult, out: Path) -> Path:
    """`power.json`, `power.csv`, `power.png` and `power.html` in `out`; the page's path."""
    out.mkdir(parents=True, exist_ok=True)
    write_json_atomic(out / "power.json", asdict(result))
    lines = ["n,sims,significant,power,low,high,not_fitted"]
    lines += [
        f"{p.n},{p.sims},{p.significant},{p.power:.4f},{p.low:.4f},{p.high:.4f},{p.not_fitted}"
        for p in result.points
    ]
    write_text_atomic(out / "power.csv", "\n".join(lines) + "\n")
    _figure(result, out / "power.png")
    page = out / "power.html"
    write_text_atomic(page, _page(result))
    return page


def _unit(outcome: str) -> str:
    return next((o.unit for o in OUTCOMES if o.name == outcome), "")


def _title(outcome: str) -> str:
    return next((o.title for o in OUTCOMES if o.name == outcome), outcome)


def _figure(result: PowerResult, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s = result.settings
    ns = [p.n for p in result.points]
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 4))
    power = [p.power for p in result.points]
    # (clipped: an interval's end and its centre may differ by rounding in the other direction)
    err = [
        [max(0.0, p.power - p.low) for p in result.points],
        [max(0.0, p.high - p.power) for p in result.points],
    ]
    ax.errorbar(ns, power, yerr=err, marker="o", capsize=4, color="#1f5fa8", label="power")
    ax.axhline(s.target, color="#2a8a2a", linestyle="--", label=f"target {s.target:.0%}")
    ax.axhline(s.alpha, color="#999999", linestyle=":", label=f"alpha {s.alpha:g}")
    if result.smallest_n is not None:
        ax.axvline(result.smallest_n, color="#2a8a2a", alpha=0.4)
    ax.set_ylim(0, 1.02)
    ax.set_xlabel("participants (N)")
    ax.set_ylabel("power")
    ax.set_title(f"{s.effect}: {_title(s.outcome)}", fontsize=10)
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    for level in result.levels[1:]:
        rows = [(p.n, p.effects[level]) for p in result.points if level in p.effects]
        if not rows:
            continue
        x = [n for n, _ in rows]
        mean = [e[0] for _, e in rows]
        band = [[max(0.0, e[0] - e[1]) for _, e in rows], [max(0.0, e[2] - e[0]) for _, e in rows]]
        bx.errorbar(x, mean, yerr=band, marker="s", capsize=4, label=_versus(result, level))
    bx.axhline(0, color="#999999", linewidth=0.8)
    bx.set_xlabel("participants (N)")
    bx.set_ylabel(f"estimated effect ({_unit(s.outcome)})")
    bx.set_title("effect estimates (mean, 95 % of studies)", fontsize=10)
    if bx.get_legend_handles_labels()[0]:
        bx.legend(fontsize=8)
    bx.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _versus(result: PowerResult, level: str) -> str:
    return f"{_label(result.settings.effect)} = {level} vs {result.reference}"


def answer(result: PowerResult) -> str:
    """One sentence: the smallest N that reaches the target power, or that none does."""
    s = result.settings
    what = f"the effect of {s.effect} on {_title(s.outcome).lower()}"
    if result.smallest_n is not None:
        pt = next(p for p in result.points if p.n == result.smallest_n)
        return (
            f"{result.smallest_n} participants see {what} with {pt.power:.0%} power "
            f"(Monte-Carlo interval {pt.low:.0%}-{pt.high:.0%}; target {s.target:.0%}, "
            f"alpha {s.alpha:g})"
        )
    best = max(result.points, key=lambda p: p.power)
    return (
        f"No N up to {max(p.n for p in result.points)} reaches {s.target:.0%} power for {what} "
        f"(at most {best.power:.0%} at N = {best.n}; alpha {s.alpha:g})"
    )


def _fmt(x: float) -> str:
    return "" if not math.isfinite(x) else f"{x:.3g}"


def _page(result: PowerResult) -> str:
    s = result.settings
    unit = _unit(s.outcome)
    parts = [
        f"<!doctype html><html><head><meta charset='utf-8'><title>Power: "
        f"{html.escape(result.study)}</title><style>{CSS}</style></head><body>",
        f"<h1>Power by simulation: {html.escape(result.study)}</h1>",
        f"<p><b>{html.escape(answer(result))}.</b></p>",
        f"<p class='muted'>Pool: {result.pool} simulated participants, {result.trials} trials "
        "that ended ok, each trial with a seed of its own. For each N, "
        f"{s.sims} studies of N participants drawn from the pool without replacement; the "
        "study's model (a mixed model, a random intercept per participant) fitted to each; "
        f"power = the share with p &lt; {s.alpha:g} for {html.escape(s.effect)} (Wald test over "
        "its levels). Interval: Monte-Carlo, Wilson 95 %.</p>",
        "<img src='power.png' alt='power against the number of participants'>",
    ]
    levels = result.levels[1:]
    head = ["N", "power", "95 % interval", "not fitted"]
    head += [f"{html.escape(_versus(result, lv))} ({unit})" for lv in levels]
    body = []
    for p in result.points:
        row = [str(p.n), f"{p.power:.2f}", f"[{p.low:.2f}, {p.high:.2f}]", str(p.not_fitted)]
        for lv in levels:
            e = p.effects.get(lv)
            row.append(f"{_fmt(e[0])} [{_fmt(e[1])}, {_fmt(e[2])}]" if e else "")
        body.append(row)
    parts.append(_table(head, body))
    whole = ", ".join(f"{html.escape(k)}: {_fmt(v)} {unit}" for k, v in result.pool_effects.items())
    p_whole = "-" if result.pool_p is None else _fmt(result.pool_p)
    parts.append(f"<p>On the whole pool: {whole or 'not fitted'} (p = {p_whole}).</p>")
    parts += [f"<p class='note'>{html.escape(n)}</p>" for n in result.notes]
    parts.append(
        f"<p class='muted'>{result.wall_s:.0f} s; draws seeded with {s.seed}.</p></body></html>"
    )
    return "\n".join(parts)


def run_power(
    study_path: Path,
    out: Path,
    settings: PowerSettings,
    *,
    pool: int = DEFAULT_POOL,
    workers: int = 0,
    cluster: str | None = None,
    timeout_s: float = 900.0,
    motion_check: bool = True,
    progress: IO[str] | None = None,
) -> PowerResult:
    """Run the pool's trials (those not done before in `out/pool`), then the curve; write the
    outputs; return the result. `pool` simulated participants drawn as the study draws them
    (its replays and fitted twins besides); 0: the study's own people as the file gives them
    (a pilot's twins alone, say)."""
    from hrc.study.spec import load_study
    from hrc.study.sweep import sweep

    t0 = time.monotonic()
    study = load_study(
        study_path, motion_check=motion_check, participants=pool or None, seeds="trial"
    )
    people = len(study.people)
    check_effect(settings.effect, list(study.factors))  # before any trial runs
    if max(settings.ns) > people:
        raise PowerError(
            f"--n up to {max(settings.ns)} needs a pool of at least that many people "
            f"(the pool has {people}: give --pool)"
        )
    # the pool's trials give their metrics; a 3D recording of each costs a tenth of the CPU
    # (the logger's view) and 2.5 MB a trial
    sweep(study, out / POOL, workers=workers, cluster=cluster, timeout_s=timeout_s, view=False)
    try:
        result = analyse(out / POOL, settings, progress or sys.stderr)
    except ReportError as exc:
        raise PowerError(str(exc)) from exc
    result.wall_s = time.monotonic() - t0
    write_outputs(result, out)
    return result
