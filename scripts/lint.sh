#!/usr/bin/env bash
# Linters and formatters of the whole repository, in check mode.
#
#   scripts/lint.sh          check; exit 1 on any finding (or a missing tool)
#   scripts/lint.sh --fix    apply the formatters and the automatic fixes, then check
#
# --fix renames C++ identifiers with clang-tidy 14, which misses two kinds of use: a type alias
# used as a qualifier (`clock::duration`) and a template's partial specialisation. The check that
# follows reports those as compile errors (clang-diagnostic-error); rename them by hand.
#
# Tools (configuration in the files named):
#   ruff check, ruff format   Python lint and format      ruff.toml
#   mypy                      Python types                mypy.ini (strict on python/hrc)
#   imports                   the library below every     scripts/check_imports.py
#                             service, no import cycle
#   clang-format              C++ format                  services/ik_cpp/.clang-format
#   clang-tidy                C++ naming                  services/ik_cpp/.clang-tidy
#                             (needs build/ik_cpp/compile_commands.json: scripts/setup.sh)
#   cargo fmt, cargo clippy   the Rust FFI crate          rustfmt defaults (max_width 100)
#
# Every tool runs even when an earlier one fails; each one's closing line is printed at the
# end, and its whole output is in build/lint-logs/<tool>.log. scripts/setup.sh installs all of
# them (ruff and mypy from requirements.lock into .venv; the rest from Debian).
set -uo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
JOBS="${HRC_JOBS:-2}"
HRC_CACHE="${HRC_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/hrc-cosim}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HRC_CACHE/cargo-target}"
LOG_DIR="$ROOT/build/lint-logs"
VENV_BIN="$ROOT/.venv/bin"
CPP_DIR="services/ik_cpp"
CRATE="$CPP_DIR/zenoh_ffi/Cargo.toml"
COMPILE_DB="build/ik_cpp/compile_commands.json"

FIX=0
for arg in "$@"; do
  case "$arg" in
    --fix) FIX=1 ;;
    -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
    *) echo "lint: unknown option '$arg' (see --help)" >&2; exit 2 ;;
  esac
done

# rustup installs outside PATH for non-login shells (as in scripts/setup.sh).
case ":$PATH:" in
  *":$HOME/.cargo/bin:"*) ;;
  *) [ -d "$HOME/.cargo/bin" ] && PATH="$PATH:$HOME/.cargo/bin" ;;
esac
export PATH
mkdir -p "$LOG_DIR"

cpp_files() { git ls-files -- "$CPP_DIR" | grep -E '\.(c|cc|cpp|h|hpp)$'; }
# clang-tidy's compile database: build/ik_cpp's, with each of our sources once (a file compiled
# into two targets would be checked twice), and our include folder as a normal one: CMake passes
# it as -isystem (it is also the imported FFI target's), and tools skip system headers.
TIDY_DB_DIR="$LOG_DIR/tidy-db"
tidy_db() {
  mkdir -p "$TIDY_DB_DIR"
  python3 - "$COMPILE_DB" "$TIDY_DB_DIR/compile_commands.json" <<'PY'
import json, sys
seen, out = set(), []
for entry in json.load(open(sys.argv[1])):
    if "/services/ik_cpp/" in entry["file"] and entry["file"] not in seen:
        seen.add(entry["file"])
        args = entry["command"].split(" ")
        for i, arg in enumerate(args[:-1]):
            if arg == "-isystem" and "/services/ik_cpp/" in args[i + 1]:
                args[i] = "-I"
        entry["command"] = " ".join(args)
        out.append(entry)
json.dump(out, open(sys.argv[2], "w"), indent=1)
PY
}
# What clang-tidy's findings depend on, as one hash: its version, the system's packages (the
# headers it parses), the compile database (the clone's path taken out) and every file of the
# C++ service and of the wire contract. The findings of a run are kept under this key outside
# the clone (HRC_CACHE): a clone or a run on the same inputs replays them instead of spending
# about 75 CPU-s on 2 cores parsing Eigen and KDL again.
tidy_key() {
  {
    clang-tidy --version
    dpkg-query -W 2>/dev/null
    sed "s|$ROOT|@ROOT@|g" "$TIDY_DB_DIR/compile_commands.json"
    find "$CPP_DIR" proto -type f -print0 | LC_ALL=C sort -z | xargs -0 sha256sum
  } | sha256sum | cut -c1-32
}
tidy_sources() {
  python3 -c 'import json, sys
print("\n".join(sorted(e["file"] for e in json.load(open(sys.argv[1])))))' \
    "$TIDY_DB_DIR/compile_commands.json"
}
missing_tool() { echo "$1: not installed ($2)"; return 1; }

