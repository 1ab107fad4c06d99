"""The scripted participant's profiles: whose values its unset parameters take.

`baseline` is the parameters' own defaults (`ScriptedParams`): the values the project started
with, chosen and not checked, kept as the default so that every study and recording made before
profiles reproduces. `real` and `vr` replace some of them; a key written in the scenario or drawn
in a study always wins over its profile. Where each value comes from: docs/participant-model.md;
how well `real` matches MTM-1: ``hrc bench participant``.
"""

from __future__ import annotations

from typing import Any

from hrc.scenario.enums import ParticipantProfile

PROFILES: dict[ParticipantProfile, dict[str, Any]] = {
    ParticipantProfile.BASELINE: {},
    # A practised worker at a real bench, fitted to MTM-1 element times (reach R-A, R-B, move
    # M-B, M-C at 10-60 cm; a 40 cm pick-and-place) with the model's own Fitts widths.
    ParticipantProfile.REAL: {
        "reaction_time_s": 0.22,  # simple visual reaction time (0.19-0.23 s)
        "collision_reaction_s": 0.17,  # a touch and the alarm: auditory/tactile (0.16-0.19 s)
        "peak_hand_speed": 2.0,  # ISO 13855's hand approach speed, as a ceiling
        "fitts_a_s": 0.11,
        "fitts_b_s": 0.04,
        "fitts_c_s_per_m": 0.8,
        "stop_above": False,  # a reach or a placing is one motion
        "grip_close_s": 0.072,  # G1A (2.0 TMU): grasp an object lying alone
        "pick_dwell_s": 0.072,  # the grasp is the dwell
        "grip_open_s": 0.072,  # RL1 (2.0 TMU): release by opening the fingers
        "place_dwell_s": 0.2,  # P1SE (5.6 TMU): position, loose fit, symmetric, easy to handle
    },
    # A participant in a headset with controllers: reaches start later and take longer, mostly
    # in their final (homing) phase; grabbing is a button press.
    ParticipantProfile.VR: {
        "reaction_time_s": 0.30,  # visual reaction plus the headset's motion-to-photon latency
        "collision_reaction_s": 0.25,  # no touch in VR: the alarm and what is seen
        "peak_hand_speed": 2.0,
        "fitts_a_s": 0.5,
        "fitts_b_s": 0.4,
        "fitts_c_s_per_m": 0.0,
        "stop_above": False,
        "grip_close_s": 0.1,
        "pick_dwell_s": 0.3,  # press, and see that the part is held
        "grip_open_s": 0.1,
        "place_dwell_s": 0.4,  # align the part with its outline, then let go
    },
}


def profile_defaults(profile: ParticipantProfile) -> dict[str, Any]:
    """The values a profile gives the keys a scenario leaves unset."""
    return dict(PROFILES[profile])
