#!/usr/bin/env bash
# Set up everything (scripts/setup.sh) and run all tests: the linters and
# formatters in check mode (scripts/lint.sh), the C++ tests with ctest, then the
# Python tests with pytest (configuration in pytest.ini).
#
#   scripts/test-all.sh [PYTEST_ARGS...]
#
# Lint and both runners always run; the script exits non-zero when setup fails,
# when lint finds anything, when either runner fails, or when a runner ran no
# test at all (ctest without tests, pytest exit code 5 in every phase). It ends with the
# closing line of lint and of each runner.
#
# pytest runs in phases (conftest.py): first the live trials with a browser page, one at a
# time (they must have the machine to themselves) and, at the same time at nice 10, lint and in
# a pytest process of its own the tests that mostly wait for a timeout (they fill the CPU the
# live ones leave idle), and at nice 15 in another the shortest of the other tests, one after
# the other until the live trials end; then every other test in HRC_TEST_WORKERS parallel workers
# (pytest-xdist; default 2, one per core of the CI machine), handed one test at a time, the
# longest first.
# HRC_TEST_WORKERS=0 runs all tests in one pytest process, in the same order. Each phase prints
# its 30 slowest tests; every test's time is in build/test-logs/pytest-*.xml (JUnit XML:
# `scripts/slow_tests.py` sums them by file).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
JOBS="${HRC_JOBS:-2}"
WORKERS="${HRC_TEST_WORKERS:-2}"
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
# With parallel workers, lint runs at nice 10 beside the live trials (about a minute of CPU the
# live phase leaves idle), its output shown after theirs; otherwise first, on its own.
lint_rc=0
lint_pid=""
lint_ended() {
  [ "$lint_rc" -eq 0 ] || failed+=("lint (exit $lint_rc: scripts/lint.sh; --fix applies the formatters)")
}
if [ "$WORKERS" -gt 0 ]; then
  echo "[test-all] lint: started, its output after the live trials'"
  nice -n 10 "$ROOT/scripts/lint.sh" >"$LOG_DIR/lint.log" 2>&1 &
  lint_pid=$!
else
  echo "[test-all] lint"
  "$ROOT/scripts/lint.sh" 2>&1 | tee "$LOG_DIR/lint.log" || lint_rc=$?
  lint_ended
fi

# --- C++ ---------------------------------------------------------------------
echo "[test-all] ctest (build/ik_cpp)"
ctest_rc=0
ctest --test-dir build/ik_cpp --output-on-failure --no-tests=error -j "$JOBS" 2>&1 \
  | tee "$LOG_DIR/ctest.log" || ctest_rc=$?
[ "$ctest_rc" -eq 0 ] || failed+=("ctest (exit $ctest_rc)")

# --- Python ------------------------------------------------------------------
# pytest rewrites the test modules' asserts; with PYTHONDONTWRITEBYTECODE set (as in some shells)
# every pytest process rewrote and compiled them all again (collection 5.0 -> 2.4 CPU-s each).
unset PYTHONDONTWRITEBYTECODE
: >"$LOG_DIR/pytest.log"
PYTEST_TMP="${TMPDIR:-/tmp}/pytest-of-$(id -un)"  # where the trials' folders go (pytest's tmp_path)
# run_pytest NAME ARGS...: one pytest run, its output on the terminal and appended to the log; a
# run that selected no test (exit 5) is no failure here, as long as the whole command ran some.
run_pytest() {
  local name="$1" rc=0
  shift
  echo "[test-all] pytest ($name)"
  "$ROOT/.venv/bin/python" -m pytest --durations=30 "$@" 2>&1 | tee -a "$LOG_DIR/pytest.log" \
    || rc=$?
  pytest_ended "$name" "$rc"
}
# pytest_ended NAME RC: a pytest run's exit code into the summary
pytest_ended() {
  case "$2" in
    0 | 5) ;;
    *) failed+=("pytest, $1 (exit $2)") ;;
  esac
  [ "$2" -eq 0 ] && ran_tests=1
  return 0
}
ran_tests=0
touch "$LOG_DIR/pytest.log.start"
if [ "$WORKERS" -gt 0 ]; then
  # start_background NICE PHASE ARGS...: pytest in the background at niceness NICE (the phase's
  # environment from the caller), its output in $LOG_DIR/pytest-PHASE.log; its pid in bg_pid.
  # (A script's background command ignores SIGINT, and bash cannot undo that when the script
  # itself started with it ignored: pytest takes Ctrl-C again itself.)
  start_background() {
    local nice="$1" phase="$2"
    shift 2
    nice -n "$nice" "$ROOT/.venv/bin/python" -c \
      'import signal, sys, pytest; signal.signal(signal.SIGINT, signal.default_int_handler)
sys.exit(pytest.main(sys.argv[1:]))' \
      --durations=30 --junitxml="$LOG_DIR/pytest-$phase.xml" "$@" \
      >"$LOG_DIR/pytest-$phase.log" 2>&1 &
    bg_pid=$!
  }
  # background_ended NAME PHASE PID: waits for it, shows its output, counts its result
  background_ended() {
    local rc=0
    wait "$3" || rc=$?
    echo "[test-all] pytest ($1)"
    tee -a "$LOG_DIR/pytest.log" <"$LOG_DIR/pytest-$2.log"
    pytest_ended "$1" "$rc"
  }
  beside_name="tests that wait for a timeout, beside the live trials"
  echo "[test-all] pytest ($beside_name): started, its output after the live trials'"
  HRC_TEST_PHASE=beside start_background 10 beside "$@"
  beside_pid=$bg_pid
  # ... and, at nice 15, the parallel phase's tests from its end (the shortest first) until the
  # live trials end (conftest.py, HRC_TEST_PHASE=fill): the CPU the live trials leave idle
  fill_name="the parallel phase's shortest tests, while the live trials ran"
  fill_list="$LOG_DIR/fill.list"
  fill_stop="$LOG_DIR/fill.stop"
  rm -f "$fill_stop"
  : >"$fill_list"
  echo "[test-all] pytest ($fill_name): started, its output after the parallel phase's"
  HRC_TEST_PHASE=fill HRC_TEST_FILL_STOP="$fill_stop" HRC_TEST_FILL_LIST="$fill_list" \
    start_background 15 fill "$@"
  fill_pid=$bg_pid
  # however this script ends (an error, Ctrl-C, SIGTERM), the background tests end with it,
  # through their teardown (SIGINT: pytest stops the trials its fixtures started), within 60 s
  stop_beside() {
    [ -z "$lint_pid" ] || kill -TERM -- "$lint_pid" 2>/dev/null || true
    kill -INT "$beside_pid" "$fill_pid" 2>/dev/null || true
    for _ in $(seq 120); do
      kill -0 "$beside_pid" 2>/dev/null || kill -0 "$fill_pid" 2>/dev/null || return 0
      sleep 0.5
    done
    kill -KILL "$beside_pid" "$fill_pid" 2>/dev/null || true
  }
  trap stop_beside EXIT
  trap 'exit 130' INT
  trap 'exit 143' TERM
  HRC_TEST_PHASE=alone run_pytest "live trials with a browser, one at a time" \
    --junitxml="$LOG_DIR/pytest-alone.xml" "$@"
  # the fill phase starts no test after this (the list is whole once the lock is ours)
  flock "$fill_list" touch "$fill_stop"
  wait "$lint_pid" || lint_rc=$?
  lint_pid=""
  echo "[test-all] lint"
  cat "$LOG_DIR/lint.log"
  lint_ended
  background_ended "$beside_name" beside "$beside_pid"
  HRC_TEST_PHASE=parallel HRC_TEST_FILL_LIST="$fill_list" run_pytest "the rest, $WORKERS workers" \
    -n "$WORKERS" --dist load --maxschedchunk 1 --junitxml="$LOG_DIR/pytest-parallel.xml" "$@"
  background_ended "$fill_name" fill "$fill_pid"
  trap - EXIT INT TERM
