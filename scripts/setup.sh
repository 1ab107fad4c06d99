#!/usr/bin/env bash
# Idempotent setup of hrc-cosim on a Debian 12 machine.
#
#   scripts/setup.sh [--no-apt] [--no-cpp] [--only-run] [--with-process-compose] [--verbose]
#
# Steps (each one is skipped when its outputs are already up to date):
#   1. apt packages (only when one is missing; sudo only when not root)
#   2. toolchains: cargo/rustc (+ rustfmt, clippy) for the Rust crate, go for process-compose
#      (only with --with-process-compose)
#   3. wire contract: proto/hrc/v2/hrc.proto -> python/hrc/wire/hrc_pb2.py
#   4. .venv with the pinned Python dependencies and the editable project packages, then the
#      wire contract's type stubs hrc_pb2.pyi (protoc-gen-mypy comes from the venv)
#   5. C++ build (CMake, which also builds the Rust crate with cargo) in build/ik_cpp; with
#      --only-run (scripts/run-default.sh) only the IK service, not the C++ tests, bench, probe
#   6. process-compose, built from the Go module proxy into tools/bin/: only with
#      --with-process-compose (scripts/test-all.sh; scripts/process-compose.sh on first use), since
#      only deploy/process-compose.yaml needs it
#   7. participant client: npm ci (package-lock.json) and the esbuild bundle in
#      services/human_input/client/dist/ (served by the VR bridge)
#
# Environment:
#   HRC_CACHE   caches kept outside the clone (cargo target dir, Go caches, npm cache);
#               default ~/.cache/hrc-cosim. A machine without them still works.
#   HRC_JOBS    parallel build jobs (default 2)
#   HRC_PYTHON  interpreter for the venv (default python3, must be >= 3.11)
#   HRC_APT_EXTRA             extra apt packages to ensure (space separated)
#   HRC_WITH_PROCESS_COMPOSE=1     as --with-process-compose
#   HRC_REQUIRE_PROCESS_COMPOSE=1  fail (instead of warn) when process-compose can't be built
#   HRC_VERBOSE=1             stream tool output instead of writing it to build/setup-logs/
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

HRC_CACHE="${HRC_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/hrc-cosim}"
JOBS="${HRC_JOBS:-2}"
PYTHON="${HRC_PYTHON:-python3}"
VERBOSE="${HRC_VERBOSE:-0}"
DO_APT=1
DO_CPP=1
DO_PC="${HRC_WITH_PROCESS_COMPOSE:-0}"
CPP_TARGETS=()  # empty: all

# --- pins -------------------------------------------------------------------
PIP_VERSION="25.1.1"
SETUPTOOLS_VERSION="80.9.0"
# uv installs requirements.lock into the venv: seconds from its cache outside the clone (pip
# took ~45 s on a fresh clone, most of it resolving and unpacking what it had cached).
UV_VERSION="0.13.8"
MIN_PYTHON="3.11"
# The Rust crate pins zenoh =1.10.2 (rust-version 1.75); its Cargo.lock pulls
# crates (uuid 1.29, time 0.3.55, darling 0.24, ...) that need rustc >= 1.89.
MIN_RUSTC="1.89.0"
# process-compose: v1.87.0 is the newest release whose whole dependency set the
# Go module proxy serves here (newer ones need glippy v1.2.0, which it refuses).
# Its go.mod says go 1.24.0; Debian 12's golang-go is 1.19.
PC_MODULE="github.com/f1bonacc1/process-compose"
PC_VERSION="v1.87.0"
MIN_GO="1.24.0"

APT_PACKAGES=(
  cmake g++ make pkg-config
  liborocos-kdl-dev libeigen3-dev liburdfdom-dev
  protobuf-compiler libprotobuf-dev libgtest-dev
  python3 python3-venv python3-dev
  git ca-certificates
  chromium  # headless, for the VR page test (services/human_input serves a WebXR page)
  clang-format clang-tidy  # scripts/lint.sh (C++ format and naming)
  ccache  # C++ compile cache outside the clone (worktrees and repeated CI runs share it)
)
# Node for the participant client's bundle: Debian's nodejs and npm only when no npm is on PATH
# (a newer Node installed otherwise is used as it is).
command -v npm >/dev/null 2>&1 || APT_PACKAGES+=(nodejs npm)

