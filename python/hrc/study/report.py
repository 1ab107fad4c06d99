"""`hrc report SWEEP_DIR`: `report.html` and its figures (`figures/*.png`) from a sweep's table.

For each outcome: means with 95 % bootstrap confidence intervals by factor level; interaction
plots (the speed factor against each other factor: anticipation, policy, ...); a linear
mixed-effects model per outcome (statsmodels MixedLM, a random intercept per participant) with
its effect estimates and CIs; and the list of trials that did not end ok. Only trials that ended
ok enter the statistics. What each outcome is made of is in docs/studies.md.

Why one file of over 600 lines: the report's sections are built from one table in one pass and
written as one page; each section is a function of its own.
"""

from __future__ import annotations

import html
import json
import logging
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    import pandas as pd

log = logging.getLogger(__name__)

BOOTSTRAP_SAMPLES = 2000
BOOTSTRAP_SEED = 0  # the report of a table is always the same
FIGURES = "figures"
DASH = "\u2013"  # en dash: "human\u2013robot", an empty cell
TIMES = "\u00d7"  # multiplication sign: "speed \u00d7 anticipation"


class ReportError(Exception):
    """The folder is not a sweep folder (or its table is unreadable)."""


@dataclass(frozen=True)
class Outcome:
    name: str  # column of the analysis frame
    title: str
    unit: str
    columns: str  # regex over the table's columns; several matches are averaged (per robot)
    note: str = ""


OUTCOMES = (
    Outcome("task_completion_s", "Task completion", "s", r"task\.completion_s"),
    Outcome("human_completion_s", "Human completion", "s", r"human\.completion_s"),
    Outcome("human_idle_s", "Human idle", "s", r"human\.idle_s"),
    Outcome("robot_idle_s", "Robot idle", "s", r"robots\.[^.]+\.idle_s", "mean of the robots"),
    Outcome(
        "collisions",
        f"Human{DASH}robot collisions",
        "count",
        r"collisions\.human_robot_count|collisions\.human_robot",
    ),
    Outcome("collision_delay_s", "Total collision delay", "s", r"collisions\.total_delay_s"),
    Outcome(
        "near_collisions", "Near collisions", "count", r"collisions\.near_count|collisions\.near"
    ),
    Outcome(
        "avg_speed_mps",
        "Average TCP speed",
        "m/s",
        r"robots\.[^.]+\.avg_tcp_speed_mps",
        "mean of the robots; moving-only average",
    ),
)


# ---------------------------------------------------------------- data


