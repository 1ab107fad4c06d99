"""The scripted participant's element times beside published human data (``hrc bench participant``).

The model alone (no services): a `Hand` with a profile's parameters performs the moves the
scripted participant makes in a trial, at the distances of the reference tables, and its times
are set beside them. The references and where they come from: docs/participant-model.md.

- MTM-1 (Methods-Time Measurement; Maynard, Stegemerten & Schwab 1948, the MTM Association's
  data card): element times in TMU (1 TMU = 0.036 s) by the distance the hand travels, in inches.
  Each element is the model's move of the same kind, with the Fitts width the scripted
  participant uses for it (`ELEMENT_WIDTH_M`).
- A pick-and-place at 40 cm: R16B + G1A + M16B + P1SE + RL1, against the scripted participant's
  own reach and place plans (`reach_plan`, `place_plan`) with hand paths of 16 in each.
- VR reaching: a band of Fitts lines (intercept 0.5-1.0 s, slope 0.4 s/bit).
- Reaction times: simple visual 0.19-0.23 s; auditory 0.16-0.19 s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from hrc.participant.hand import Hand, Move, Step
from hrc.participant.motor import FIXED_PLACE, MotorParams, fitts_index
from hrc.participant.plans import (
    APPROACH_CLEARANCE,
    CARRY_CLEARANCE,
    PICK_WIDTH,
    place_plan,
    reach_plan,
)
from hrc.scenario import ParticipantProfile, ScriptedParams
from hrc.scenario.models import DEFAULT_TOLERANCE_M

TMU_S = 0.036  # MTM's time measurement unit: 1e-5 h
INCH_M = 0.0254
DISTANCES_IN = (4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24)  # 10-61 cm
# MTM-1 data card, TMU at DISTANCES_IN. R-A: reach to an object in a fixed location; R-B: to a
# single object whose location varies slightly; M-B: move an object to an approximate location;
# M-C: to an exact location.
MTM_TMU: dict[str, tuple[float, ...]] = {
    "R-A": (6.1, 7.0, 7.9, 8.7, 9.6, 10.5, 11.4, 12.3, 13.1, 14.0, 14.9),
    "R-B": (6.4, 8.6, 10.1, 11.5, 12.9, 14.4, 15.8, 17.2, 18.6, 20.1, 21.5),
    "M-B": (6.9, 8.9, 10.6, 12.2, 13.4, 14.6, 15.8, 17.0, 18.2, 19.4, 20.6),
    "M-C": (8.0, 10.3, 11.8, 13.5, 15.2, 16.9, 18.7, 20.4, 22.1, 23.8, 25.5),
}
# The model's move of each kind: the Fitts width the scripted participant gives it.
ELEMENT_WIDTH_M: dict[str, float] = {
    "R-A": FIXED_PLACE,  # to the hands' resting and waiting places
    "R-B": PICK_WIDTH,  # the reach for a part
    "M-B": PICK_WIDTH,  # carrying a part above its target (stop_above)
    "M-C": 2.0 * DEFAULT_TOLERANCE_M,  # onto the target, within the placement tolerance
}
PICK_AND_PLACE_IN = 16
# R16B + G1A + M16B + P1SE + RL1
PICK_AND_PLACE_TMU = 15.8 + 2.0 + 15.8 + 5.6 + 2.0
VR_FITTS_A_S = (0.5, 1.0)  # published VR manipulation fits: intercepts ...
VR_FITTS_B_S = 0.4  # ... and slope (s/bit)
REACTION_REFERENCE_S = {"visual": (0.19, 0.23), "auditory": (0.16, 0.19), "choice": (0.28, 0.28)}
REAL_TOLERANCE = 0.15  # the real profile's element times: within +-15 % of MTM-1
SAMPLES = 200  # draws per element (movement times vary from trial to trial)


@dataclass(frozen=True)
class ElementTime:
    element: str
    distance_cm: float
    model_s: float
    reference_s: float

    @property
    def ratio(self) -> float:
        return self.model_s / self.reference_s

    def as_dict(self) -> dict[str, Any]:
        return {
            "element": self.element,
            "distance_cm": round(self.distance_cm, 1),
            "model_s": round(self.model_s, 4),
            "reference_s": round(self.reference_s, 4),
            "ratio": round(self.ratio, 3),
        }


def plan_time(
    motor: MotorParams, start: tuple[float, float, float], steps: list[Step], seed: int
) -> float:
    """Seconds a hand at ``start`` takes to carry out ``steps`` (played on a 1 ms clock)."""
    hand = Hand("right", start, 0.0, motor, np.random.default_rng(seed))
    hand.do(*steps)
    dt, t = 0.001, 0.0
    hand.advance(t)
    while hand.busy:
        t += dt
        hand.advance(t)
        if t > 60.0:
            raise RuntimeError("a plan of the bench did not end within 60 s")
    return t


def move_time(motor: MotorParams, distance_m: float, width_m: float, seed: int) -> float:
    """The mean over SAMPLES draws of a straight move of ``distance_m`` (its movement time)."""
    rng = np.random.default_rng(seed)
    times = []
    for _ in range(SAMPLES):
        hand = Hand("right", (0.0, 0.0, 0.1), 0.0, motor, rng)
        hand.do(Move((distance_m, 0.0, 0.1), None, width_m))
        hand.advance(0.0)
        assert hand.segment is not None
        times.append(hand.segment.mt)
    return float(np.mean(times))


def element_times(p: ScriptedParams, seed: int = 1) -> list[ElementTime]:
    motor = MotorParams.of(p)
    out = []
    for element, tmus in MTM_TMU.items():
        for inches, tmu in zip(DISTANCES_IN, tmus, strict=True):
            d = inches * INCH_M
            model = move_time(motor, d, ELEMENT_WIDTH_M[element], seed)
            out.append(ElementTime(element, d * 100.0, model, tmu * TMU_S))
    return out


def pick_and_place_time(p: ScriptedParams, seed: int = 1) -> ElementTime:
    """The scripted participant's reach, grasp, carry, place and release with hand paths of
    PICK_AND_PLACE_IN inches each (the part at the hand's height, approached from above), the
    mean over SAMPLES / 10 runs."""
    motor = MotorParams.of(p)
    d = PICK_AND_PLACE_IN * INCH_M
    grasp = (0.0, 0.0, 0.02)
    above = (grasp[0], grasp[1], grasp[2] + APPROACH_CLEARANCE)
    start = (-(d - APPROACH_CLEARANCE), 0.0, above[2])  # path: across, then down
    reach = reach_plan(above, grasp, 0.0, motor, p.stop_above, p.pick_dwell_s)
    carry_z = grasp[2] + CARRY_CLEARANCE
    release = (d - 2.0 * CARRY_CLEARANCE, 0.0, grasp[2])  # path: up, across, down
    place = place_plan(
        grasp, carry_z, release, 0.0, 2.0 * DEFAULT_TOLERANCE_M, p.stop_above, p.place_dwell_s
    )
    runs = max(1, SAMPLES // 10)
    times = [
        plan_time(motor, start, reach, seed + 2 * i)
        + plan_time(motor, grasp, place, seed + 2 * i + 1)
        for i in range(runs)
    ]
    return ElementTime(
        "pick-and-place", d * 100.0, float(np.mean(times)), PICK_AND_PLACE_TMU * TMU_S
    )


def vr_band(element: str, distance_m: float) -> tuple[float, float]:
    """The VR reference band (s) for a move of the element's kind."""
    width = ELEMENT_WIDTH_M[element]
    index = fitts_index(distance_m, width) if not math.isinf(width) else 0.0
    return (VR_FITTS_A_S[0] + VR_FITTS_B_S * index, VR_FITTS_A_S[1] + VR_FITTS_B_S * index)


def profile_report(profile: ParticipantProfile, seed: int = 1) -> dict[str, Any]:
    """The figures of one profile: its element times against MTM-1 (and, for vr, against the VR
    band), its pick-and-place against MTM-1's, and its reaction times against the literature."""
    p = ScriptedParams.model_validate({"profile": profile.value})
    elements = element_times(p, seed)
    pnp = pick_and_place_time(p, seed)
    worst = max([abs(e.ratio - 1.0) for e in elements] + [abs(pnp.ratio - 1.0)])
    report: dict[str, Any] = {
        "parameters": p.model_dump(mode="json"),
        "elements": [e.as_dict() for e in elements],
        "pick_and_place": pnp.as_dict(),
        "max_abs_deviation_from_mtm": round(worst, 3),
        "within_15pct_of_mtm": worst <= REAL_TOLERANCE,
        "reaction_s": {"visual": p.reaction_time_s, "collision": p.collision_reaction},
    }
    if profile == ParticipantProfile.VR:
        inside = []
        for e in elements:
            lo, hi = vr_band(e.element, e.distance_cm / 100.0)
            inside.append(lo * 0.95 <= e.model_s <= hi * 1.05)
        report["within_vr_band"] = all(inside)
    return report


def bench(seed: int = 1) -> dict[str, Any]:
    return {
        "reference": {
            "tmu_s": TMU_S,
            "mtm_tmu": {k: dict(zip(DISTANCES_IN, v, strict=True)) for k, v in MTM_TMU.items()},
            "pick_and_place_tmu": round(PICK_AND_PLACE_TMU, 1),
            "vr_fitts": {"a_s": list(VR_FITTS_A_S), "b_s_per_bit": VR_FITTS_B_S},
            "reaction_s": {k: list(v) for k, v in REACTION_REFERENCE_S.items()},
        },
        "profiles": {prof.value: profile_report(prof, seed) for prof in ParticipantProfile},
    }