declare -A CLOSING=()
failed=()

# run_tool NAME FUNCTION CLOSING_RE: runs FUNCTION with its output on the terminal and in the
# log; a non-zero return is a finding. The closing line is the last line matching CLOSING_RE
# (else the last line).
run_tool() {
  local name="$1" fn="$2" re="$3|: not installed" rc=0 log="$LOG_DIR/$1.log" line
  echo "[lint] $name"
  "$fn" 2>&1 | tee "$log" || rc=$?
  line="$(grep -E "$re" "$log" | tail -n 1)"
  CLOSING[$name]="${line:-$(grep -v '^[[:space:]]*$' "$log" | tail -n 1)}"
  [ "$rc" -eq 0 ] || failed+=("$name")
}

# --- the checks ----------------------------------------------------------------
ruff_check() {
  [ -x "$VENV_BIN/ruff" ] || missing_tool ruff "scripts/setup.sh installs it into .venv" || return 1
  "$VENV_BIN/ruff" check --output-format concise .
}

ruff_format() {
  [ -x "$VENV_BIN/ruff" ] || missing_tool ruff "scripts/setup.sh installs it into .venv" || return 1
  "$VENV_BIN/ruff" format --check .
}

mypy_check() {
  [ -x "$VENV_BIN/mypy" ] || missing_tool mypy "scripts/setup.sh installs it into .venv" || return 1
  # Its cache outside the clone (HRC_CACHE): a fresh clone re-checks only the modules whose
  # source differs from the last run's (13 -> 0.5 CPU-s). mypy takes a cached module only when
  # its source's hash (and those of its dependencies) match, wherever the clone or its venv is;
  # the lock keeps two clones' runs from writing the cache at once.
  local dir="$HRC_CACHE/mypy"
  mkdir -p "$dir"
  flock "$dir/lock" "$VENV_BIN/mypy" --cache-dir "$dir/cache"  # files, strictness: mypy.ini
}

imports_check() {
  "$VENV_BIN/python" "$ROOT/scripts/check_imports.py"
}

clang_format_check() {
  command -v clang-format >/dev/null || missing_tool clang-format "Debian package clang-format" \
    || return 1
  local f n lines=0 files=0 total=0
  while read -r f; do
    total=$((total + 1))
    n="$(clang-format --style=file "$f" | diff "$f" - | grep -c '^<')"
    if [ "$n" -gt 0 ]; then
      echo "$f: $n lines would change"
      lines=$((lines + n)); files=$((files + 1))
    fi
  done < <(cpp_files)
  echo "clang-format: $lines lines in $files of $total files would change"
  [ "$files" -eq 0 ]
}

clang_tidy_check() {
  command -v clang-tidy >/dev/null || missing_tool clang-tidy "Debian package clang-tidy" \
    || return 1
  [ -f "$COMPILE_DB" ] || missing_tool "$COMPILE_DB" "scripts/setup.sh configures the C++ build" \
    || return 1
  # One finding per declaration: headers are reported by every file that includes them.
  local findings n key cache rc
  tidy_db
  key="$(tidy_key)"
  cache="$HRC_CACHE/lint/clang-tidy-$key.txt"
  if [ -f "$cache" ]; then
    findings="$(cat "$cache")"
    echo "(replayed from $cache: a run on the same sources, build flags and packages)"
  else
    findings="$(tidy_sources \
      | xargs -P "$JOBS" -n 4 clang-tidy -p "$TIDY_DB_DIR" --quiet 2>/dev/null \
      | grep -E '^[^ ].*: (warning|error): ' | sed "s|^$ROOT/||" | sort -u
      exit "${PIPESTATUS[1]}")"
    rc=$?
    # xargs: 0 clean, 123 a file with findings; anything else (a clang-tidy killed, xargs
    # itself failing) is not a result to keep
    if [ "$rc" -eq 0 ] || [ "$rc" -eq 123 ]; then
      mkdir -p "$(dirname "$cache")"
      printf '%s' "$findings" >"$cache.$$" && mv "$cache.$$" "$cache"
    else
      echo "clang-tidy: xargs exited $rc (a clang-tidy killed?): run lint again"
      return 1
    fi
  fi
  [ -n "$findings" ] && echo "$findings"
  n="$(grep -c . <<<"$findings")"
  echo "clang-tidy: $n naming findings"
  [ "$n" -eq 0 ]
}