# --help prints the comment block at the top of this file.
usage() { awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; }

for arg in "$@"; do
  case "$arg" in
    --no-apt) DO_APT=0 ;;
    --no-cpp) DO_CPP=0 ;;
    --with-process-compose) DO_PC=1 ;;
    --only-run) CPP_TARGETS=(--target hrc-ik) ;;
    --no-process-compose) DO_PC=0 ;;  # the default
    --verbose|-v) VERBOSE=1 ;;
    -h|--help) usage; exit 0 ;;
    *) echo "setup: unknown option '$arg' (see --help)" >&2; exit 2 ;;
  esac
done

# --- output helpers ---------------------------------------------------------
STEP="start"
T_START=$SECONDS
T_STEP=$SECONDS
LOG_DIR="$ROOT/build/setup-logs"
mkdir -p "$LOG_DIR"

say()  { printf '[setup] %s\n' "$*"; }
warn() { printf '[setup] WARNING: %s\n' "$*" >&2; }
die()  { printf '[setup] ERROR in step "%s": %s\n' "$STEP" "$*" >&2; exit 1; }
step() { STEP="$1"; T_STEP=$SECONDS; say "$1 ..."; }
done_step() { say "  ${1:-done} ($((SECONDS - T_STEP)) s)"; }

on_exit() {
  local rc=$?
  if [ "$rc" -ne 0 ]; then
    printf '[setup] FAILED in step "%s" (exit %s) after %s s\n' "$STEP" "$rc" "$((SECONDS - T_START))" >&2
  fi
}
trap on_exit EXIT

# run_logged NAME CMD...: run a noisy command; its output goes to
# build/setup-logs/NAME.log (or the terminal with --verbose). On failure the
# tail of the log is shown and the step fails with the log's path.
run_logged() {
  local name="$1"; shift
  local log="$LOG_DIR/$name.log"
  local rc=0
  if [ "$VERBOSE" = "1" ]; then
    "$@" 2>&1 | tee "$log" || rc=$?
  else
    "$@" >"$log" 2>&1 || rc=$?
  fi
  if [ "$rc" -ne 0 ]; then
    if [ "$VERBOSE" != "1" ]; then
      echo "----- last 40 lines of $log -----" >&2
      tail -n 40 "$log" >&2 || true
      echo "-----" >&2
    fi
    die "'$*' exited with $rc (full output: $log)"
  fi
}

# version_ge A B: true when version A >= version B (dpkg ordering).
version_ge() { dpkg --compare-versions "$1" ge "$2"; }

# Toolchains installed outside apt (rustup, Go tarball) are often not on a
# non-login shell's PATH (CI): look in their usual places too, after PATH.
for d in "$HOME/.cargo/bin" /usr/local/go/bin; do
  case ":$PATH:" in *":$d:"*) ;; *) [ -d "$d" ] && PATH="$PATH:$d" ;; esac
done
export PATH

if [ "$(id -u)" -eq 0 ]; then SUDO=(); else SUDO=(sudo -n); fi
export DEBIAN_FRONTEND=noninteractive

say "hrc-cosim setup in $ROOT (cache: $HRC_CACHE, jobs: $JOBS)"

# --- 1. apt -----------------------------------------------------------------
apt_missing() {
  local p
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || echo "$p"
  done
}

APT_UPDATED=0
apt_install() {
  command -v apt-get >/dev/null || die "apt-get not found: this script targets Debian 12; install $* by hand"
  if [ "${#SUDO[@]}" -gt 0 ] && ! command -v sudo >/dev/null; then
    die "not root and sudo is missing; install as root: apt-get install $*"
  fi
  if [ "$APT_UPDATED" = 0 ]; then
    run_logged apt-update "${SUDO[@]}" apt-get update -q
    APT_UPDATED=1
  fi
  run_logged apt-install "${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive \
    apt-get install -y -q --no-install-recommends "$@"
}

