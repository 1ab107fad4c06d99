"""Questionnaires asked in the participant's page (docs/studies.md, "Questionnaires"): the
built-in NASA-TLX and simulator sickness questionnaire, and the study author's own (Likert
items, single choice, free text), with their scores.

    q = builtin("tlx")
    q.score({"mental": 55, "physical": 20, ...})   # {"raw": 37.5}

Every answer and score becomes a column of the study's table, ``q.<questionnaire>.<item>`` and
``q.<questionnaire>.<score>``.
"""

from __future__ import annotations

import itertools
import re
from dataclasses import dataclass, field, replace
from typing import Any

KINDS = ("scale", "likert", "choice", "text")
SCORES = ("mean", "sum", "none")
_ID = re.compile(r"^[a-z][a-z0-9_]*$")


@dataclass(frozen=True)
class Item:
    """One question. ``scale``: 0-100 in steps of 5 between two anchors (the TLX's 21
    gradations); ``likert``: ``points`` boxes valued ``start``..``start + points - 1``, with a
    label per point or anchors at the ends; ``choice``: one of ``options``; ``text``: free text."""

    id: str
    text: str
    kind: str
    anchors: tuple[str, str] = ("", "")
    points: int = 0
    start: int = 1
    labels: tuple[str, ...] = ()
    options: tuple[str, ...] = ()
    reverse: bool = False
    required: bool = True
    # asked only when each earlier item named has one of these answers (branching); () always
    show_if: tuple[tuple[str, tuple[Any, ...]], ...] = ()

    def shown(self, answers: dict[str, Any]) -> bool:
        return all(answers.get(iid) in values for iid, values in self.show_if)

    def check(self, value: Any) -> str | None:
        """A problem with an answer, or None."""
        if value is None:
            return None if not self.required else "missing"
        if self.kind == "scale":
            ok = isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= 100
            return None if ok and value % 5 == 0 else "should be 0, 5, ..., 100"
        if self.kind == "likert":
            lo, hi = self.start, self.start + self.points - 1
            ok = isinstance(value, int) and not isinstance(value, bool) and lo <= value <= hi
            return None if ok else f"should be an integer {lo}..{hi}"
        if self.kind == "choice":
            return None if value in self.options else f"should be one of {list(self.options)}"
        ok = isinstance(value, str) and len(value) <= 2000
        return None if ok else "should be text of at most 2000 characters"

    def to_wire(self) -> dict[str, Any]:
        d: dict[str, Any] = {"id": self.id, "text": self.text, "kind": self.kind}
        d["required"] = self.required
        if self.kind in ("scale", "likert"):
            d["anchors"] = list(self.anchors)
        if self.kind == "likert":
            d.update(points=self.points, start=self.start, labels=list(self.labels))
        if self.kind == "choice":
            d["options"] = list(self.options)
        if self.show_if:
            d["show_if"] = {iid: list(values) for iid, values in self.show_if}
        return d


