"""Questionnaire items, checks and scores (hrc.study.questionnaires)."""

from __future__ import annotations

import pytest

from hrc.study.questionnaires import SSQ, builtin, parse, tlx_pairs
from hrc.study.table import answer_columns

TLX = {
    "mental": 55,
    "physical": 20,
    "temporal": 40,
    "performance": 25,
    "effort": 50,
    "frustration": 10,
}


def test_raw_tlx_is_the_mean_of_the_six_scales() -> None:
    q = builtin("tlx")
    assert q.item_ids() == list(TLX)
    assert q.check(TLX) == []
    assert q.score(TLX) == {"raw": 33.3333}


def test_weighted_tlx_weighs_each_scale_by_the_pairs_it_won() -> None:
    problems: list[str] = []
    q = parse("tlx_w", {"kind": "nasa_tlx", "weighted": True}, problems)
    assert not problems and q is not None
    assert len(tlx_pairs()) == 15
    # the first of each pair wins: mental 5 times, physical 4, ... frustration never
    answers = dict(TLX)
    for item in q.items:
        if item.kind == "choice":
            answers[item.id] = item.options[0]
    assert q.check(answers) == []
    weighted = (55 * 5 + 20 * 4 + 40 * 3 + 25 * 2 + 50 * 1 + 10 * 0) / 15
    assert q.score(answers) == {"raw": 33.3333, "weighted": round(weighted, 4)}


def test_ssq_scores_use_the_published_weights() -> None:
    q = builtin("ssq")
    assert len(q.items) == 16
    none = {k: 0 for k, _, _ in SSQ}
    assert q.score(none) == {
        "nausea_score": 0.0,
        "oculomotor_score": 0.0,
        "disorientation_score": 0.0,
        "total_score": 0.0,
    }
    # nausea (N, D) rated 2: N sum 2, D sum 2
    one = {**none, "nausea": 2}
    s = q.score(one)
    assert s["nausea_score"] == round(2 * 9.54, 4)
    assert s["disorientation_score"] == round(2 * 13.92, 4)
    assert s["oculomotor_score"] == 0 and s["total_score"] == round(4 * 3.74, 4)
    # the table's columns: the symptom's answer and the subscale, each in its own (the
    # subscale took the item's column, and the answer was lost)
    columns = answer_columns({"ssq": one}, {"ssq": s})
    assert columns["q.ssq.nausea"] == 2 and columns["q.ssq.nausea_score"] == s["nausea_score"]
    assert len(columns) == len(q.items) + len(q.score_names())
    # every cluster has seven symptoms
    for c in "NOD":
        assert sum(c in loads for _, _, loads in SSQ) == 7


def test_answers_out_of_range_or_missing_are_named() -> None:
    q = builtin("tlx")
    bad = {**TLX, "mental": 57, "effort": 101}
    del bad["frustration"]
    assert q.check(bad) == [
        "mental: should be 0, 5, ..., 100",
        "effort: should be 0, 5, ..., 100",
        "frustration: missing",
    ]
    assert q.check({**TLX, "extra": 1}) == ["extra: not an item"]


def test_a_likert_questionnaire_scores_its_mean_with_reversed_items() -> None:
    problems: list[str] = []
    q = parse(
        "trust",
        {
            "points": 7,
            "anchors": ["strongly disagree", "strongly agree"],
            "items": [
                {"id": "safe", "text": "I felt safe."},
                {"id": "nervous", "text": "The robots made me nervous.", "reverse": True},
                {"id": "which", "kind": "choice", "text": "Which robot?", "options": ["r1", "r2"]},
                {"id": "comment", "kind": "text", "text": "Anything else?"},
            ],
        },
        problems,
    )
    assert not problems and q is not None
    assert [i.required for i in q.items] == [True, True, True, False]
    answers = {"safe": 6, "nervous": 2, "which": "r2"}
    assert q.check(answers) == []
    assert q.score(answers) == {"mean": 6.0}  # (6 + (8 - 2)) / 2
    assert q.check({**answers, "safe": 8}) == ["safe: should be an integer 1..7"]


@pytest.mark.parametrize(
    ("spec", "problem"),
    [
        ({"items": []}, "questionnaires.q.items: a list of items"),
        ({"items": [{"id": "a"}]}, "questionnaires.q.items[0].text: the question, as text"),
        (
            {"points": 1, "items": [{"id": "a", "text": "A?"}]},
            "questionnaires.q.items[0].points: an integer 2..11",
        ),
        (
            {"items": [{"id": "a", "text": "A?", "kind": "choice", "options": ["x"]}]},
            "options: two or more",
        ),
        (
            {"kind": "essay", "items": [{"id": "a", "text": "A?"}]},
            "questionnaires.q.kind: one of nasa_tlx",
        ),
        ({"items": [{"id": "a", "text": "A?"}, {"id": "a", "text": "B?"}]}, "'a' is used twice"),
        ({"kind": "ssq", "weighted": True}, "questionnaires.q.weighted"),
        (
            {"items": [{"id": "mean", "text": "A?"}, {"id": "b", "text": "B?"}]},
            "an item is named 'mean', as the questionnaire's score: rename the item",
        ),
    ],
)
def test_a_bad_questionnaire_is_named(spec: dict, problem: str) -> None:
    problems: list[str] = []
    parse("q", spec, problems)
    assert any(problem in p for p in problems), problems


def test_an_item_asked_only_after_some_answers_branching() -> None:
    """show_if: asked only when an earlier item's answer is among those named; then it is
    required like any other, else no answer may come, and the mean leaves it out."""
    problems: list[str] = []
    q = parse(
        "vr",
        {
            "items": [
                {"id": "used", "kind": "choice", "text": "Used VR?", "options": ["yes", "no"]},
                {"id": "sick", "text": "VR made me sick.", "show_if": {"used": "yes"}},
                {"id": "fun", "text": "I enjoy games."},
            ]
        },
        problems,
    )
    assert not problems and q is not None
    assert q.items[1].to_wire()["show_if"] == {"used": ["yes"]}
    assert q.check({"used": "no", "fun": 4}) == []
    assert q.check({"used": "yes", "fun": 4}) == ["sick: missing"]
    assert q.check({"used": "no", "sick": 2, "fun": 4}) == [
        "sick: not asked with the answers given before it"
    ]
    assert q.score({"used": "no", "fun": 4}) == {"mean": 4.0}
    assert q.score({"used": "yes", "sick": 2, "fun": 4}) == {"mean": 3.0}
    for show_if, problem in (
        ({"later": "x"}, "show_if.later: not an item before this one"),
        ({"used": "maybe"}, "show_if.used: 'maybe' is not an answer to it"),
    ):
        problems = []
        spec = {
            "items": [
                {"id": "used", "kind": "choice", "text": "Used VR?", "options": ["yes", "no"]},
                {"id": "sick", "text": "Sick?", "show_if": show_if},
                {"id": "later", "text": "Later?"},
            ]
        }
        parse("vr", spec, problems)
        assert any(problem in p for p in problems), problems