step "apt packages"
if [ "$DO_APT" = 1 ]; then
  # shellcheck disable=SC2206
  wanted=("${APT_PACKAGES[@]}" ${HRC_APT_EXTRA:-})
  mapfile -t missing < <(apt_missing "${wanted[@]}")
  if [ "${#missing[@]}" -eq 0 ]; then
    done_step "all ${#wanted[@]} present"
  else
    say "  installing: ${missing[*]}"
    apt_install "${missing[@]}"
    mapfile -t still < <(apt_missing "${missing[@]}")
    [ "${#still[@]}" -eq 0 ] || die "still missing after apt-get install: ${still[*]}"
    done_step "installed ${#missing[@]}"
  fi
else
  done_step "skipped (--no-apt)"
fi

# --- 2. toolchains ----------------------------------------------------------
# Candidate version of a Debian package (empty when unknown).
apt_candidate() {
  apt-cache policy "$1" 2>/dev/null | sed -n 's/^ *Candidate: *//p' | sed 's/^[0-9]*://; s/[+~-].*//' | grep -v '(none)' || true
}

step "toolchains"
if [ "$DO_CPP" = 1 ]; then
  if ! command -v cargo >/dev/null || ! command -v rustc >/dev/null; then
    cand="$(apt_candidate rustc)"
    web="$(apt_candidate rustc-web)"
    if [ -n "$cand" ] && version_ge "$cand" "$MIN_RUSTC"; then
      say "  cargo not found; installing Debian's cargo/rustc $cand"
      apt_install cargo rustc
    elif [ -n "$web" ] && version_ge "$web" "$MIN_RUSTC"; then
      # Debian 12 keeps a current Rust for its browsers as rustc-web/cargo-web (security
      # updates); it installs /usr/bin/cargo and /usr/bin/rustc.
      say "  cargo not found; installing Debian's cargo-web/rustc-web $web"
      apt_install cargo-web rustc-web
    else
      die "cargo/rustc not found. services/ik_cpp/zenoh_ffi (zenoh 1.10.2 and its locked crates) needs rustc >= $MIN_RUSTC, and Debian offers ${cand:+rustc }${cand:-no rustc}. Install Rust >= $MIN_RUSTC (e.g. with rustup) so that cargo is on PATH or in ~/.cargo/bin, then re-run."
    fi
  fi
  rustc_v="$(rustc --version 2>/dev/null | awk '{print $2}')"
  [ -n "$rustc_v" ] || die "'rustc --version' fails (a rustup proxy without a toolchain?); install Rust >= $MIN_RUSTC"
  version_ge "$rustc_v" "$MIN_RUSTC" \
    || die "rustc $rustc_v is too old: services/ik_cpp/zenoh_ffi needs rustc >= $MIN_RUSTC (zenoh 1.10.2 and its locked crates). Update Rust and re-run."
  say "  rustc $rustc_v"
  # scripts/lint.sh runs `cargo fmt` and `cargo clippy`: Debian packages them apart from rustc.
  if ! cargo fmt --version >/dev/null 2>&1 || ! cargo clippy --version >/dev/null 2>&1; then
    if dpkg -s rustc-web >/dev/null 2>&1 && [ "$(command -v cargo)" = /usr/bin/cargo ]; then
      lint_pkgs=(rustfmt-web rust-web-clippy)
    elif dpkg -s rustc >/dev/null 2>&1 && [ "$(command -v cargo)" = /usr/bin/cargo ]; then
      lint_pkgs=(rustfmt rust-clippy)
    else
      lint_pkgs=()
    fi
    if [ "${#lint_pkgs[@]}" -gt 0 ] && [ "$DO_APT" = 1 ]; then
      say "  installing ${lint_pkgs[*]} (cargo fmt / cargo clippy, for scripts/lint.sh)"
      apt_install "${lint_pkgs[@]}"
    elif command -v rustup >/dev/null \
      && rustup component add rustfmt clippy >"$LOG_DIR/rustup-components.log" 2>&1; then
      say "  added rustup components rustfmt, clippy"
    else
      warn "cargo fmt / cargo clippy missing (Debian: ${lint_pkgs[*]:-rustfmt-web rust-web-clippy});" \
        "scripts/lint.sh will fail"
    fi
  fi
