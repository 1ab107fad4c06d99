#!/usr/bin/env bash
# process-compose for deploy/process-compose.yaml, built on first use (scripts/setup.sh
# --with-process-compose: the pinned release from the Go module proxy into tools/bin/), e.g.
#   scripts/process-compose.sh -f deploy/process-compose.yaml up -U
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
PC_BIN="$ROOT/tools/bin/process-compose"
if [ ! -x "$PC_BIN" ]; then
  echo "[process-compose] not built yet: scripts/setup.sh --with-process-compose" >&2
  HRC_REQUIRE_PROCESS_COMPOSE=1 "$ROOT/scripts/setup.sh" --with-process-compose >&2
fi
exec "$PC_BIN" "$@"
