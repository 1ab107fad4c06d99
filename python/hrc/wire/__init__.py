"""The wire contract, compiled from proto/hrc/v2/hrc.proto by the build (never edited by hand).

Use ``from hrc.wire import pb`` and then ``pb.ClockTick()`` etc.; `hrc.wire.jsonmap` gives the
JSON form of any message.
"""

try:
    from hrc.wire import hrc_pb2 as pb
except ImportError as exc:  # pragma: no cover - only without a build
    raise ImportError(
        "hrc.wire.hrc_pb2 is missing: run scripts/setup.sh (it compiles proto/hrc/v2/hrc.proto)"
    ) from exc

__all__ = ["pb"]
