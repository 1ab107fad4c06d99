#!/usr/bin/env bash
# Rewrite tests/golden/<name>/ from fresh runs of the golden trials (tests/goldens.py), after a
# deliberate change of behaviour or of an output's shape; say which in the commit.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
exec .venv/bin/python - <<'PY'
import shutil, sys, tempfile
from pathlib import Path
sys.path.insert(0, ".")
from tests.goldens import FILES, GOLDEN_ROOT, GOLDEN_TRIALS, run_trial, scenario_file

for name in sorted(GOLDEN_TRIALS):
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out"
        proc = run_trial(scenario_file(name, Path(tmp)), out)
        if proc.returncode != 0:
            sys.exit(f"[update-golden] {name} failed:\n{proc.stderr[-3000:]}")
        (GOLDEN_ROOT / name).mkdir(parents=True, exist_ok=True)
        for f in FILES:
            shutil.copy(out / f, GOLDEN_ROOT / name / f)
    print(f"[update-golden] tests/golden/{name}/ rewritten")
print("[update-golden] review the change with: git diff tests/golden")
PY
