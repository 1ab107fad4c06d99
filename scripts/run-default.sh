#!/usr/bin/env bash
# Set up everything (scripts/setup.sh) and run the default trial:
#   hrc run scenarios/thesis.toml [EXTRA_ARGS...]
# The trial folder is runs/<date>/<participant>/<scenario>_<condition>/ unless --out DIR is given.
# Extra arguments go to `hrc run` (e.g. --out runs/t1, --mode realtime, --seed 2, --viewer).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

# --only-run: what hrc run needs (the C++ tests and benches are built by scripts/test-all.sh)
if ! "$ROOT/scripts/setup.sh" --only-run; then
  echo "[run-default] FAILED: scripts/setup.sh (see its message above)" >&2
  exit 1
fi
echo "[run-default] hrc run scenarios/thesis.toml $*"
exec "$ROOT/.venv/bin/hrc" run scenarios/thesis.toml "$@"