fi

GO_OK=0
go_reason=""
if [ "$DO_PC" = 1 ]; then
  if ! command -v go >/dev/null; then
    cand="$(apt_candidate golang-go)"
    if [ -n "$cand" ] && version_ge "$cand" "$MIN_GO"; then
      say "  go not found; installing Debian's golang-go $cand"
      apt_install golang-go
    else
      go_reason="go not found, and Debian's golang-go (${cand:-unavailable}) is older than $MIN_GO"
    fi
  fi
  if [ -z "$go_reason" ]; then
    go_v="$(go env GOVERSION 2>/dev/null | sed 's/^go//')"
    if [ -n "$go_v" ] && version_ge "$go_v" "$MIN_GO"; then
      GO_OK=1
      say "  go $go_v"
    else
      go_reason="go ${go_v:-?} is older than $MIN_GO (needed by process-compose $PC_VERSION)"
    fi
  fi
fi
done_step

# --- 3. wire contract for Python -------------------------------------------
step "wire contract (protoc -> python/hrc/wire)"
PROTO="proto/hrc/v2/hrc.proto"
PB_PY="python/hrc/wire/hrc_pb2.py"
PB_PYI="python/hrc/wire/hrc_pb2.pyi"
[ -f "$PROTO" ] || die "$PROTO is missing"
command -v protoc >/dev/null || die "protoc not found (apt package protobuf-compiler)"
protoc_v="$(protoc --version | awk '{print $2}')"
case "$protoc_v" in
  3.21.*) ;;
  *) warn "protoc $protoc_v: the Python runtime is pinned to protobuf 4.21.12 (made for protoc 3.21.x); generated code may not load" ;;
esac
# The .pyi is made after the venv (step 4): mypy-protobuf writes stubs mypy can read.
if [ -f "$PB_PY" ] && [ "$PB_PY" -nt "$PROTO" ]; then
  done_step "up to date"
else
  run_logged protoc protoc -I proto/hrc/v2 --python_out=python/hrc/wire "$PROTO"
  done_step "generated with protoc $protoc_v"
fi

# --- 4. Python venv ---------------------------------------------------------
step "python venv (.venv)"
VENV="$ROOT/.venv"
VPY="$VENV/bin/python"
command -v "$PYTHON" >/dev/null || die "$PYTHON not found (apt package python3)"
"$PYTHON" -c "import sys; sys.exit(0 if sys.version_info[:2] >= tuple(map(int, '$MIN_PYTHON'.split('.'))) else 1)" \
  || die "$PYTHON is $("$PYTHON" -V 2>&1); need >= $MIN_PYTHON (or set HRC_PYTHON)"

