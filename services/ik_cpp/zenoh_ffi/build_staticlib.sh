#!/usr/bin/env bash
# The FFI crate's static library for CMake (CMakeLists.txt, target hrc_zenoh_ffi_cargo), kept
# under a hash of what it is built from.
#
#   build_staticlib.sh CARGO TARGET_DIR OUT
#
# Cargo takes a path crate for fresh by its files' times. In a target dir shared by clones
# (HRC_CACHE's, scripts/setup.sh) every new clone, its files all new, rebuilt the crate (10 s of
# every fresh clone's setup on 2 cores), and a clone whose files were older than another clone's
# last build would have linked that clone's library. Here the library is kept in
# TARGET_DIR/hrc-ffi/<hash> of the crate's files, the toolchain and the build's environment:
# the same inputs take the kept library; new ones are built after `cargo clean -p`, so that no
# file time can hide them. OUT is rewritten only when it changes (no relink otherwise).
set -euo pipefail
cargo="$1" target="$2" out="$3"
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
rustc="$(dirname "$cargo")/rustc"
[ -x "$rustc" ] || rustc=rustc
key="$(
  {
    "$cargo" -vV
    "$rustc" -vV
    # (what changes the library; not CARGO_BUILD_JOBS, which setup sets)
    env | grep -E '^(RUSTFLAGS|CARGO_ENCODED_RUSTFLAGS|CARGO_PROFILE_|CARGO_BUILD_)' \
      | grep -v '^CARGO_BUILD_JOBS=' | sort || true
    cd "$here" && find . -type f ! -name '*.sh' -print0 | LC_ALL=C sort -z | xargs -0 sha256sum
  } | sha256sum | cut -c1-32
)"
kept="$target/hrc-ffi/$key/libhrc_zenoh_ffi.a"
mkdir -p "$target/hrc-ffi"
(
  # one build at a time per target dir: the library cargo leaves in release/ is copied before
  # another clone's build can replace it
  flock 9
  if [ ! -f "$kept" ]; then
    CARGO_TARGET_DIR="$target" "$cargo" clean --quiet --release -p hrc_zenoh_ffi \
      --manifest-path "$here/Cargo.toml"
    CARGO_TARGET_DIR="$target" "$cargo" build --release --locked -j 2 \
      --manifest-path "$here/Cargo.toml"
    mkdir -p "$(dirname "$kept")"
    cp "$target/release/libhrc_zenoh_ffi.a" "$kept.$$"
    mv "$kept.$$" "$kept"
    # the last few inputs' libraries are kept (75 MB each), the older ones go
    ls -1dt "$target"/hrc-ffi/*/ | tail -n +6 | xargs -r rm -rf
  fi
) 9>"$target/hrc-ffi/lock"
mkdir -p "$(dirname "$out")"
cmp -s "$kept" "$out" || cp "$kept" "$out"