@dataclass(frozen=True)
class Questionnaire:
    id: str
    title: str
    intro: str
    items: tuple[Item, ...]
    scoring: str  # "tlx" | "ssq" | "mean" | "sum" | "none"
    weighted: bool = False  # NASA-TLX: the 15 pairwise comparisons
    source: str = ""  # where the items come from (cited in docs/studies.md)

    def check(self, answers: dict[str, Any]) -> list[str]:
        problems = [f"{k}: not an item" for k in answers if k not in self.item_ids()]
        for item in self.items:
            if not item.shown(answers):  # not asked: no answer may come
                if answers.get(item.id) is not None:
                    problems.append(f"{item.id}: not asked with the answers given before it")
                continue
            p = item.check(answers.get(item.id))
            if p:
                problems.append(f"{item.id}: {p}")
        return problems

    def item_ids(self) -> list[str]:
        return [i.id for i in self.items]

    def score_names(self) -> list[str]:
        if self.scoring == "tlx":
            return ["raw", "weighted"] if self.weighted else ["raw"]
        if self.scoring == "ssq":
            return list(SSQ_SCORES)
        return [] if self.scoring == "none" else [self.scoring]

    def score(self, answers: dict[str, Any]) -> dict[str, float | None]:
        """The questionnaire's scores from its answers (None where an answer is missing)."""
        if self.scoring == "tlx":
            return _tlx(answers, self.weighted)
        if self.scoring == "ssq":
            return _ssq(answers)
        if self.scoring == "none":
            return {}
        values: list[float] = []
        for item in self.items:
            v = answers.get(item.id)
            if item.kind not in ("scale", "likert") or not item.shown(answers):
                continue
            if not isinstance(v, (int, float)):
                return {self.scoring: None}
            if item.reverse:
                v = (
                    (item.start + item.points - 1 + item.start - v)
                    if item.kind == "likert"
                    else 100 - v
                )
            values.append(float(v))
        if not values:
            return {self.scoring: None}
        total = sum(values)
        return {self.scoring: round(total / len(values) if self.scoring == "mean" else total, 4)}

    def to_wire(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "title": self.title,
            "intro": self.intro,
            "items": [i.to_wire() for i in self.items],
        }


# ---------------------------------------------------------------- NASA-TLX

# Hart & Staveland (1988); the raw TLX (no weighting) as in Hart (2006). Anchors as on the NASA
# paper form: "Very Low"/"Very High", for performance "Perfect"/"Failure".
TLX = (
    ("mental", "Mental Demand", "How mentally demanding was the task?"),
    ("physical", "Physical Demand", "How physically demanding was the task?"),
    ("temporal", "Temporal Demand", "How hurried or rushed was the pace of the task?"),
    (
        "performance",
        "Performance",
        "How successful were you in accomplishing what you were asked to do?",
    ),
    ("effort", "Effort", "How hard did you have to work to accomplish your level of performance?"),
    (
        "frustration",
        "Frustration",
        "How insecure, discouraged, irritated, stressed, and annoyed were you?",
    ),
)


def tlx_pairs() -> list[tuple[str, str]]:
    """The 15 pairwise comparisons of the weighted TLX."""
    return list(itertools.combinations([d[0] for d in TLX], 2))


def _tlx_questionnaire(qid: str, weighted: bool) -> Questionnaire:
    items = [
        Item(
            key,
            f"{name}: {question}",
            "scale",
            ("Perfect", "Failure") if key == "performance" else ("Very Low", "Very High"),
        )
        for key, name, question in TLX
    ]
    names = {k: n for k, n, _ in TLX}
    if weighted:
        for a, b in tlx_pairs():
            items.append(
                Item(
                    f"pair_{a}_{b}",
                    "Which contributed more to the workload of this task?",
                    "choice",
                    options=(names[a], names[b]),
                )
            )
    return Questionnaire(
        qid,
        "NASA Task Load Index",
        "Rate the trial you just did on each scale (left: low, right: high).",
        tuple(items),
        "tlx",
        weighted,
        "Hart & Staveland 1988; Hart 2006",
    )


def _tlx(answers: dict[str, Any], weighted: bool) -> dict[str, float | None]:
    ratings = [answers.get(k) for k, _, _ in TLX]
    if not all(isinstance(r, (int, float)) for r in ratings):
        out: dict[str, float | None] = {"raw": None}
        if weighted:
            out["weighted"] = None
        return out
    vals = [float(r) for r in ratings if isinstance(r, (int, float))]
    out = {"raw": round(sum(vals) / len(vals), 4)}
    if weighted:
        names = {n: k for k, n, _ in TLX}
        weights = dict.fromkeys(names.values(), 0)
        for a, b in tlx_pairs():
            chosen = answers.get(f"pair_{a}_{b}")
            if chosen not in names:
                out["weighted"] = None
                return out
            weights[names[chosen]] += 1
        total = sum(float(answers[k]) * weights[k] for k, _, _ in TLX)
        out["weighted"] = round(total / 15, 4)
    return out