def _load(sweep_dir: Path) -> tuple[pd.DataFrame, dict[str, Any]]:
    import pandas as pd

    table = sweep_dir / "trials.parquet"
    if not table.exists():
        raise ReportError(f"{sweep_dir}: no trials.parquet (run hrc sweep with --out here)")
    try:
        df = pd.read_parquet(table)
    except Exception as exc:  # pyarrow raises several kinds
        raise ReportError(f"{table}: unreadable: {exc}") from exc
    try:
        meta = json.loads((sweep_dir / "study.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        meta = {"name": str(df["study"].iloc[0]) if len(df) else sweep_dir.name, "factors": {}}
    return df, meta


def _outcome_values(df: pd.DataFrame, outcome: Outcome) -> pd.Series | None:
    import pandas as pd

    for alternative in outcome.columns.split("|"):
        cols = [c for c in df.columns if re.fullmatch(alternative, c)]
        if cols:
            values = df[cols].apply(pd.to_numeric, errors="coerce")
            return values.mean(axis=1)
    return None


def _levels(df: pd.DataFrame, factor: str, meta: dict[str, Any]) -> list[str]:
    declared = [str(v) for v in meta.get("factors", {}).get(factor, [])]
    seen = [str(v) for v in df[factor].dropna().unique()]
    return [v for v in declared if v in seen] + [v for v in seen if v not in declared]


def bootstrap_ci(
    values: npt.NDArray[np.float64], rng: np.random.Generator
) -> tuple[float, float, float]:
    """Mean and its 95 % percentile-bootstrap interval."""
    values = values[np.isfinite(values)]
    if len(values) == 0:
        return (float("nan"),) * 3
    mean = float(values.mean())
    if len(values) == 1:
        return mean, mean, mean
    idx = rng.integers(0, len(values), size=(BOOTSTRAP_SAMPLES, len(values)))
    means = values[idx].mean(axis=1)
    return mean, float(np.percentile(means, 2.5)), float(np.percentile(means, 97.5))


# ---------------------------------------------------------------- figures


def _fmt(x: Any) -> str:
    if isinstance(x, str) or x is None:
        return html.escape(str(x or DASH))
    x = float(x)
    if not np.isfinite(x):
        return DASH
    if abs(x) < 1e-9:  # rounding noise of a fit
        return "0"
    return f"{x:.3g}" if abs(x) < 1000 else f"{x:.0f}"


def _pval(p: float) -> str:
    if not np.isfinite(p):
        return DASH
    return "< 0.001" if p < 0.001 else f"{p:.3f}"


def _label(factor: str) -> str:
    return factor.replace("robots.*.", "").replace("conditions.", "").replace("participant.", "")


def _main_effects(
    data: pd.DataFrame, factors: list[str], levels: dict[str, list[str]], path: Path
) -> dict[str, list[tuple[str, int, float, float, float]]]:
    """Per outcome: (factor level, n, mean, lo, hi) rows; one figure per outcome."""
    import matplotlib.pyplot as plt

    table: dict[str, list[tuple[str, int, float, float, float]]] = {}
    for outcome in OUTCOMES:
        if outcome.name not in data:
            continue
        rng = np.random.default_rng(BOOTSTRAP_SEED)
        rows: list[tuple[str, int, float, float, float]] = []
        fig, axes = plt.subplots(
            1,
            max(1, len(factors)),
            figsize=(2.6 * max(1, len(factors)), 2.4),
            sharey=True,
            squeeze=False,
        )
        for ax, factor in zip(axes[0], factors, strict=False):
            xs, ms, los, his = [], [], [], []
            for i, level in enumerate(levels[factor]):
                vals = data.loc[data[factor] == level, outcome.name].to_numpy(dtype=float)
                m, lo, hi = bootstrap_ci(vals, rng)
                rows.append(
                    (f"{_label(factor)} = {level}", int(np.isfinite(vals).sum()), m, lo, hi)
                )
                xs.append(i)
                ms.append(m)
                los.append(m - lo if np.isfinite(m) else 0)
                his.append(hi - m if np.isfinite(m) else 0)
            ax.errorbar(xs, ms, yerr=[los, his], fmt="o", capsize=4, color="#1f5f99")
            ax.set_xticks(xs, levels[factor])
            ax.set_xlim(-0.5, len(xs) - 0.5)
            ax.set_xlabel(_label(factor))
            ax.grid(axis="y", alpha=0.3)
        axes[0][0].set_ylabel(outcome.unit)  # the section heading names the outcome
        fig.tight_layout()
        fig.savefig(path / f"means_{outcome.name}.png", dpi=90)
        plt.close(fig)
        table[outcome.name] = rows
    return table


def _interaction(
    data: pd.DataFrame, x: str, line: str, levels: dict[str, list[str]], path: Path
) -> str:
    import matplotlib.pyplot as plt

    present = [
        o for o in OUTCOMES if o.name in data and float(data[o.name].std(ddof=0) or 0.0) > 0.0
    ]
    if not present:
        return ""
    cols = 4
    nrows = (len(present) + cols - 1) // cols
    fig, axes = plt.subplots(nrows, cols, figsize=(3.1 * cols, 2.5 * nrows), squeeze=False)
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    for ax, outcome in zip(axes.flat, present, strict=False):
        for j, lv in enumerate(levels[line]):
            ms: list[float] = []
            errs: list[list[float]] = [[], []]
            for xv in levels[x]:
                sel = (data[x] == xv) & (data[line] == lv)
                m, lo, hi = bootstrap_ci(data.loc[sel, outcome.name].to_numpy(dtype=float), rng)
                ms.append(m)
                errs[0].append(m - lo if np.isfinite(m) else 0)
                errs[1].append(hi - m if np.isfinite(m) else 0)
            offset = (j - (len(levels[line]) - 1) / 2) * 0.06
            ax.errorbar(
                np.arange(len(ms)) + offset,
                ms,
                yerr=errs,
                marker="o",
                capsize=3,
                label=f"{_label(line)} = {lv}",
            )
        ax.set_xticks(range(len(levels[x])), levels[x])
        ax.set_xlabel(_label(x))
        ax.set_title(f"{outcome.title} ({outcome.unit})", fontsize=9)
        ax.grid(axis="y", alpha=0.3)
    for ax in list(axes.flat)[len(present) :]:
        ax.axis("off")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", ncol=len(labels), frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 0.93))
    name = f"interaction_{_safe(x)}_x_{_safe(line)}.png"
    fig.savefig(path / name, dpi=90)
    plt.close(fig)
    return name


def _safe(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "-", _label(text)).strip("-")


# ---------------------------------------------------------------- mixed models


@dataclass
class ModelResult:
    outcome: Outcome
    rows: list[tuple[str, float, float, float, float]]  # term, estimate, lo, hi, p
    group_var: float | None
    notes: list[str]
    method: str = "MixedLM (REML), random intercept per participant"


def _term(
    name: str, names: dict[str, str], reference: dict[str, str], covs: dict[str, str] | None = None
) -> str:
    if covs and name in covs:
        return f"{covs[name].replace('_', ' ')} (per step)"
    m = re.fullmatch(r"C\((f\d+)\)\[T\.(.*)\]", name)
    if m:
        factor = names[m.group(1)]
        return f"{_label(factor)} = {m.group(2)} (vs {reference[factor]})"
    return {"Intercept": "intercept (reference levels)", "Group Var": "participant variance"}.get(
        name, name
    )


def fit_formula(formula: str, d: pd.DataFrame, notes: list[str]) -> tuple[Any, str, float | None]:
    """The study's model of `d` (`model_data`): a mixed model with a random intercept per
    participant, or the plain regression with one participant or where the mixed model is
    degenerate (saying so in `notes`); the fit, its method and the participant variance. Raises
    what statsmodels raises on data it cannot fit."""
    import statsmodels.formula.api as smf

    if d["participant"].nunique() < 2:
        notes.append("one participant: no random intercept; ordinary least squares")
        return smf.ols(formula, d).fit(), "OLS (one participant)", None
    res = smf.mixedlm(formula, d, groups=d["participant"]).fit(reml=True)
    if not np.isfinite(np.asarray(res.bse)).all():
        # a degenerate fit (no residual or no participant variance) has no standard errors:
        # say so, and give the plain regression, which is what remains
        notes.append(
            "the mixed model is degenerate here (no standard errors: the factors explain "
            "the outcome almost exactly, or the participants do not differ); shown: "
            "ordinary least squares"
        )
        return smf.ols(formula, d).fit(), "OLS (degenerate MixedLM)", None
    return res, "MixedLM (REML), random intercept per participant", float(res.cov_re.iloc[0, 0])


@dataclass
class ModelData:
    """An outcome's data as the model sees it: `y`, `participant`, factors renamed `f0`, `f1`,
    ... (categorical, the study's first level the reference) and covariates `c0`, ...; the
    formula over those that vary."""

    d: pd.DataFrame
    formula: str
    names: dict[str, str]  # f0 -> the factor's key
    covariates: dict[str, str]  # c0 -> the covariate's column
    reference: dict[str, str]  # factor key -> its reference level
    notes: list[str]
    problem: str = ""  # why nothing can be fitted ("" if it can)


def model_data(
    data: pd.DataFrame,
    outcome: str,
    factors: list[str],
    levels: dict[str, list[str]],
    covariates: tuple[str, ...] = (),
) -> ModelData:
    """The study's model of one outcome (`y ~ C(f0) + C(f1) + ... + c0 ...`, a random intercept
    per participant): its data and formula, shared by the report and `hrc power`."""
    import pandas as pd

    notes: list[str] = []
    d = data[[outcome, "participant", *factors, *covariates]].dropna()
    d = d.rename(
        columns={
            outcome: "y",
            **{f: f"f{i}" for i, f in enumerate(factors)},
            **{c: f"c{i}" for i, c in enumerate(covariates)},
        }
    )
    for i in range(len(covariates)):
        d[f"c{i}"] = pd.to_numeric(d[f"c{i}"], errors="coerce")
    covs = [f"c{i}" for i in range(len(covariates)) if d[f"c{i}"].nunique() > 1]
    cov_names = {f"c{i}": c for i, c in enumerate(covariates)}
    names = {f"f{i}": f for i, f in enumerate(factors)}
    used = [f"f{i}" for i, f in enumerate(factors) if d[f"f{i}"].nunique() > 1]
    for key in names:
        if key not in used:
            notes.append(f"{_label(names[key])} has one level here: left out of the model")
    problem = ""
    if len(d) < 3:
        problem = f"{len(d)} trial(s): too few to fit"
    elif float(d["y"].std(ddof=0)) == 0.0:
        value = _fmt(float(d["y"].iloc[0]))
        problem = f"the same value ({value}) in every trial: nothing to model"
    for key in used:  # reference level = the study's first level
        order = [lv for lv in levels[names[key]] if lv in set(d[key])]
        d[key] = pd.Categorical(d[key], categories=order)
    reference = {names[k]: str(d[k].cat.categories[0]) for k in used}
    formula = "y ~ " + (" + ".join([*(f"C({k})" for k in used), *covs]) or "1")
    return ModelData(d, formula, names, cov_names, reference, notes, problem)


def fit_model(
    data: pd.DataFrame,
    outcome: Outcome,
    factors: list[str],
    levels: dict[str, list[str]],
    covariates: tuple[str, ...] = (),
) -> ModelResult:
    """One outcome's mixed model; every degenerate case gives notes, never an exception.
    `covariates`: numeric columns entered as they are (a live trial's order position)."""
    m = model_data(data, outcome.name, factors, levels, covariates)
    notes, d, formula, names, reference = m.notes, m.d, m.formula, m.names, m.reference
    cov_names = m.covariates
    if m.problem:
        return ModelResult(outcome, [], None, [*notes, m.problem])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            res, method, group_var = fit_formula(formula, d, notes)
        except (np.linalg.LinAlgError, ValueError, IndexError, ZeroDivisionError) as exc:
            return ModelResult(outcome, [], None, [*notes, f"model not fitted: {exc}"])
    texts = {str(w.message).split("\n")[0] for w in caught}
    if method.startswith("MixedLM") and any("boundary" in t for t in texts):
        notes.append(
            "the participant variance is estimated at or near 0 (the participants hardly differ "
            "beyond the factors): the effects are close to those of a plain regression"
        )
    if method.startswith("MixedLM") and not res.converged:
        notes.append("the fit did not converge: read the estimates with care")
    ci = res.conf_int()
    rows = []
    for term in res.params.index:
        if term == "Group Var":
            continue
        rows.append(
            (
                _term(term, names, reference, cov_names),
                float(res.params[term]),
                float(ci.loc[term, 0]),
                float(ci.loc[term, 1]),
                float(res.pvalues[term]),
            )
        )
    return ModelResult(outcome, rows, group_var, notes, method)


# ---------------------------------------------------------------- page

CSS = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1100px; color: #222;
       line-height: 1.4; padding: 0 1em; }
h1 { margin-bottom: 0.2em; } h2 { border-bottom: 2px solid #ddd; padding-bottom: 0.2em;
margin-top: 2em; } h3 { margin-bottom: 0.3em; }
table { border-collapse: collapse; margin: 0.5em 0 1em; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }
th { background: #f0f3f7; } td:first-child, th:first-child { text-align: left; }
.outcome { display: flex; gap: 1.5em; align-items: flex-start; flex-wrap: wrap; }
.note { color: #7a4b00; background: #fff6e0; border-left: 4px solid #e0a800;
        padding: 0.3em 0.7em; margin: 0.3em 0; font-size: 0.9em; }
.muted { color: #666; font-size: 0.9em; } pre { white-space: pre-wrap; margin: 0;
font-size: 0.85em; } .fail td { text-align: left; vertical-align: top; }
img { max-width: 100%; }
"""


def _participants_line(df: pd.DataFrame, data: pd.DataFrame) -> str:
    """How many participants, and who has no trial in the statistics (all skipped, say): they
    are not counted as if they had taken part."""
    everyone = set(df["participant"].astype(str))
    analysed = set(data["participant"].astype(str))
    line = f"{len(analysed)} participants with trials in the statistics"
    none = sorted(everyone - analysed)
    if none:
        line += f" ({len(none)} more with none: {html.escape(', '.join(none))})"
    return line


def _table(head: list[str], body: list[list[str]], cls: str = "") -> str:
    th = "".join(f"<th>{html.escape(h)}</th>" for h in head)
    trs = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in row) + "</tr>" for row in body)
    return f'<table class="{cls}"><tr>{th}</tr>{trs}</table>'


def analysis_frame(
    df: pd.DataFrame, meta: dict[str, Any]
) -> tuple[pd.DataFrame, list[str], dict[str, list[str]]]:
    """The trials the statistics use (ended ok, no practice), factor values as text and one
    column per outcome; the study's factors and their levels in the study's order. (`df` gets a
    `participant_kind` column if a table from before live participants has none.)"""
    factors = [f for f in meta.get("factors", {}) if f in df.columns]
    if "participant_kind" not in df.columns:  # a table from before live participants
        df["participant_kind"] = "simulated"
    practice = df["practice"].fillna(False).astype(bool) if "practice" in df.columns else False
    data = df[(df["outcome"] == "ok") & ~practice].copy()
    for f in factors:
        data[f] = data[f].map(str)
    for outcome in OUTCOMES:
        values = _outcome_values(data, outcome)
        if values is not None:
            data[outcome.name] = values
    return data, factors, {f: _levels(data, f, meta) for f in factors}


def write_report(sweep_dir: Path) -> Path:
    """Write `<sweep_dir>/report.html` and `<sweep_dir>/figures/`; return the page's path."""
    import matplotlib

    matplotlib.use("Agg")
    df, meta = _load(sweep_dir)
    figdir = sweep_dir / FIGURES
    figdir.mkdir(exist_ok=True)
    data, factors, levels = analysis_frame(df, meta)

    parts: list[str] = [f"<h1>Study {html.escape(str(meta.get('name')))}</h1>"]
    n_ok = int((df["outcome"] == "ok").sum())
    counts = df["outcome"].value_counts().to_dict()
    parts.append(
        f"<p class='muted'>{len(df)} trials: "
        + ", ".join(f"{v} {html.escape(str(k))}" for k, v in counts.items())
        + f"; {_participants_line(df, data)}; base scenario "
        f"<code>{html.escape(Path(str(meta.get('scenario', '?'))).name)}</code>. "
        f"Statistics use the {len(data)} trials that ended ok"
        + (f" ({n_ok - len(data)} practice trials left out)" if n_ok > len(data) else "")
        + ".</p>"
    )
    parts.append("<h2>Design</h2>")
    between = set(meta.get("between") or [])
    # with live participants: how they meet each factor (the simulated ones: crossed)
    live = bool(meta.get("live_participants"))
    rows = []
    for f in factors:
        row = [html.escape(f), html.escape(", ".join(levels[f]))]
        if live:
            row.append("between (one level each)" if f in between else "within (every level)")
        rows.append(row)
    parts.append(_table(["factor", "levels", *(["live participants"] if live else [])], rows))
    params = [c for c in df.columns if c.startswith("participant.") and c not in factors]
    people = df.drop_duplicates("participant").sort_values("participant")
    parts.append("<h3>Participants</h3>")
    parts.append(
        _table(
            ["participant", "kind", *[_label(c) for c in params]],
            [
                [
                    html.escape(str(r["participant"])),
                    html.escape(str(r["participant_kind"])),
                    *[_fmt(r[c]) for c in params],
                ]
                for _, r in people.iterrows()
            ],
        )
    )
    missing = [o.title for o in OUTCOMES if o.name not in data]
    if missing:
        parts.append(f"<p class='note'>Not in the table: {html.escape(', '.join(missing))}.</p>")

    parts.append("<h2>Outcomes by factor level</h2>")
    parts.append(
        "<p class='muted'>Means with 95 % bootstrap confidence intervals "
        f"({BOOTSTRAP_SAMPLES} resamples of the trials at each level).</p>"
    )
    if data.empty or not factors:
        parts.append(
            "<p class='note'>No trial ended ok (or the study varies nothing): "
            "nothing to summarise.</p>"
        )
        means: dict[str, Any] = {}
    else:
        means = _main_effects(data, factors, levels, figdir)
    for outcome in OUTCOMES:
        if outcome.name not in means:
            continue
        note = f" <span class='muted'>({html.escape(outcome.note)})</span>" if outcome.note else ""
        values = data[outcome.name].dropna()
        if len(values) and float(values.std(ddof=0)) == 0.0:
            parts.append(
                f"<h3 id='{outcome.name}'>{outcome.title} ({outcome.unit}){note}</h3>"
                f"<p>{_fmt(float(values.iloc[0]))} in every trial.</p>"
            )
            continue
        body = [
            [html.escape(r[0]), str(r[1]), _fmt(r[2]), f"[{_fmt(r[3])}, {_fmt(r[4])}]"]
            for r in means[outcome.name]
        ]
        parts.append(
            f"<h3 id='{outcome.name}'>{outcome.title} ({outcome.unit}){note}</h3>"
            "<div class='outcome'>"
            + _table(["level", "n", "mean", "95 % CI"], body)
            + f"<img src='{FIGURES}/means_{outcome.name}.png' alt='{outcome.title}'></div>"
        )

    parts.append("<h2>Interactions</h2>")
    if len(factors) < 2 or data.empty:
        parts.append("<p class='note'>One factor only (or no trial ok): no interaction.</p>")
    else:
        parts.append(
            "<p class='muted'>Outcomes that vary, by the speed factor (or the first "
            "factor) and each other factor; means with 95 % bootstrap CIs.</p>"
        )
        speed = next((f for f in factors if "speed" in f), factors[0])
        for other in [f for f in factors if f != speed]:
            name = _interaction(data, speed, other, levels, figdir)
            if not name:
                parts.append("<p>No outcome varies: nothing to plot.</p>")
                continue
            parts.append(
                f"<h3>{html.escape(_label(speed))} {TIMES} {html.escape(_label(other))}</h3>"
                f"<img src='{FIGURES}/{name}' alt='interaction'>"
            )

    parts.append("<h2>Mixed-effects models</h2>")
    parts.append(
        "<p class='muted'>Per outcome: <code>outcome ~ factors</code> (each factor categorical, "
        "its first level the reference), random intercept per participant (statsmodels MixedLM, "
        "REML). Estimates are differences from the reference, with 95 % Wald CIs.</p>"
    )
    for outcome in OUTCOMES:
        if outcome.name not in data:
            continue
        m = fit_model(data, outcome, factors, levels)
        parts.append(f"<h3>{outcome.title} ({outcome.unit})</h3>")
        parts.extend(f"<p class='note'>{html.escape(n)}</p>" for n in m.notes)
        if m.rows:
            body = [
                [html.escape(t), _fmt(e), f"[{_fmt(lo)}, {_fmt(hi)}]", _pval(p)]
                for t, e, lo, hi, p in m.rows
            ]
            parts.append(_table(["term", "estimate", "95 % CI", "p"], body))
            var = "" if m.group_var is None else f"; participant variance {_fmt(m.group_var)}"
            parts.append(f"<p class='muted'>{html.escape(m.method)}{var}</p>")

    parts.extend(_kinds_section(data, factors, levels, figdir))
    parts.extend(_questionnaire_section(data, df, meta, factors, levels, figdir))

    parts.append("<h2>Failed trials</h2>")
    bad = df[df["outcome"] != "ok"]
    if bad.empty:
        parts.append("<p>None: every trial ended ok.</p>")
    else:
        body = [
            [
                html.escape(str(r.trial))
                + (f" <span class='muted'>({html.escape(str(r.participant))})</span>"),
                html.escape(str(r.outcome)),
                f"<pre>{html.escape(str(r.reason)[:1200])}</pre>",
            ]
            for r in bad.itertuples()
        ]
        parts.append(_table(["trial", "outcome", "reason"], body, "fail"))

    parts.extend(_notes_section(df))

    title = html.escape(f"Study {meta.get('name')}")
    head = f"<meta charset='utf-8'><title>{title}</title><style>{CSS}</style>"
    page = f"<!doctype html><html><head>{head}</head><body>" + "\n".join(parts) + "</body></html>\n"
    out = sweep_dir / "report.html"
    out.write_text(page, encoding="utf-8")
    return out


# ---------------------------------------------------------------- people and simulations


def _condition_order(
    data: pd.DataFrame, factors: list[str], levels: dict[str, list[str]]
) -> list[str]:
    """The conditions present, in the study's order of the factor levels."""
    rows = data[factors].astype(str).drop_duplicates().itertuples(index=False)
    rank = sorted(
        rows,
        key=lambda r: [
            levels[f].index(v) if v in levels[f] else 99 for f, v in zip(factors, r, strict=True)
        ],
    )
    return [", ".join(f"{_label(f)} = {v}" for f, v in zip(factors, r, strict=True)) for r in rank]


def _condition(data: pd.DataFrame, factors: list[str]) -> pd.Series:
    return (
        data[factors]
        .astype(str)
        .agg(
            lambda row: ", ".join(f"{_label(f)} = {v}" for f, v in zip(factors, row, strict=True)),
            axis=1,
        )
    )


def _notes_section(df: pd.DataFrame) -> list[str]:
    """The experimenter's notes and flags on live trials (`n`, `f` in hrc session): nothing is
    left out for them; they are listed for a person to look at."""
    if "notes" not in df and "flagged" not in df:
        return []
    flagged = df["flagged"].fillna(False).astype(bool) if "flagged" in df else False
    noted = df["notes"].notna() if "notes" in df else False
    marked = df[flagged | noted]
    if marked.empty:
        return []
    body = [
        [
            html.escape(str(r["trial"]))
            + f" <span class='muted'>({html.escape(str(r['participant']))})</span>",
            "flagged" if bool(r.get("flagged")) is True else "",
            html.escape(str(r["notes"])) if isinstance(r.get("notes"), str) else "",
        ]
        for _, r in marked.iterrows()
    ]
    return [
        "<h2>The experimenter's notes</h2>",
        "<p class='muted'>Trials the experimenter flagged (<code>f</code>) or wrote a note on "
        "(<code>n</code>) during <code>hrc session</code>; the statistics above include them as "
        "they are.</p>",
        _table(["trial", "flag", "notes"], body),
    ]


def _kinds_section(
    data: pd.DataFrame, factors: list[str], levels: dict[str, list[str]], figdir: Path
) -> list[str]:
    """Live, fitted (their twins), simulated and replayed participants side by side: each
    outcome by condition and kind, with CIs; for the live trials, the mixed model with the
    order position."""
    import matplotlib.pyplot as plt

    kinds = [
        k for k in ("live", "fitted", "simulated", "replay") if k in set(data["participant_kind"])
    ]
    if "live" not in kinds:
        return []
    out = ["<h2>Live and simulated participants</h2>"]
    out.append(
        "<p class='muted'>Each outcome by condition, one column per kind of participant: mean "
        "[95 % bootstrap CI] (n). Live: people in the headset or at the desktop "
        "(<code>hrc session</code>); fitted: each person's simulated twin, the scripted "
        "participant with the parameters <code>hrc fit</code> found in their recordings; "
        "simulated: the scripted participant; replay: recorded movements that do not react.</p>"
    )
    conds = _condition(data, factors) if factors else None
    order = _condition_order(data, factors, levels) if factors else ["(all)"]
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    for outcome in OUTCOMES:
        if outcome.name not in data:
            continue
        body: list[list[str]] = []
        fig, ax = plt.subplots(figsize=(max(4.0, 1.4 * len(order)), 2.6))
        for j, kind in enumerate(kinds):
            ms: list[float] = []
            errs: list[list[float]] = [[], []]
            for c in order:
                sel = data["participant_kind"] == kind
                if conds is not None:
                    sel &= conds == c
                m, lo, hi = bootstrap_ci(data.loc[sel, outcome.name].to_numpy(dtype=float), rng)
                ms.append(m)
                errs[0].append(m - lo if np.isfinite(m) else 0)
                errs[1].append(hi - m if np.isfinite(m) else 0)
            x = np.arange(len(order)) + (j - (len(kinds) - 1) / 2) * 0.12
            ax.errorbar(x, ms, yerr=errs, fmt="o", capsize=4, label=kind)
        for c in order:
            row = [html.escape(c)]
            for kind in kinds:
                sel = data["participant_kind"] == kind
                if conds is not None:
                    sel &= conds == c
                vals = data.loc[sel, outcome.name].to_numpy(dtype=float)
                m, lo, hi = bootstrap_ci(vals, rng)
                n = int(np.isfinite(vals).sum())
                row.append(f"{_fmt(m)} [{_fmt(lo)}, {_fmt(hi)}] ({n})" if n else DASH)
            body.append(row)
        ax.set_xticks(range(len(order)), [c.replace(", ", "\n") for c in order], fontsize=7)
        ax.set_ylabel(outcome.unit)
        ax.legend(fontsize=7, frameon=False)
        ax.grid(axis="y", alpha=0.3)
        fig.tight_layout()
        name = f"kinds_{outcome.name}.png"
        fig.savefig(figdir / name, dpi=90)
        plt.close(fig)
        out.append(
            f"<h3>{outcome.title} ({outcome.unit})</h3><div class='outcome'>"
            + _table(["condition", *kinds], body)
            + f"<img src='{FIGURES}/{name}' alt='{outcome.title} by kind'></div>"
        )
    live = data[data["participant_kind"] == "live"]
    out.append("<h3>Live trials: mixed models with the order position</h3>")
    out.append(
        "<p class='muted'><code>outcome ~ factors + order_position</code>, random intercept per "
        "participant: the order position (1, 2, ... in the participant's session) takes up "
        "learning and fatigue that counterbalancing spreads over the conditions.</p>"
    )
    for outcome in OUTCOMES:
        if outcome.name not in live:
            continue
        model = fit_model(live, outcome, factors, levels, ("order_position",))
        out.append(_model_html(outcome.title, outcome.unit, model))
    return out


def _model_html(title: str, unit: str, m: ModelResult) -> str:
    parts = [f"<h4>{html.escape(title)} ({html.escape(unit)})</h4>"]
    parts.extend(f"<p class='note'>{html.escape(n)}</p>" for n in m.notes)
    if m.rows:
        body = [
            [html.escape(t), _fmt(e), f"[{_fmt(lo)}, {_fmt(hi)}]", _pval(p)]
            for t, e, lo, hi, p in m.rows
        ]
        parts.append(_table(["term", "estimate", "95 % CI", "p"], body))
        var = "" if m.group_var is None else f"; participant variance {_fmt(m.group_var)}"
        parts.append(f"<p class='muted'>{html.escape(m.method)}{var}</p>")
    return "".join(parts)


def _questionnaire_section(
    data: pd.DataFrame,
    df: pd.DataFrame,
    meta: dict[str, Any],
    factors: list[str],
    levels: dict[str, list[str]],
    figdir: Path,
) -> list[str]:
    """Questionnaire scores by condition with CIs (after each trial), per participant (at the
    end), and a mixed model of each after-trial score with the order position."""
    import matplotlib.pyplot as plt

    qs = meta.get("questionnaires") or {}
    if not qs:
        return []
    out = ["<h2>Questionnaires</h2>"]
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    live = data[data["participant_kind"] == "live"]
    conds = _condition(live, factors) if factors and len(live) else None
    order = _condition_order(live, factors, levels) if conds is not None else []
    for qid, q in qs.items():
        cols = [f"q.{qid}.{s}" for s in [*q.get("scores", []), *q.get("items", [])]]
        cols = [c for c in cols if c in df.columns]
        title = html.escape(str(q.get("title", qid)))
        if not cols:
            out.append(f"<h3>{title}</h3><p class='note'>No answers yet.</p>")
            continue
        when = q.get("when")
        if when in ("end", "before_session"):
            people = df[df["participant_kind"] == "live"].drop_duplicates("participant")
            body = []
            for c in cols:
                vals = pd_numeric(people[c])
                m, lo, hi = bootstrap_ci(vals, rng)
                body.append(
                    [
                        html.escape(c),
                        str(int(np.isfinite(vals).sum())),
                        _fmt(m),
                        f"[{_fmt(lo)}, {_fmt(hi)}]",
                    ]
                )
            out.append(
                f"<h3>{title} <span class='muted'>("
                + ("before the session" if when == "before_session" else "end of the session")
                + ", one answer per participant)</span></h3>"
                + _table(["column", "n", "mean", "95 % CI"], body)
            )
            continue
        head = ["column", *order]
        body = []
        for c in cols:
            row = [html.escape(c)]
            for cond in order:
                assert conds is not None
                vals = pd_numeric(live.loc[conds == cond, c])
                m, lo, hi = bootstrap_ci(vals, rng)
                n = int(np.isfinite(vals).sum())
                row.append(f"{_fmt(m)} [{_fmt(lo)}, {_fmt(hi)}] ({n})" if n else DASH)
            body.append(row)
        out.append(
            f"<h3>{title} <span class='muted'>("
            + ("before" if when == "before_trial" else "after")
            + " each trial; practice left out)</span></h3>"
            "<p class='muted'>Mean [95 % bootstrap CI] (n) by condition.</p>" + _table(head, body)
        )
        scores = [c for c in cols if c.rsplit(".", 1)[1] in q.get("scores", [])]
        if scores and order:
            fig, ax = plt.subplots(figsize=(max(4.0, 1.4 * len(order)), 2.6))
            for j, c in enumerate(scores):
                ms: list[float] = []
                errs: list[list[float]] = [[], []]
                for cond in order:
                    assert conds is not None
                    m, lo, hi = bootstrap_ci(pd_numeric(live.loc[conds == cond, c]), rng)
                    ms.append(m)
                    errs[0].append(m - lo if np.isfinite(m) else 0)
                    errs[1].append(hi - m if np.isfinite(m) else 0)
                x = np.arange(len(order)) + (j - (len(scores) - 1) / 2) * 0.1
                ax.errorbar(x, ms, yerr=errs, fmt="o", capsize=4, label=c)
            ax.set_xticks(range(len(order)), [c.replace(", ", "\n") for c in order], fontsize=7)
            ax.legend(fontsize=7, frameon=False)
            ax.grid(axis="y", alpha=0.3)
            fig.tight_layout()
            name = f"questionnaire_{_safe(qid)}.png"
            fig.savefig(figdir / name, dpi=90)
            plt.close(fig)
            out.append(f"<img src='{FIGURES}/{name}' alt='{title} by condition'>")
            for c in scores:
                d = live.assign(**{c: pd_numeric(live[c])})
                model = fit_model(
                    d, Outcome(c, c, "", re.escape(c)), factors, levels, ("order_position",)
                )
                out.append(_model_html(f"{c} ~ factors + order position", "score", model))
    return out


def pd_numeric(values: Any) -> npt.NDArray[np.float64]:
    import pandas as pd

    out: npt.NDArray[np.float64] = pd.to_numeric(values, errors="coerce").to_numpy(dtype=float)
    return out
