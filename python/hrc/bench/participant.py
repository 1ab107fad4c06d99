"""``hrc bench participant``: the scripted participant's element times against MTM-1, VR reaching
and reaction-time data, per profile (hrc.participant.elements).

No services run: the participant's own hand model performs each element. ``--json`` prints one
object ``{"reference": ..., "profiles": {PROFILE: {"elements": [{"element", "distance_cm",
"model_s", "reference_s", "ratio"}], "pick_and_place": {...}, "max_abs_deviation_from_mtm",
"within_15pct_of_mtm", ...}}}``; without it, a table per profile.
"""

from __future__ import annotations

import argparse
import json
from typing import Any


def _table(report: dict[str, Any]) -> str:
    lines = []
    for name, prof in report["profiles"].items():
        lines.append(
            f"profile {name}: max |model/MTM - 1| = {prof['max_abs_deviation_from_mtm']:.3f}"
            f" ({'within' if prof['within_15pct_of_mtm'] else 'outside'} +-15 %)"
            + (
                f"; inside the VR band: {prof['within_vr_band']}"
                if "within_vr_band" in prof
                else ""
            )
        )
        rows: dict[str, list[dict[str, Any]]] = {}
        for e in prof["elements"]:
            rows.setdefault(e["element"], []).append(e)
        dists = [e["distance_cm"] for e in next(iter(rows.values()))]
        lines.append("  element  " + " ".join(f"{d:>6.0f}cm" for d in dists))
        for element, cells in rows.items():
            lines.append(f"  {element:<8} " + " ".join(f"{c['ratio']:>8.2f}" for c in cells))
        pnp = prof["pick_and_place"]
        lines.append(
            f"  pick-and-place {pnp['distance_cm']:.0f} cm: model {pnp['model_s']:.3f} s, "
            f"MTM {pnp['reference_s']:.3f} s, ratio {pnp['ratio']:.2f}"
        )
        rt = prof["reaction_s"]
        lines.append(
            f"  reaction (median): visual {rt['visual']:.3f} s, collision {rt['collision']:.3f} s"
        )
    ref = report["reference"]["reaction_s"]
    lines.append(
        "reference reaction times: "
        + ", ".join(f"{k} {lo:g}-{hi:g} s" for k, (lo, hi) in ref.items())
        + " (ratios: model time / MTM-1 time)"
    )
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    from hrc.participant.elements import bench

    report = bench()
    if getattr(args, "json", False):
        print(json.dumps(report, indent=1))
    else:
        print(_table(report))
    return 0