# ---------------------------------------------------------------- simulator sickness

# Kennedy, Lane, Berbaum & Lilienthal (1993): 16 symptoms rated none/slight/moderate/severe
# (0-3); each loads on nausea (N), oculomotor (O) and/or disorientation (D).
SSQ = (
    ("general_discomfort", "General discomfort", "NO"),
    ("fatigue", "Fatigue", "O"),
    ("headache", "Headache", "O"),
    ("eye_strain", "Eye strain", "O"),
    ("difficulty_focusing", "Difficulty focusing", "OD"),
    ("salivation", "Salivation increasing", "N"),
    ("sweating", "Sweating", "N"),
    ("nausea", "Nausea", "ND"),
    ("difficulty_concentrating", "Difficulty concentrating", "NO"),
    ("fullness_of_head", "Fullness of the head", "D"),
    ("blurred_vision", "Blurred vision", "OD"),
    ("dizziness_eyes_open", "Dizziness with eyes open", "D"),
    ("dizziness_eyes_closed", "Dizziness with eyes closed", "D"),
    ("vertigo", "Vertigo", "D"),
    ("stomach_awareness", "Stomach awareness", "N"),
    ("burping", "Burping", "N"),
)
SSQ_WEIGHTS = {"N": 9.54, "O": 7.58, "D": 13.92}
SSQ_TOTAL_WEIGHT = 3.74
# its scores' names, apart from its items' ("nausea" is a symptom and a subscale: the table
# has a column for each)
SSQ_SCORES = ("nausea_score", "oculomotor_score", "disorientation_score", "total_score")


def _ssq_questionnaire(qid: str) -> Questionnaire:
    labels = ("None", "Slight", "Moderate", "Severe")
    items = tuple(
        Item(key, text, "likert", points=4, start=0, labels=labels) for key, text, _ in SSQ
    )
    return Questionnaire(
        qid,
        "Simulator sickness",
        "How much is each symptom affecting you right now?",
        items,
        "ssq",
        source="Kennedy, Lane, Berbaum & Lilienthal 1993",
    )


def _ssq(answers: dict[str, Any]) -> dict[str, float | None]:
    sums = dict.fromkeys("NOD", 0.0)
    for key, _, loads in SSQ:
        v = answers.get(key)
        if not isinstance(v, (int, float)):
            return dict.fromkeys(SSQ_SCORES)
        for c in loads:
            sums[c] += float(v)
    n, o, d, total = SSQ_SCORES
    return {
        n: round(sums["N"] * SSQ_WEIGHTS["N"], 4),
        o: round(sums["O"] * SSQ_WEIGHTS["O"], 4),
        d: round(sums["D"] * SSQ_WEIGHTS["D"], 4),
        total: round((sums["N"] + sums["O"] + sums["D"]) * SSQ_TOTAL_WEIGHT, 4),
    }


# ---------------------------------------------------------------- demographics

FREQUENCY = ("never", "once or twice", "a few times a year", "monthly", "weekly or more")


def _demographics_questionnaire(qid: str) -> Questionnaire:
    """Who took part: asked once (live.before_session); ranges rather than exact figures, and
    every item may be left out but handedness (it decides the hand the task is set up for)."""

    def choice(iid: str, text: str, options: tuple[str, ...], required: bool = False) -> Item:
        return Item(iid, text, "choice", options=options, required=required)

    items = (
        choice("age", "Your age", ("18-24", "25-34", "35-44", "45-54", "55-64", "65 or older")),
        choice("gender", "Your gender", ("woman", "man", "non-binary", "prefer not to say")),
        choice("handedness", "Your writing hand", ("right", "left", "either"), required=True),
        choice("vr_experience", "How often have you used a VR headset?", FREQUENCY),
        choice("robot_experience", "How often have you worked beside a robot arm?", FREQUENCY),
    )
    return Questionnaire(qid, "About you", "A few questions about you.", items, "none")