# Project packages installed editable: the common library and every Python
# service folder that has a pyproject.toml.
EDITABLES=(python)
for d in services/*/; do
  d="${d%/}"
  [ -f "$d/pyproject.toml" ] && EDITABLES+=("$d")
done

# The stamp covers everything that decides the venv's contents; when it matches
# and the entry points exist, nothing is installed.
venv_stamp() {
  {
    echo "pip=$PIP_VERSION setuptools=$SETUPTOOLS_VERSION uv=$UV_VERSION"
    "$VPY" -c 'import sys; print(sys.version)'
    sha256sum requirements.lock
    local e
    for e in "${EDITABLES[@]}"; do sha256sum "$e/pyproject.toml"; done
  } | sha256sum | awk '{print $1}'
}

if [ -x "$VPY" ] && ! "$VPY" -c 'import sys' >/dev/null 2>&1; then
  warn ".venv is broken (its python does not run); re-creating it"
  rm -rf "$VENV"
fi
created=0
if [ ! -x "$VPY" ]; then
  run_logged venv "$PYTHON" -m venv "$VENV"
  created=1
fi
STAMP_FILE="$VENV/.hrc-setup-stamp"
want_stamp="$(venv_stamp)"
if [ "$created" = 0 ] && [ -f "$STAMP_FILE" ] && [ "$(cat "$STAMP_FILE")" = "$want_stamp" ] && [ -x "$VENV/bin/hrc" ]; then
  done_step "up to date (${#EDITABLES[@]} project packages)"
else
  rm -f "$STAMP_FILE"
  export PIP_DISABLE_PIP_VERSION_CHECK=1 PIP_CACHE_DIR="$HRC_CACHE/pip"
  run_logged pip-bootstrap "$VPY" -m pip install -q "pip==$PIP_VERSION" \
    "setuptools==$SETUPTOOLS_VERSION" "uv==$UV_VERSION"
  # uv: the system's CA bundle (as pip), never a Python of its own, its cache outside the clone.
  export UV_CACHE_DIR="$HRC_CACHE/uv" UV_NATIVE_TLS=1 UV_PYTHON_DOWNLOADS=never UV_NO_PROGRESS=1
  UV=("$VENV/bin/uv" pip install --python "$VPY")
  run_logged pip-requirements "${UV[@]}" -r requirements.lock
  # setuptools-backed packages build without isolation (fast, offline, uses the
  # pinned setuptools); any other backend gets uv's isolated build.
  backends_txt="$("$VPY" - "${EDITABLES[@]}" <<'PYEOF'
import sys, tomllib
for d in sys.argv[1:]:
    with open(f"{d}/pyproject.toml", "rb") as f:
        backend = tomllib.load(f).get("build-system", {}).get("build-backend", "")
    print(f"{'st' if backend.startswith('setuptools') else 'other'} {d}")
PYEOF
  )" || die "cannot read the pyproject.toml files of: ${EDITABLES[*]}"
  mapfile -t backends <<<"$backends_txt"
  st_args=(); other=()
  for b in "${backends[@]}"; do
    kind="${b%% *}"; dir="${b#* }"
    if [ "$kind" = st ]; then st_args+=(-e "$dir"); else other+=("$dir"); fi
  done
  if [ "${#st_args[@]}" -gt 0 ]; then
    run_logged pip-editable "${UV[@]}" --no-build-isolation "${st_args[@]}"
  fi
  for dir in "${other[@]}"; do
    run_logged "pip-editable-$(basename "$dir")" "${UV[@]}" -e "$dir"
  done
  [ -x "$VENV/bin/hrc" ] || die "the hrc entry point is missing after installing python/ (check python/pyproject.toml)"
  if ! "$VPY" -m pip check >"$LOG_DIR/pip-check.log" 2>&1; then
    warn "pip check reports conflicts (see $LOG_DIR/pip-check.log)"
  fi
  echo "$want_stamp" >"$STAMP_FILE"
  done_step "installed requirements.lock + ${EDITABLES[*]}"
fi
"$VPY" -c 'from hrc.wire import pb' 2>/dev/null || die "the venv cannot import hrc.wire.pb"

# The project's own modules compiled to bytecode now: with PYTHONDONTWRITEBYTECODE set (as in
# some shells), every service start would otherwise compile them again (~30 ms CPU each).
# compileall skips what is up to date.
run_logged compileall "$VPY" -m compileall -q -j 0 python/hrc services/*/hrc_*
# So are the installed packages (uv installs them without bytecode): with that variable set, a
# trial's processes compiled numpy, zenoh, rerun, ... from source at every start, 0.7 CPU-s of a
# minimal trial's 2.5 (bench/README.md, "Bytecode"). Their own tests and the tools no trial
# imports are left out (7 s on 2 cores, once per installed set of packages).
BYTECODE_STAMP="$VENV/.hrc-bytecode-stamp"
if [ "$(cat "$BYTECODE_STAMP" 2>/dev/null)" != "$want_stamp" ]; then
  site="$("$VPY" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
  skip='/tests?/|/testing/|site-packages/(mypy|mypyc|pip|setuptools|pygments|fontTools|pybullet_envs|pybullet_data|pybullet_utils|pkg_resources|wheel)/'
  # (a package may ship a file that is not Python 3.11, a template say: not an error here)
  "$VPY" -m compileall -q -j 0 -x "$skip" "$site" >"$LOG_DIR/compileall-site.log" 2>&1 \
    || warn "some installed files did not compile (see $LOG_DIR/compileall-site.log)"
  echo "$want_stamp" >"$BYTECODE_STAMP"
