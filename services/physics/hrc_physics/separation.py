"""Human-robot separation for speed and separation monitoring (safety_policy = "ssm",
docs/safety-ssm.md): per robot, the minimum distance between the participant (both hands and the
head) and the robot's moving links, from pybullet closest-point queries up to the robot's
sensing range.

Built only under ssm, so the other policies pay nothing. The world calls :meth:`pose_head` when
a HumanState arrives and :meth:`mark_moved` when a hand or an arm moved; :meth:`update` computes
the separations only after such a change and returns them only when they differ from the last
ones.
"""

from __future__ import annotations

from typing import cast

import pybullet as p

from hrc.geometry import IDENTITY, Vec3, vec3
from hrc.wire import pb

from hrc_physics.closest import Box, nearest
from hrc_physics.hands import PARKED, Hand
from hrc_physics.robots import BASE, KinematicRobot

HEAD = "head"
HEAD_RADIUS = 0.1  # m: a sphere standing in for the head (about 0.2 m across)
DIGITS = 6  # distances and points are rounded to the micrometre: no change for float noise


class SeparationMonitor:
    def __init__(
        self,
        client: int,
        robots: dict[str, KinematicRobot],
        hands: dict[str, Hand],
        ranges: dict[str, float],
    ) -> None:
        self._c = client
        self.robots = robots
        self.hands = hands
        self.ranges = ranges  # robot id -> sensing range (m)
        shape = p.createCollisionShape(p.GEOM_SPHERE, radius=HEAD_RADIUS, physicsClientId=client)
        self.head = p.createMultiBody(0.0, shape, -1, list(PARKED), physicsClientId=client)
        p.setCollisionFilterGroupMask(self.head, -1, 0, 0, physicsClientId=client)  # queries only
        self.head_active = False
        self._stale = True
        self._last: list[pb.Separation] | None = None

    def pose_head(self, pose: pb.Pose) -> None:
        pos = vec3((pose.position.x, pose.position.y, pose.position.z))
        p.resetBasePositionAndOrientation(
            self.head, list(pos), list(IDENTITY), physicsClientId=self._c
        )
        self.head_active = True
        self._stale = True

    def mark_moved(self) -> None:
        self._stale = True

    def _bodies(self) -> list[tuple[str, int]]:
        out = [(h.name, h.body) for h in self.hands.values() if h.active]
        if self.head_active:
            out.append((HEAD, self.head))
        return out

    def current(self) -> list[pb.Separation]:
        """One entry per robot, in the world's robot order."""
        c = self._c
        out: list[pb.Separation] = []
        # each human body with its box, once for all robots
        bodies = [
            (name, body, [(-1, cast(Box, p.getAABB(body, -1, physicsClientId=c)))])
            for name, body in self._bodies()
        ]
        for rid, robot in self.robots.items():
            reach = self.ranges[rid]
            # the robot's moving links: the base does not move, being near it is no hazard
            links = [(link, box) for link, box in robot.link_boxes() if link != BASE]
            best: tuple[float, str, int, Vec3, Vec3] | None = None
            for name, body, body_links in bodies:
                # (up to the nearest so far: a farther body gives nothing)
                bound = reach if best is None else best[0]
                pt = nearest(c, body, body_links, robot.body, links, bound)
                if pt is not None and pt[8] <= reach and (best is None or pt[8] < best[0]):
                    best = (pt[8], name, pt[4], vec3(pt[5]), vec3(pt[6]))
            if best is None:
                out.append(pb.Separation(robot=rid, distance_m=reach))
                continue
            d, name, link, on_human, on_robot = best
            out.append(
                pb.Separation(
                    robot=rid,
                    distance_m=round(max(0.0, d), DIGITS),
                    body=name,
                    link=robot.link_name(link),
                    human_point=_pb(on_human),
                    robot_point=_pb(on_robot),
                )
            )
        return out

    def update(self) -> list[pb.Separation] | None:
        """The separations if a hand, the head or an arm moved and they changed, else None."""
        if not self._stale:
            return None
        self._stale = False
        now = self.current()
        if now == self._last:
            return None
        self._last = now
        return now


def _pb(v: Vec3) -> pb.Vec3:
    return pb.Vec3(x=round(v[0], DIGITS), y=round(v[1], DIGITS), z=round(v[2], DIGITS))