BUILTIN = {"tlx": "nasa_tlx", "ssq": "ssq", "demographics": "demographics"}


def builtin(qid: str, kind: str | None = None, weighted: bool = False) -> Questionnaire:
    kind = kind or BUILTIN[qid]
    if kind == "demographics":
        return _demographics_questionnaire(qid)
    return _tlx_questionnaire(qid, weighted) if kind == "nasa_tlx" else _ssq_questionnaire(qid)


# ---------------------------------------------------------------- the study author's own


def parse(qid: str, spec: Any, problems: list[str]) -> Questionnaire | None:
    """A questionnaire from its table in the study file; problems are appended."""
    where = f"questionnaires.{qid}"
    if not _ID.match(qid):
        problems.append(f"{where}: a name of lower-case letters, digits and '_'")
        return None
    if not isinstance(spec, dict):
        problems.append(f"{where}: should be a table")
        return None
    kind = spec.get("kind", "likert")
    if kind in ("nasa_tlx", "ssq", "demographics"):
        for extra in sorted(set(spec) - {"kind", "weighted"}):
            problems.append(f"{where}.{extra}: unknown key for a {kind} questionnaire")
        weighted = spec.get("weighted", False)
        if not isinstance(weighted, bool) or (weighted and kind == "ssq"):
            problems.append(f"{where}.weighted: true or false (nasa_tlx only)")
            weighted = False
        return builtin(qid, kind, weighted)
    allowed = {"kind", "title", "text", "points", "start", "anchors", "labels", "items", "score"}
    for extra in sorted(set(spec) - allowed):
        problems.append(f"{where}.{extra}: unknown key")
    if kind not in KINDS:
        problems.append(
            f"{where}.kind: one of nasa_tlx, ssq, demographics, {', '.join(KINDS)} (the "
            f"items' kind; got {kind!r})"
        )
        return None
    defaults = {k: spec[k] for k in ("points", "start", "anchors", "labels") if k in spec}
    raw_items = spec.get("items")
    if not isinstance(raw_items, list) or not raw_items:
        problems.append(f"{where}.items: a list of items ({{ id = ..., text = ... }})")
        return None
    items: list[Item] = []
    seen: set[str] = set()
    for i, raw in enumerate(raw_items):
        item = _item(f"{where}.items[{i}]", raw, kind, defaults, problems)
        if item is None:
            continue
        if isinstance(raw, dict) and "show_if" in raw:
            item = replace(
                item, show_if=_show_if(f"{where}.items[{i}]", raw["show_if"], items, problems)
            )
        if item.id in seen:
            problems.append(f"{where}.items[{i}].id: {item.id!r} is used twice")
        seen.add(item.id)
        items.append(item)
    score = spec.get(
        "score", "mean" if any(i.kind in ("scale", "likert") for i in items) else "none"
    )
    if score not in SCORES:
        problems.append(f"{where}.score: one of {', '.join(SCORES)} (got {score!r})")
        score = "none"
    elif score in seen:  # its column would be the item's (q.<questionnaire>.<name>)
        problems.append(
            f"{where}: an item is named {score!r}, as the questionnaire's score: rename the item"
        )
    title = spec.get("title", qid)
    text = spec.get("text", "")
    if not isinstance(title, str) or not isinstance(text, str):
        problems.append(f"{where}: title and text should be text")
        title, text = qid, ""
    return Questionnaire(qid, title, text, tuple(items), score)