cargo_fmt_check() {
  cargo fmt --version >/dev/null 2>&1 \
    || missing_tool "cargo fmt" "Debian package rustfmt-web (or: rustup component add rustfmt)" \
    || return 1
  local out n
  out="$(cargo fmt --check --manifest-path "$CRATE" -- --color never)"
  [ -n "$out" ] && echo "$out"
  n="$(grep -c '^Diff in' <<<"$out")"
  echo "cargo fmt: $n hunks would change"
  [ "$n" -eq 0 ]
}

cargo_clippy_check() {
  cargo clippy --version >/dev/null 2>&1 \
    || missing_tool "cargo clippy" \
      "Debian package rust-web-clippy (or: rustup component add clippy)" \
    || return 1
  cargo clippy --release --locked --manifest-path "$CRATE" --color never -- -D warnings
}

# --- the fixes -----------------------------------------------------------------
apply_fixes() {
  echo "[lint] --fix: ruff check --fix, ruff format"
  "$VENV_BIN/ruff" check --fix --output-format concise . >/dev/null
  "$VENV_BIN/ruff" format .
  if command -v run-clang-tidy >/dev/null && [ -f "$COMPILE_DB" ]; then
    echo "[lint] --fix: clang-tidy naming fixes (renames declarations and their uses)"
    local apply
    tidy_db
    # Debian names it clang-apply-replacements-14; run-clang-tidy looks for the plain name.
    apply="$(command -v clang-apply-replacements || command -v clang-apply-replacements-14 || true)"
    # shellcheck disable=SC2046  # one argument per source file
    run-clang-tidy -p "$TIDY_DB_DIR" -quiet -fix -j "$JOBS" \
      ${apply:+-clang-apply-replacements-binary "$apply"} $(tidy_sources) \
      >"$LOG_DIR/clang-tidy-fix.log" 2>&1
  fi
  echo "[lint] --fix: clang-format -i"
  cpp_files | xargs clang-format --style=file -i
  echo "[lint] --fix: cargo clippy --fix, cargo fmt"
  cargo clippy --fix --allow-dirty --allow-staged --release --locked --manifest-path "$CRATE" \
    >"$LOG_DIR/clippy-fix.log" 2>&1
  cargo fmt --manifest-path "$CRATE"
}

[ "$FIX" -eq 1 ] && apply_fixes

run_tool ruff-check ruff_check '^(Found [0-9]+ errors?|All checks passed)'
run_tool ruff-format ruff_format 'would be reformatted|already formatted'
run_tool mypy mypy_check '^(Found [0-9]+ errors?|Success:)'
run_tool imports imports_check '^imports:'
run_tool clang-format clang_format_check '^clang-format:'
run_tool clang-tidy clang_tidy_check '^clang-tidy:'
run_tool cargo-fmt cargo_fmt_check '^cargo fmt:'
run_tool clippy cargo_clippy_check '^error: could not compile|^ *Finished'

echo
echo "[lint] summary"
for name in ruff-check ruff-format mypy imports clang-format clang-tidy cargo-fmt clippy; do
  printf '  %-12s: %s\n' "$name" \
    "$(sed -E 's/^(clang-format|clang-tidy|cargo fmt|imports): //' <<<"${CLOSING[$name]:-no output}")"
done
if [ "${#failed[@]}" -gt 0 ]; then
  echo "[lint] FAILED: ${failed[*]}"
  exit 1
fi
echo "[lint] clean"
