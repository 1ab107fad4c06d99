"""The recording carries the researcher's layout (a rerun blueprint): read back from the .rrd,
the 3D scene takes three quarters of the width, seen from behind the participant, with the TCP
speeds, hand distances and events stacked beside it."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import rerun as rr
from offline import run_offline
from synthetic import SyntheticTrial

from hrc import scenario as sc
from hrc.paths import project_root

from hrc_logger.blueprint import EYE_POSITION, EYE_TARGET, SCENE_NAME, SCENE_SHARE


def blueprint_rows(rrd: Path) -> dict[str, dict[str, Any]]:
    """Entity -> its last row's components, from the recording's blueprint store."""
    reader = rr.chunk.RrdReader(rrd)
    (store,) = reader.blueprints()
    rows: dict[str, dict[str, Any]] = {}
    for chunk in reader.stream(store=store):
        row = chunk.to_record_batch().to_pylist()[-1]
        rows.setdefault(chunk.entity_path, {}).update(
            {k.split(":")[1]: v for k, v in row.items() if ":" in k}
        )
    return rows


def test_the_recording_carries_the_layout_with_the_scene_large(tmp_path: Path) -> None:
    scenario = sc.to_proto(
        sc.load(project_root() / "scenarios" / "thesis.toml", motion_check=False)
    )
    run_offline(SyntheticTrial(scenario, n_ticks=580), tmp_path)
    rows = blueprint_rows(tmp_path / "recording.rrd")
    views = {
        row["display_name"][0]: (path, row) for path, row in rows.items() if "display_name" in row
    }
    scene_path, scene = views[SCENE_NAME]
    assert scene["class_identifier"] == ["3D"] and scene["space_origin"] == ["/"]
    eye = rows[f"{scene_path}/EyeControls3D"]
    assert [round(v, 5) for v in eye["position"][0]] == [round(v, 5) for v in EYE_POSITION]
    assert [round(v, 5) for v in eye["look_target"][0]] == [round(v, 5) for v in EYE_TARGET]
    assert EYE_POSITION[1] < -0.7 < EYE_TARGET[1]  # behind the participant, looking at the board
    side = {name: row["space_origin"][0] for name, (_p, row) in views.items() if name != SCENE_NAME}
    assert side == {
        "TCP speed (m/s)": "/plots/tcp_speed",
        "Hand to robot (m)": "/plots/hand_distance",
        "Events": "/events",
    }
    (top,) = [row for row in rows.values() if "col_shares" in row]
    assert top["col_shares"] == [SCENE_SHARE, 1.0]  # the scene: three quarters of the width
    assert top["contents"][0] == scene_path.lstrip("/")
