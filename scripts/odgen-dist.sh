#!/usr/bin/env bash
# Builds `odgen`, the command-line tool, the way it is meant to be installed, and prints the
# path of the binary; with --install, installs it with `cargo install` instead (into
# ~/.cargo/bin, or $CARGO_INSTALL_ROOT/bin).
#
#   scripts/odgen-dist.sh              build; prints target/<host>/dist/odgen
#   scripts/odgen-dist.sh --install    cargo install --path odgen, the same way
#
# How (see ARCHITECTURE.md, "Reading speed"):
# - the `dist` profile (Cargo.toml): the release profile with whole-program optimisation (fat
#   LTO, one codegen unit);
# - on Linux with glibc, linked statically (`-C target-feature=+crt-static`, a static-pie
#   binary: still position independent). A run of `odgen` is a few milliseconds; loading
#   libc and libgcc_s and relocating against them was 0.4 ms of `odgen --version`'s 1.3 ms,
#   and of every `odgen check`.
# The host is given as the target (`--target`), so that these flags reach the binary and its
# libraries but not the build scripts and proc macros that cargo builds and runs on the host (a
# proc macro cannot be linked statically). Other hosts get the `dist` profile only.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"

install=false
case "${1:-}" in
  --install) install=true ;;
  "") ;;
  *) echo "usage: scripts/odgen-dist.sh [--install]" >&2; exit 2 ;;
esac

host=$(rustc -vV | sed -n 's/^host: //p')
[ -n "$host" ] || { echo "cannot tell the host from \`rustc -vV\`" >&2; exit 2; }
case "$host" in
  *-linux-gnu*)
    # (cargo reads CARGO_TARGET_<TRIPLE>_RUSTFLAGS for that target only; RUSTFLAGS, when set,
    # would override it, so it is not used here.)
    var="CARGO_TARGET_$(printf '%s' "$host" | tr 'a-z.-' 'A-Z__')_RUSTFLAGS"
    export "$var=-C target-feature=+crt-static${!var:+ ${!var}}"
    if [ -n "${RUSTFLAGS:-}" ]; then
      echo "note: RUSTFLAGS is set, so cargo ignores $var: the binary is not linked statically" >&2
    fi
    ;;
esac

if $install; then
  cargo install --locked --path odgen --profile dist --target "$host"
else
  cargo build --locked -q -p odgen --profile dist --target "$host"
  target=${CARGO_TARGET_DIR:-$root/target}
  case "$target" in /*) ;; *) target="$root/$target" ;; esac
  echo "$target/$host/dist/odgen"
fi
