"""The protective zone in the view (safety policy ssm): logged per robot, radius S_p at the
arm's speed, colour by state (green normal, yellow reduced, red stopped)."""

from __future__ import annotations

import numpy as np
import pytest
import rerun as rr

from hrc import scenario as sc
from hrc.paths import project_root
from hrc.ssm import protective_distance
from hrc.wire import pb

from hrc_logger.ssm_zone import COLORS, Zone
from hrc_logger.view import View


def _scenario(policy: str) -> pb.Scenario:
    s = sc.load(project_root() / "scenarios" / "thesis.toml", motion_check=False)
    s.conditions.safety_policy = sc.SafetyPolicy(policy)
    return sc.to_proto(s)


def test_zone_state_radius_and_colour() -> None:
    z = Zone(sc.Ssm())
    st = pb.RobotState(robot="r1", tcp_speed=0.3)
    z.observe(st)
    assert z.state == "normal" and z.radius == pytest.approx(protective_distance(sc.Ssm(), 0.3))
    st.speed_scale = 0.4
    z.observe(st)
    assert z.state == "reduced"
    assert z.event(pb.TaskEvent(kind=pb.TASK_EVENT_KIND_PROTECTIVE_STOP, robot="r1"))
    assert z.state == "stopped"
    arch = z.archetype(np.zeros((3, 3)))
    assert arch.colors is not None
    assert list(arch.colors.as_arrow_array().to_pylist()[0].to_bytes(4, "big")[:3]) == list(
        COLORS["stopped"]
    )
    assert z.event(pb.TaskEvent(kind=pb.TASK_EVENT_KIND_PROTECTIVE_RESUME, robot="r1"))
    assert z.state == "reduced"
    assert not z.event(pb.TaskEvent(kind=pb.TASK_EVENT_KIND_COLLISION, robot="r1"))


def _logged(policy: str) -> tuple[View, int]:
    rec = rr.RecordingStream("hrc-test-ssm-zone")
    rec.memory_recording()
    view = View(rec)
    view.setup(_scenario(policy))
    before = view.logged
    view.robot_state(pb.RobotState(robot="r1", tcp_speed=0.2))
    view.event(pb.TaskEvent(kind=pb.TASK_EVENT_KIND_PROTECTIVE_STOP, robot="r1"), None)
    return view, view.logged - before


def test_the_view_draws_zones_only_under_ssm() -> None:
    ssm, n_ssm = _logged("ssm")
    retreat, n_retreat = _logged("retreat")
    assert set(ssm.zones) == {"r1", "r2"} and retreat.zones == {}
    assert ssm.zones["r1"].state == "stopped"
    # the zone is logged with the state, and again at the stop (a stopped arm sends no state)
    assert n_ssm == n_retreat + 2
