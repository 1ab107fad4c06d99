"""The layout of the researcher's rerun view (a rerun blueprint, sent with every recording).

Without one, rerun splits the screen into one equal panel per entity group, and the 3D scene gets
a ninth of it. This layout gives the scene about three quarters of the width, seen from behind
and above the participant (who stands at -y looking towards +y, docs/scenario.md), and stacks
the TCP speeds, the hand-robot distances and the event log in a narrow column on the right.
"""

from __future__ import annotations

import rerun.blueprint as rrb

from hrc.geometry import Vec3

# Behind and well above the participant's head (the scripted participant's eyes are at
# (0, -0.70, 0.60)), looking down at the board: the head then sits at the board's near edge,
# where the participant stands, instead of hiding the middle of the board.
EYE_POSITION: Vec3 = (0.0, -1.25, 1.75)
EYE_TARGET: Vec3 = (0.0, 0.10, 0.0)
SCENE_SHARE = 3.0  # the scene's width : the side column's width
SCENE_NAME = "Scene (behind the participant)"


def blueprint() -> rrb.Blueprint:
    scene = rrb.Spatial3DView(
        name=SCENE_NAME,
        origin="/",
        # everything spatial: the robots (robot_<id>/...) and the world (parts, targets, the
        # participant's head and hands, cues, contacts, workspace)
        contents=["+ /**", "- /plots/**", "- /events", "- /status/**"],
        eye_controls=rrb.EyeControls3D(
            kind=rrb.Eye3DKind.Orbital,
            position=EYE_POSITION,
            look_target=EYE_TARGET,
            eye_up=(0.0, 0.0, 1.0),
        ),
    )
    side = rrb.Vertical(
        rrb.TimeSeriesView(name="TCP speed (m/s)", origin="/plots/tcp_speed"),
        rrb.TimeSeriesView(name="Hand to robot (m)", origin="/plots/hand_distance"),
        rrb.TextLogView(name="Events", origin="/events"),
        row_shares=[1.0, 1.0, 1.5],
    )
    return rrb.Blueprint(
        rrb.Horizontal(scene, side, column_shares=[SCENE_SHARE, 1.0]),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed", timeline="sim_time"),
    )
