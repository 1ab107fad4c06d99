"""The physics bench (``python -m hrc_physics.bench``, run by ``hrc bench physics``): the cost of
one physics tick of the thesis world with nothing else around.

Per tick, as the physics service does it (minus the bus): take a robot state per arm and a human
state, step the world (dynamics, kinematic robots and hands, grasp logic), collect the changed
object states and events, and run the contact queries. The arms sweep and the hands move over
the board, so every query runs with fresh poses. The figure is the upper bound for how fast a
lockstep trial can tick.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

from hrc import scenario as sc
from hrc.paths import project_root
from hrc.wire import pb

from hrc_physics.world import World, WorldSettings

WARMUP_TICKS = 240  # parts settle and fall asleep, as in a real trial's first second


def _human(k: int, dt: float) -> pb.HumanState:
    t = k * dt
    msg = pb.HumanState(left_grip=0.0, right_grip=0.0)
    for hand, x0 in ((msg.left_hand, -0.15), (msg.right_hand, 0.15)):
        hand.position.x = x0 + 0.10 * math.sin(1.3 * t)
        hand.position.y = -0.10 + 0.15 * math.sin(0.7 * t)
        hand.position.z = 0.15 + 0.05 * math.sin(2.1 * t)
        hand.orientation.w = 1.0
    return msg


def _joints(k: int, dt: float, phase: float) -> list[float]:
    t = k * dt
    q2 = 0.5 + 0.3 * math.sin(0.9 * t + phase)
    q3 = 1.6 + 0.3 * math.sin(1.1 * t + phase)
    return [0.4 * math.sin(0.5 * t + phase), q2, q3, math.pi - q2 - q3, 0.0]


def measure(n: int, path: Path | None = None) -> dict[str, float]:
    path = path or project_root() / "scenarios" / "thesis.toml"
    scenario = sc.load(path, motion_check=False)
    dt = 1.0 / scenario.scenario.tick_hz
    with World(scenario, WorldSettings(dt=dt)) as world:
        robots = list(world.robots)
        total = WARMUP_TICKS + n
        # Inputs made up front: the figure is the world's cost, not the bench's.
        humans = [_human(k, dt) for k in range(total)]
        joints = [[_joints(k, dt, math.pi * i) for i in range(len(robots))] for k in range(total)]
        contacts = 0

        def tick(k: int) -> None:
            nonlocal contacts
            for rid, q in zip(robots, joints[k], strict=True):
                world.set_robot_state(rid, [], q)
            world.set_human(humans[k])
            world.step()
            world.object_states(full=k == 0)
            world.take_events()
            contacts += len(world.contact_events())

        for k in range(WARMUP_TICKS):
            tick(k)
        t0 = time.perf_counter()
        for k in range(WARMUP_TICKS, total):
            tick(k)
        wall = time.perf_counter() - t0
    return {"us_per_tick": round(wall / n * 1e6, 1), "ticks": n, "contact_events": contacts}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m hrc_physics.bench", description=__doc__)
    p.add_argument("--n", type=int, default=5000, help="measured ticks (default %(default)s)")
    p.add_argument("--json", action="store_true", help='print one JSON object {"us_per_tick": x}')
    p.add_argument(
        "--scenario", type=Path, default=None, help="the world of this scenario (default: thesis)"
    )
    args = p.parse_args(argv)
    if args.n < 1:
        p.error(f"--n must be >= 1, got {args.n}")
    result = measure(args.n, args.scenario)
    if args.json:
        print(json.dumps({"us_per_tick": result["us_per_tick"]}))
    else:
        rate = 1e6 / result["us_per_tick"] if result["us_per_tick"] > 0 else math.inf
        print(
            f"physics tick, thesis world, no bus ({args.n} ticks after {WARMUP_TICKS} warm-up): "
            f"{result['us_per_tick']:.1f} us/tick (at most {rate:,.0f} ticks/s), "
            f"{result['contact_events']} contact events"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