fi

# Type stubs of the wire contract: mypy-protobuf (pinned in requirements.lock) instead of
# protoc's --pyi_out, whose enums mypy cannot read. Remade when the .proto or the pins change.
PB_GEN="$VENV/bin/protoc-gen-mypy"
[ -x "$PB_GEN" ] || die "$PB_GEN is missing (mypy-protobuf in requirements.lock)"
if ! { [ -f "$PB_PYI" ] && [ "$PB_PYI" -nt "$PROTO" ] && [ "$PB_PYI" -nt requirements.lock ]; }; then
  run_logged protoc-mypy protoc -I proto/hrc/v2 --plugin=protoc-gen-mypy="$PB_GEN" \
    --mypy_out=python/hrc/wire "$PROTO"
  say "  wire contract stubs: $PB_PYI (mypy-protobuf)"
fi

# --- 5. C++ (+ Rust crate) --------------------------------------------------
step "C++ build (build/ik_cpp)"
if [ "$DO_CPP" = 1 ]; then
  [ -f services/ik_cpp/CMakeLists.txt ] || die "services/ik_cpp/CMakeLists.txt is missing"
  export CARGO_TARGET_DIR="$HRC_CACHE/cargo-target"
  export CARGO_BUILD_JOBS="$JOBS"
  export CMAKE_BUILD_PARALLEL_LEVEL="$JOBS"
  mkdir -p "$CARGO_TARGET_DIR"
  # ccache keyed on paths relative to the clone, so every clone and worktree shares one cache.
  if command -v ccache >/dev/null 2>&1; then
    export CMAKE_CXX_COMPILER_LAUNCHER=ccache CCACHE_BASEDIR="$ROOT"
    export CCACHE_DIR="${CCACHE_DIR:-$HRC_CACHE/ccache}"
  fi
  # compile_commands.json: what clang-tidy (scripts/lint.sh) compiles each file with.
  if [ ! -f build/ik_cpp/CMakeCache.txt ] || [ ! -f build/ik_cpp/compile_commands.json ]; then
    run_logged cmake-configure cmake -S services/ik_cpp -B build/ik_cpp -DCMAKE_BUILD_TYPE=Release \
      -DCMAKE_EXPORT_COMPILE_COMMANDS=ON
  fi
  # Incremental: a no-op when nothing changed (cmake re-configures by itself
  # when a CMakeLists.txt changed, cargo checks its own fingerprints).
  run_logged cmake-build cmake --build build/ik_cpp -j "$JOBS" "${CPP_TARGETS[@]}"
  done_step "built${CPP_TARGETS[*]:+ (the IK service only: --only-run)} (log: build/setup-logs/cmake-build.log)"
else
  done_step "skipped (--no-cpp)"
fi

# --- 6. process-compose ----------------------------------------------------
step "process-compose $PC_VERSION (tools/bin)"
PC_BIN="$ROOT/tools/bin/process-compose"
pc_have="$("$PC_BIN" version --short 2>/dev/null || true)"
if [ "$pc_have" = "$PC_VERSION" ]; then
  done_step "up to date"
elif [ "$DO_PC" = 0 ]; then
  done_step "not needed ('hrc run' does not use it; scripts/process-compose.sh builds it on first use)"
elif [ "$GO_OK" = 0 ]; then
  msg="process-compose not built: $go_reason. Only deploy/process-compose.yaml needs it ('hrc run' does not)."
  [ "${HRC_REQUIRE_PROCESS_COMPOSE:-0}" = 1 ] && die "$msg"
  warn "$msg"
  done_step "skipped"
