#!/usr/bin/env bash
# Set up everything (scripts/setup.sh) and run all tests: the linters and
# formatters in check mode (scripts/lint.sh), the C++ tests with ctest, then the
# Python tests with pytest (configuration in pytest.ini).
#
#   scripts/test-all.sh [PYTEST_ARGS...]
#
# Lint and both runners always run; the script exits non-zero when setup fails,
# when lint finds anything, when either runner fails, or when a runner ran no
# test at all (ctest without tests, pytest exit code 5). It ends with the
# closing line of lint and of each runner.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
JOBS="${HRC_JOBS:-2}"
LOG_DIR="$ROOT/build/test-logs"

echo "[test-all] setup"
# process-compose too: tests/test_deploy_session.py runs deploy/process-compose.yaml
if ! "$ROOT/scripts/setup.sh" --with-process-compose; then
  echo "[test-all] FAILED: scripts/setup.sh (see its message above)" >&2
  exit 1
fi
mkdir -p "$LOG_DIR"

failed=()

# --- linters and formatters (check mode) ---------------------------------------
echo "[test-all] lint"
lint_rc=0
"$ROOT/scripts/lint.sh" 2>&1 | tee "$LOG_DIR/lint.log" || lint_rc=$?
[ "$lint_rc" -eq 0 ] || failed+=("lint (exit $lint_rc: scripts/lint.sh; --fix applies the formatters)")

# --- C++ ---------------------------------------------------------------------
echo "[test-all] ctest (build/ik_cpp)"
ctest_rc=0
ctest --test-dir build/ik_cpp --output-on-failure --no-tests=error -j "$JOBS" 2>&1 \
  | tee "$LOG_DIR/ctest.log" || ctest_rc=$?
[ "$ctest_rc" -eq 0 ] || failed+=("ctest (exit $ctest_rc)")

# --- Python ------------------------------------------------------------------
echo "[test-all] pytest"
pytest_rc=0
"$ROOT/.venv/bin/python" -m pytest "$@" 2>&1 | tee "$LOG_DIR/pytest.log" || pytest_rc=$?
case "$pytest_rc" in
  0) ;;
  5) failed+=("pytest collected no tests (exit 5)") ;;
  *) failed+=("pytest (exit $pytest_rc)") ;;
esac

# --- summary -----------------------------------------------------------------
lint_line="$(grep -E '^\[lint\] (clean|FAILED)' "$LOG_DIR/lint.log" | tail -n 1 || true)"
ctest_line="$(grep -E 'tests passed|No tests were found' "$LOG_DIR/ctest.log" | tail -n 1 || true)"
pytest_line="$(grep -E '^=+ .*(passed|failed|error|skipped|no tests ran|deselected).* =+$' "$LOG_DIR/pytest.log" | tail -n 1 || true)"
# count "N <word>" in a runner's closing line (0 when absent)
count() { sed -n "s/.*[^0-9]\([0-9][0-9]*\) $2.*/\1/p" <<<" $1" | head -n 1 | grep . || echo 0; }
c_total="$(sed -n 's/.*out of \([0-9][0-9]*\).*/\1/p' <<<"$ctest_line" | head -n 1)"
c_failed="$(count "$ctest_line" "tests failed")"
c_passed=$(( ${c_total:-0} - c_failed ))
p_passed="$(count "$pytest_line" passed)"
p_failed=$(( $(count "$pytest_line" failed) + $(count "$pytest_line" error) ))
p_skipped="$(count "$pytest_line" skipped)"
echo
echo "[test-all] summary"
echo "  lint  : ${lint_line:-no summary line (exit $lint_rc)}"
echo "  ctest : ${ctest_line:-no summary line (exit $ctest_rc)}"
echo "  pytest: ${pytest_line:-no summary line (exit $pytest_rc)}"
echo "total: $((c_passed + p_passed)) passed, $((c_failed + p_failed)) failed, $p_skipped skipped"
if [ "${#failed[@]}" -gt 0 ]; then
  printf '[test-all] FAILED: %s\n' "${failed[@]}" >&2
  exit 1
fi
echo "[test-all] all tests passed"