else
  run_pytest "one process" --junitxml="$LOG_DIR/pytest.xml" "$@"
fi
[ "$ran_tests" -eq 1 ] || failed+=("pytest collected no tests (exit 5)")

# --- summary -----------------------------------------------------------------
lint_line="$(grep -E '^\[lint\] (clean|FAILED)' "$LOG_DIR/lint.log" | tail -n 1 || true)"
ctest_line="$(grep -E 'tests passed|No tests were found' "$LOG_DIR/ctest.log" | tail -n 1 || true)"
# pytest's closing lines (one per phase)
pytest_lines="$(grep -E '^=+ .*(passed|failed|error|skipped|no tests ran|deselected).* =+$' "$LOG_DIR/pytest.log" || true)"
# count "N <word>" in a runner's closing line (0 when absent)
count() { sed -n "s/.*[^0-9]\([0-9][0-9]*\) $2.*/\1/p" <<<" $1" | head -n 1 | grep . || echo 0; }
c_total="$(sed -n 's/.*out of \([0-9][0-9]*\).*/\1/p' <<<"$ctest_line" | head -n 1)"
c_failed="$(count "$ctest_line" "tests failed")"
c_passed=$(( ${c_total:-0} - c_failed ))
p_passed=0 p_failed=0 p_skipped=0
while IFS= read -r line; do
  [ -n "$line" ] || continue
  p_passed=$(( p_passed + $(count "$line" passed) ))
  p_failed=$(( p_failed + $(count "$line" failed) + $(count "$line" error) ))
  p_skipped=$(( p_skipped + $(count "$line" skipped) ))
done <<<"$pytest_lines"
echo
echo "[test-all] summary"
echo "  lint  : ${lint_line:-no summary line (exit $lint_rc)}"
echo "  ctest : ${ctest_line:-no summary line (exit $ctest_rc)}"
echo "  pytest: ${pytest_lines:-no summary line}" | sed '2,$s/^/          /'
echo "total: $((c_passed + p_passed)) passed, $((c_failed + p_failed)) failed, $p_skipped skipped"
# Messages a lockstep service had to ask its sender for again (docs/ARCHITECTURE.md, "Lost
# messages"): none in a run where the bus lost nothing; each is a line in a trial's service log.
replays="$(find "$PYTEST_TMP" -name '*.log' -newer "$LOG_DIR/pytest.log.start" -print0 2>/dev/null \
  | xargs -0 -r grep -h "did not come within" 2>/dev/null || true)"
echo "  replays: $(grep -c . <<<"$replays" || true) (a lockstep wait asked a sender again for what the bus lost)"
[ -z "$replays" ] || head -n 5 <<<"$replays" | sed 's/^/    /'
if [ "${#failed[@]}" -gt 0 ]; then
  printf '[test-all] FAILED: %s\n' "${failed[@]}" >&2
  exit 1
fi
echo "[test-all] all tests passed"
