"""Read a recording back with rerun's own reader: what each entity holds, over which ticks.

``python -m hrc_logger.rrd runs/.../recording.rrd`` prints one line per entity. The tests use
:func:`summarize` to check a trial's recording (rerun-sdk 0.41: ``rerun.chunk.RrdReader``; the
DataFusion-based ``ChunkStore.reader`` needs the optional ``datafusion`` package, so the chunks'
Arrow record batches are read directly).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path

import pyarrow as pa
import rerun as rr


@dataclass
class EntitySummary:
    rows: int = 0
    static: bool = False
    components: set[str] = field(default_factory=set)
    ticks: list[int] = field(default_factory=list)  # the tick of every temporal row

    @property
    def first_tick(self) -> int | None:
        return min(self.ticks) if self.ticks else None

    @property
    def last_tick(self) -> int | None:
        return max(self.ticks) if self.ticks else None


def summarize(path: str | Path) -> dict[str, EntitySummary]:
    """Entity path -> rows, components and ticks, from every chunk of the first recording."""
    out: dict[str, EntitySummary] = {}
    for chunk in rr.chunk.RrdReader(path).stream():
        es = out.setdefault(chunk.entity_path, EntitySummary())
        batch: pa.RecordBatch = chunk.to_record_batch()
        es.rows += chunk.num_rows
        es.static = es.static or chunk.is_static
        for name in batch.schema.names:
            if ":" in name:  # "Archetype:component" columns (not RowId / timelines)
                es.components.add(name)
        if "tick" in batch.schema.names:
            es.ticks.extend(int(t) for t in batch.column("tick").to_pylist() if t is not None)
    return out


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1:
        print("usage: python -m hrc_logger.rrd RECORDING.rrd", file=sys.stderr)
        return 2
    for ent, s in sorted(summarize(args[0]).items()):
        span = "static" if s.first_tick is None else f"ticks {s.first_tick}..{s.last_tick}"
        print(f"{ent}  rows={s.rows}  {span}  {', '.join(sorted(s.components))}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
