"""A live VR client's reach moves the hand in the physics world (issue 6).

Full trial (all five services, real physics) with the participant's input switched to the VR
bridge; a real WebSocket client streams a reach from outside the workspace envelope into it, and
physics reports the hand entering the envelope (a contact it computes from the hand collider).
"""

from __future__ import annotations

import json
import threading
import time

from websockets.sync.client import connect

from hrc.bus import Bus, access
from hrc.service_table import EXPERIMENTER
from hrc.trial import TrialOptions, run_trial
from hrc.wire import pb

from .conftest import ROOT, free_port, wait_until


def _pose(p: list[float]) -> dict:
    return {"position": p, "orientation": [0, 0, 0, 1]}


def test_a_vr_reach_moves_the_hand_in_physics(tmp_path, ik_bin) -> None:
    session, port, vr_port = f"vr{free_port()}", free_port(), free_port()
    opts = TrialOptions(
        scenario=ROOT / "scenarios" / "empty.toml",
        out=tmp_path / "trial",
        ticks=10**9,
        session=session,
        port=port,
        mode="realtime",
        extra={"human_input": ["--input", "vr", "--vr-port", str(vr_port)]},
    )
    result: dict = {}
    runner = threading.Thread(target=lambda: result.setdefault("r", run_trial(opts, opts.out)))
    runner.start()

    contacts: list[pb.Contact] = []
    lock = threading.Lock()
    try:
        time.sleep(1.0)
        with Bus(
            access.join(session, port),
            EXPERIMENTER,
        ) as bus:

            def on_contacts(_k: str, m: pb.WorldContacts) -> None:
                with lock:
                    contacts.extend(m.contacts)

            bus.subscribe(bus.keys.world_contacts(), pb.WorldContacts, on_contacts)
            deadline = time.monotonic() + 60
            ws = None
            while ws is None:
                try:
                    ws = connect(f"ws://127.0.0.1:{vr_port}/ws", open_timeout=2)
                except OSError:
                    assert time.monotonic() < deadline, "the VR bridge never came up"
                    time.sleep(0.2)
            with ws:
                assert json.loads(ws.recv(timeout=10))["type"] == "hello"
                # the rest pose (0.22, -0.56) is outside the envelope too: no contact before this
                start, goal = (0.25, -0.75, 0.10), (0.10, -0.10, 0.10)  # outside -> inside
                for i in range(41):
                    s = i / 40
                    p = [a + (b - a) * s for a, b in zip(start, goal, strict=True)]
                    ws.send(
                        json.dumps(
                            {
                                "head": _pose([0, -0.8, 0.6]),
                                "left": _pose([-0.25, -0.75, 0.1]),
                                "right": _pose(p),
                                "left_grip": 0.0,
                                "right_grip": 0.0,
                            }
                        )
                    )
                    time.sleep(0.05)

                def entered() -> bool:
                    with lock:
                        return any(
                            c.kind == pb.CONTACT_KIND_HAND_ENVELOPE and c.begin and c.a == "right"
                            for c in contacts
                        )

                assert wait_until(entered, 20), [str(c) for c in contacts]
            bus.publisher(bus.keys.run_control(bus.sender)).put(
                pb.RunControl(command=pb.RunControl.COMMAND_STOP, reason="test done")
            )
            runner.join(60)
    finally:
        runner.join(60)
    assert result["r"].ok, result["r"].message
