#!/usr/bin/env bash
# Runs every test of the project: the Rust workspace (unit, snapshot, compile, property,
# corpus and interop tests), the generated-code freshness check, the SocketCAN build, and the
# Python end-to-end tests in which python-canopen drives the simulated devices.
# Installs what it needs (the Python venv in .venv, the thumbv7em-none-eabihf target). This is
# what .ci/run calls.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"

step() { printf '\n==> %s\n' "$*"; }

# The public EDS corpus lives beside the repository (../shared/eds-corpus) on the project's
# machines; the corpus tests say they are skipped when it is absent.
if [ -z "${EDS_CORPUS_DIR:-}" ] && [ -d "$root/../shared/eds-corpus" ]; then
  export EDS_CORPUS_DIR="$root/../shared/eds-corpus"
fi

step "Python venv (python-canopen, python-can, pytest)"
PYTHON=$("$root/scripts/venv.sh")
export ODGEN_PYTHON="$PYTHON"

step "cargo fmt --check"
cargo fmt --all -- --check

# Lints with warnings denied, every crate and target (clippy is in rust-toolchain.toml).
step "cargo clippy (workspace, all targets, warnings denied)"
cargo clippy --workspace --all-targets --locked -- -D warnings

# One build profile only: `cargo test --all-targets` also compiles the benchmarks (in the test
# profile) and runs each of them once as a smoke test.
step "cargo test (workspace, all targets)"
cargo test --workspace --all-targets --locked --no-fail-fast

# `--all-targets` leaves the doc tests out: the examples in the docs, the crates' READMEs among
# them (each published crate's README is its front page).
step "doc tests (workspace)"
cargo test --workspace --doc --locked --no-fail-fast

# The crates published on crates.io, in dependency order (drive, generated, devices, odgen,
# xtask and the examples are not published). Their docs build without a warning (docs.rs
# builds od-runtime with all features), and each one packages and builds from its .crate
# alone: `cargo package` of several packages resolves the workspace crates they depend on from
# the .crate files it has just made (a local registry in target/package), as crates.io will.
# The packages hold the sources, README and license files only: "ignoring test/benchmark ..."
# is cargo saying so. --allow-dirty: a local run checks the working tree as it is.
published=(-p od-sidecar -p od-runtime -p od-bus -p canopen-eds -p od-codegen -p od-macros)
step "docs of the published crates (warnings denied)"
RUSTDOCFLAGS="-D warnings" cargo doc --no-deps --all-features --locked "${published[@]}"
step "cargo package (the published crates, each built from its .crate)"
cargo package --locked --allow-dirty "${published[@]}"

step "binaries for the end-to-end tests"
cargo build --workspace --bins --locked
# Where cargo put them: $CARGO_TARGET_DIR when set (relative to the root, as cargo reads it).
target=${CARGO_TARGET_DIR:-$root/target}
case "$target" in /*) ;; *) target="$root/$target" ;; esac

# od-bus's optional parts (the async buses, SocketCAN through the socketcan crate, the
# od-runtime frame conversions) are off in the workspace build: lint and test them here. The
# vcan test runs where vcan0 exists and says it was skipped elsewhere.
step "od-bus with every feature (tokio, socketcan, od-runtime)"
cargo clippy -p od-bus --all-targets --all-features --locked -- -D warnings
cargo test -p od-bus --all-features --locked
cargo check -p drive --features socketcan --locked

# The firmware example for a Cortex-M4F, once per device, against the size budget (flash, RAM,
# a static stack bound, no core::fmt). `rustup target add` is a no-op when the target is there.
step "firmware size budget (thumbv7em-none-eabihf, cargo xtask size)"
rustup target add thumbv7em-none-eabihf
cargo xtask size

step "pytest (python-canopen against the simulated drives)"
export DRIVE_SIM="$target/debug/drive-sim"
export ODGEN="$target/debug/odgen"
set +e
"$PYTHON" -m pytest -q tests/python
rc=$?
set -e
if [ "$rc" -eq 5 ]; then
  echo "pytest collected no tests"
  exit 1
fi
exit "$rc"