def _show_if(
    where: str, raw: Any, earlier: list[Item], problems: list[str]
) -> tuple[tuple[str, tuple[Any, ...]], ...]:
    """`show_if = { <earlier item> = <answer or [answers]>, ... }`: the item is asked only when
    each of those items has one of those answers."""
    if not isinstance(raw, dict) or not raw:
        problems.append(f"{where}.show_if: a table {{ <earlier item> = <answer or [answers]> }}")
        return ()
    before = {i.id: i for i in earlier}
    out: list[tuple[str, tuple[Any, ...]]] = []
    for iid, want in raw.items():
        values = tuple(want) if isinstance(want, list) else (want,)
        item = before.get(iid)
        if item is None:
            problems.append(f"{where}.show_if.{iid}: not an item before this one")
            continue
        bad = [v for v in values if item.check(v) is not None]
        if bad or not values:
            problems.append(
                f"{where}.show_if.{iid}: {bad[0] if bad else '[]'!r} is not an answer to it"
            )
            continue
        out.append((iid, values))
    return tuple(out)


def _item(
    where: str, raw: Any, kind: str, defaults: dict[str, Any], problems: list[str]
) -> Item | None:
    if not isinstance(raw, dict):
        problems.append(f"{where}: should be a table {{ id = ..., text = ... }}")
        return None
    allowed = {"id", "text", "kind", "points", "start", "anchors", "labels", "options"}
    allowed |= {"reverse", "required", "show_if"}
    for extra in sorted(set(raw) - allowed):
        problems.append(f"{where}.{extra}: unknown key")
    spec = {**defaults, **raw}
    iid, text = spec.get("id"), spec.get("text")
    kind = spec.get("kind", kind)
    n0 = len(problems)
    if not isinstance(iid, str) or not _ID.match(iid):
        problems.append(f"{where}.id: lower-case letters, digits and '_' (got {iid!r})")
    if not isinstance(text, str) or not text.strip():
        problems.append(f"{where}.text: the question, as text")
    if kind not in KINDS:
        problems.append(f"{where}.kind: one of {', '.join(KINDS)} (got {kind!r})")
    points = spec.get("points", 5 if kind == "likert" else 0)
    start = spec.get("start", 1)
    anchors = spec.get("anchors", ["", ""])
    labels = spec.get("labels", [])
    options = spec.get("options", [])
    if kind == "likert":
        if isinstance(points, bool) or not isinstance(points, int) or not 2 <= points <= 11:
            problems.append(f"{where}.points: an integer 2..11 (got {points!r})")
        if isinstance(start, bool) or not isinstance(start, int):
            problems.append(f"{where}.start: an integer (the first point's value)")
        if labels and (
            not isinstance(labels, list)
            or len(labels) != points
            or not all(isinstance(x, str) for x in labels)
        ):
            problems.append(f"{where}.labels: one text per point ({points})")
    if kind in ("likert", "scale") and (
        not isinstance(anchors, list)
        or len(anchors) != 2
        or not all(isinstance(a, str) for a in anchors)
    ):
        problems.append(f"{where}.anchors: two texts, the low and the high end")
    if kind == "choice" and (
        not isinstance(options, list)
        or len(options) < 2
        or not all(isinstance(o, str) and o for o in options)
        or len(set(options)) != len(options)
    ):
        problems.append(f"{where}.options: two or more different texts")
    for flag in ("reverse", "required"):
        if flag in spec and not isinstance(spec[flag], bool):
            problems.append(f"{where}.{flag}: true or false")
    if len(problems) > n0 or not isinstance(iid, str) or not isinstance(text, str):
        return None
    return Item(
        iid,
        text.strip(),
        kind,
        (anchors[0], anchors[1]) if kind in ("likert", "scale") else ("", ""),
        points if kind == "likert" else 0,
        start if kind == "likert" else 1,
        tuple(labels) if kind == "likert" else (),
        tuple(options) if kind == "choice" else (),
        bool(spec.get("reverse", False)),
        bool(spec.get("required", kind != "text")),
    )


@dataclass
class Catalogue:
    """The questionnaires a study can ask, by id."""

    by_id: dict[str, Questionnaire] = field(default_factory=dict)

    def get(self, qid: str) -> Questionnaire | None:
        if qid in self.by_id:
            return self.by_id[qid]
        return builtin(qid) if qid in BUILTIN else None