else
  export GOPATH="$HRC_CACHE/go"
  export GOMODCACHE="$HRC_CACHE/go/mod"
  export GOCACHE="$HRC_CACHE/go/build"
  export GOFLAGS="-mod=mod -buildvcs=false"
  export GOTOOLCHAIN=local   # never try to download another Go toolchain
  export CGO_ENABLED=0
  mkdir -p "$GOMODCACHE" "$GOCACHE" "$ROOT/tools/bin"
  # `go install module@version` needs the proxy's version list, which is not
  # served here; downloading one pinned version and building in it works.
  dl_json="$LOG_DIR/pc-download.json"
  (cd "$GOPATH" && go mod download -json "$PC_MODULE@$PC_VERSION") >"$dl_json" 2>&1 \
    || { cat "$dl_json" >&2; die "go mod download $PC_MODULE@$PC_VERSION failed"; }
  pc_src="$(sed -n 's/^[[:space:]]*"Dir": "\(.*\)",\{0,1\}$/\1/p' "$dl_json")"
  if [ -z "$pc_src" ] || [ ! -d "$pc_src" ]; then
    die "go mod download gave no module directory (see $dl_json)"
  fi
  # The main package moved from src/ to the module root over time.
  if [ -f "$pc_src/src/main.go" ]; then pc_pkg=./src; else pc_pkg=.; fi
  ldflags="-s -w -X $PC_MODULE/src/config.Version=$PC_VERSION"
  (cd "$pc_src" && run_logged go-build-process-compose go build -p "$JOBS" -trimpath \
      -ldflags "$ldflags" -o "$PC_BIN.tmp" "$pc_pkg")
  mv -f "$PC_BIN.tmp" "$PC_BIN"
  pc_have="$("$PC_BIN" version --short 2>/dev/null || true)"
  [ "$pc_have" = "$PC_VERSION" ] || die "built process-compose reports version '$pc_have', expected $PC_VERSION"
  done_step "built"
fi

# --- 7. participant client -------------------------------------------------
# services/human_input/client: npm ci from the committed package-lock.json (cache outside the
# clone), then esbuild bundles the page into dist/. Each is skipped while its inputs are unchanged.
step "participant client (services/human_input/client/dist)"
CLIENT="$ROOT/services/human_input/client"
command -v npm >/dev/null 2>&1 || die "npm not found: install Debian's nodejs and npm (apt-get install nodejs npm), or run setup without --no-apt"
export npm_config_cache="$HRC_CACHE/npm"
export npm_config_update_notifier=false
deps_stamp="$( { node --version; sha256sum "$CLIENT/package-lock.json"; } | sha256sum | awk '{print $1}')"
deps_file="$CLIENT/node_modules/.hrc-setup-stamp"
client_note="dependencies up to date"
if [ ! -f "$deps_file" ] || [ "$(cat "$deps_file")" != "$deps_stamp" ]; then
  (cd "$CLIENT" && run_logged npm-ci npm ci --no-audit --no-fund)
  echo "$deps_stamp" >"$deps_file"
  client_note="npm ci"
fi
bundle_stamp="$( { echo "$deps_stamp"; cd "$CLIENT" && find src index.html build.mjs -type f -print0 \
  | sort -z | xargs -0 sha256sum; } | sha256sum | awk '{print $1}')"
bundle_file="$CLIENT/dist/.hrc-setup-stamp"
if [ ! -f "$bundle_file" ] || [ "$(cat "$bundle_file")" != "$bundle_stamp" ] || [ ! -f "$CLIENT/dist/index.html" ]; then
  (cd "$CLIENT" && run_logged client-build node build.mjs)
  echo "$bundle_stamp" >"$bundle_file"
  done_step "$client_note, bundle built ($(du -sk "$CLIENT/dist" | awk '{print $1}') KiB)"
else
  done_step "$client_note, bundle up to date"
fi

STEP="done"
say "setup complete in $((SECONDS - T_START)) s"
