#!/usr/bin/env bash
# Runs every test of the project: the Rust workspace (unit, snapshot, compile, property,
# corpus and interop tests), the generated-code freshness check, the Windows and macOS checks, and the
# Python end-to-end tests in which python-canopen drives the simulated devices.
# Installs what it needs (the Python venv in .venv, the thumbv7em-none-eabihf target). This is
# what .ci/run calls.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"

# Each step says when it starts, in seconds since the script started.
# With the CPU time the commands run so far have taken (user + system, all cores): on a busy
# machine the wall time says little, the CPU time still says where the time goes.
cpu_file=$(mktemp)
cpu() {
  times >"$cpu_file" # in this shell: `times` in a subshell counts none of its children
  cpu_s=$(awk 'END { split($1, u, "m"); split($2, s, "m"); printf "%.0f", u[1] * 60 + u[2] + s[1] * 60 + s[2] }' "$cpu_file")
}
step() { cpu; printf '\n==> [%4ss, cpu %ss] %s\n' "$SECONDS" "$cpu_s" "$*"; }
# A step that fails ends the run: the Python tests, when they run in the background, end with it.
pytest_pid=
size_pid=
trap 'rc=$?; [ -z "$pytest_pid" ] || kill -- "-$pytest_pid" 2>/dev/null || true; [ -z "$size_pid" ] || kill "$size_pid" 2>/dev/null || true; cpu; printf "\n==> [%4ss, cpu %ss] done (exit %s)\n" "$SECONDS" "$cpu_s" "$rc"; rm -f "$cpu_file"' EXIT

# The public EDS corpus lives beside the repository (../shared/eds-corpus) on the project's
# machines; the corpus tests say they are skipped when it is absent.
if [ -z "${EDS_CORPUS_DIR:-}" ] && [ -d "$root/../shared/eds-corpus" ]; then
  export EDS_CORPUS_DIR="$root/../shared/eds-corpus"
fi

# A CI run builds everything once from nothing: incremental compilation's caches cost time to
# write there and are never read again. A local run keeps them. Nor does a CI run write line
# tables for the workspace's crates (the dev profile's and build-override's, .cargo/config.toml):
# a failing test or program still says where (a panic's message has its file, line and column
# from the panic's location, not from debug info); only a backtrace's frames lose their lines,
# and nothing here prints one. The tests' build from a fresh clone, 2026-12-07, one after the
# other: 204 s of CPU (106 s) with line tables, 193 s (100 s) without, and a target directory
# of 0.9 GB instead of 1.3 GB. Exported, so that the tests' own inner builds (trybuild's
# project, the generated crates, the build-script project) and every later step keep the
# settings the tests' build was made with.
if [ -n "${CI:-}" ]; then
  export CARGO_INCREMENTAL=0
  export CARGO_PROFILE_DEV_DEBUG=false CARGO_PROFILE_DEV_BUILD_OVERRIDE_DEBUG=false
fi

# The venv is made (a minute on a fresh clone, most of it waiting on downloads) while the
# first cargo steps run; the Rust tests are the first to use it.
step "Python venv (python-canopen, python-can, pytest), in the background"
venv_out=$(mktemp)
"$root/scripts/venv.sh" >"$venv_out" 2>"$venv_out.err" &
venv_pid=$!
venv_ready() {
  if ! wait "$venv_pid"; then
    echo "scripts/venv.sh failed:" >&2
    cat "$venv_out.err" >&2
    exit 1
  fi
  cat "$venv_out.err"
  PYTHON=$(cat "$venv_out")
  export ODGEN_PYTHON="$PYTHON"
}

# `od-master top` is tested in a real terminal: tmux (tests/python/test_od_master_top.py).
if ! command -v tmux >/dev/null; then
  step "tmux (for od-master top's terminal test)"
  (apt-get update -qq && apt-get install -y -qq tmux) >/dev/null 2>&1 || echo "could not install tmux (apt-get install tmux)"
fi

# The library od-master builds without the command line's dependencies and without the code
# generator (the CLI is the package od-master-cli); proc macros' own dependencies do not count.
step "od-master's library: no clap, no code generator in its build"
lib_deps=$(cargo tree -p od-master -e normal,no-proc-macro --prefix none --locked)
if bad=$(grep -E '^(clap|clap_builder|syn|quote|proc-macro2|prettyplease|od-codegen) ' <<<"$lib_deps"); then
  echo "od-master's library depends on what only the command line or the generator needs:" >&2
  echo "$bad" | sort -u >&2
  exit 1
fi

step "cargo fmt --check"
cargo fmt --all -- --check

# Lints: clippy runs as the tests build. Cargo compiles the workspace's crates with
# scripts/clippy-rustc (clippy-driver, which is rustc with clippy's lints, every warning an
# error), the dependencies with rustc. One build where a `cargo clippy` check of every crate
# and dependency came first (294 s of CPU on a fresh clone, 2026-12-06); the linted build of
# the workspace's crates took 99 s of CPU where rustc alone took 148 s (clippy-driver runs
# fewer MIR optimisations). clippy-driver also leaves out rustc's debug-build checks of raw
# pointer dereferences (alignment, null) in the workspace's crates: the one place where such a
# read could go wrong, a generated dictionary's slots (od_runtime::__private_v3::slot), is
# aligned by construction (each slot is `offset_of!` of a field whose type `offset` checks at
# compile time), and the eds reader's unsafe code reads bytes. `--config` rather than an
# environment variable: the tests' own inner builds (the compile-fail project, the generated
# crates) must not inherit it. The settings are part of cargo's fingerprint, so every cargo
# command that reuses this build passes them.
lint=(--config "build.rustc-workspace-wrapper=\"$root/scripts/clippy-rustc\"")
# syn optimized a little, in this build only: od-codegen's corpus tests parse ~40 MB of
# generated code with it (their CPU 80 s unoptimized, 52 s optimized, for 18 s more to build
# it). Not in .cargo/config.toml, so that the tests' inner builds (trybuild's project, the
# generated crates, the build-script project), where syn only runs derive macros and the
# proc macro's small expansions, build it unoptimized: trybuild's project took 91 s of CPU
# with it optimized, 72 s without (2026-12-07).
syn_optimized=(--config 'profile.dev.package."syn@3".opt-level = 1')
tests_build=("${lint[@]}" "${syn_optimized[@]}")

# One build profile only: the benchmarks are compiled in the test profile and each runs once as
# a smoke test. Every target with tests (not `--all-targets`, which also builds the test harness
# of a target whose manifest says `test = false`, such as the generated dictionaries' crate: a
# second compile of 70,000 lines for no test). First the libraries, the binaries (every one:
# the Python tests run drive-sim, odgen, od-master and network-boot) and the tests; then
# `cargo test` adds the benchmarks and examples and runs them. The binaries are built with
# the dev-dependencies' features, as `cargo test` builds the ones its integration tests run;
# that each one builds with its own features is the cross-platform step's check below.
# One binary at a time, as cargo runs them: the machine is busy already. Tried on fresh clones
# (2026-12-06): every binary two at a time made od-bus's hub timing tests fail; only the
# CPU-bound packages' binaries two at a time (canopen-eds, od-codegen, od-macros, odgen) took
# 334 s where they take 303 s one at a time, each of them keeping both cores busy for most of
# its run (the inner `cargo check`s of generated code and the compile-fail project build their
# dependencies with two jobs; the test harness runs two tests at once).
step "cargo build (libraries, binaries, tests; clippy's lints, warnings denied)"
cargo build --workspace --lib --bins --tests --locked "${tests_build[@]}"

# The programs the Python tests run, from the tests' build. Where cargo puts what it builds:
# $CARGO_TARGET_DIR when set (relative to the root, as cargo reads it).
target=${CARGO_TARGET_DIR:-$root/target}
case "$target" in /*) ;; *) target="$root/$target" ;; esac
programs=(drive-sim odgen od-master network-boot inline-macro-user)
for bin in "${programs[@]}" xtask; do
  [ -x "$target/debug/$bin" ] || { echo "cargo build did not build $target/debug/$bin" >&2; exit 1; }
done

# The Python tests wait on the simulated drives' real time, not on the CPU (in one process:
# 6.4 minutes of wall time for 35 s of CPU), and every drive-sim, hub and client listens on a
# port the OS picks: so the test files run side by side, six at a time, largest first, each
# in a pytest of its own whose output is printed when it ends (on 2 cores, alone, 2026-11-29:
# four at a time 74 s, six 51 s, eight 45 s, the longest file taking 45 s). A file that fails,
# or collects no tests (pytest's exit code 5), fails the run. They run in the background
# from here on, beside the Rust tests, whose test binaries leave a core idle now and then
# (one long test at the end of a binary; 330 s of wall time for 580 s of CPU): they need a
# little over one core for a minute (the files were made to hold under two busy cores:
# `conftest.py`'s waits). Their output is printed, and their result counted, at the end.
# They run copies of the programs, so that nothing cargo does later can change a program
# under a running test; every program is named, so no test builds one itself (one did:
# test_macro_eds.py's `cargo build -p inline-macro-user` without the tests' settings,
# compiling the proc macro and its generator again while the docs built).
step "pytest (python-canopen against the simulated drives), six files at a time, in the background"
venv_ready
pytest_programs=$(mktemp -d)
for bin in "${programs[@]}"; do
  cp "$target/debug/$bin" "$pytest_programs/"
done
export DRIVE_SIM="$pytest_programs/drive-sim" ODGEN="$pytest_programs/odgen" OD_MASTER="$pytest_programs/od-master"
export NETWORK_BOOT="$pytest_programs/network-boot" INLINE_MACRO_USER="$pytest_programs/inline-macro-user"
pytest_logs=$(mktemp -d)
# In a process group of its own (setsid), so that a failing step can end all of it.
# shellcheck disable=SC2016
ls -S tests/python/test_*.py | setsid xargs -P 6 -I{} sh -c '
  log="$2/$(basename "$1").log"
  "$0" -m pytest -q -p no:cacheprovider "$1" >"$log" 2>&1
  rc=$?
  printf "\n--- %s (exit %s)\n" "$1" "$rc"
  cat "$log"
  [ "$rc" -eq 0 ]' "$PYTHON" {} "$pytest_logs" >"$pytest_logs/all.out" 2>&1 &
pytest_pid=$!
pytest_started=$SECONDS

step "cargo test (workspace, all targets)"
cargo test --workspace --tests --benches --examples --locked --no-fail-fast "${tests_build[@]}"

# The firmware example for a Cortex-M4F, once per device, against the size budget (flash, RAM,
# a static stack bound, no core::fmt), in the background from here: it builds in directories
# of its own (the `firmware` profile's, target/firmware and target/thumbv7em-none-eabihf), so
# it waits on no other step's cargo lock, and the doc tests below run on one core (11 s, 11 s
# of CPU on a fresh clone, 2026-12-07) and the .crate checks on about 1.3: the size check, 11 s
# and 15 s of CPU alone, fills the idle core. Its output is printed, and its result counted,
# after the platforms' check. `rustup target add` is a no-op when the target is there.
step "firmware size budget (thumbv7em-none-eabihf, cargo xtask size), in the background"
rustup target add thumbv7em-none-eabihf
size_log=$(mktemp)
# The xtask the tests' build built (`cargo xtask` would build it again: `cargo run -p xtask`
# resolves features for xtask alone, and recompiled the reader and the generator, 12 s).
"$target/debug/xtask" size >"$size_log" 2>&1 &
size_pid=$!
size_started=$SECONDS

# These leave the doc tests out: the examples in the docs, the crates' READMEs among
# them (each published crate's README is its front page).
step "doc tests (workspace)"
cargo test --workspace --doc --locked --no-fail-fast "${tests_build[@]}"

# The crates published on crates.io, in dependency order (drive, generated, devices, odgen,
# xtask, ui-tests and the examples are not published). Their docs build without a warning
# (docs.rs builds od-runtime with all features), and each one packages and compiles from its
# .crate alone. The packages hold the sources, README and license files only: "ignoring
# test/benchmark ..." is cargo saying so. --allow-dirty: a local run checks the working tree
# as it is.
published=(od-sidecar od-runtime od-bus od-master canopen-eds od-codegen od-macros)
# With the tests' build's syn: the proc macros the dependencies' docs need (serde_derive,
# thiserror-impl, tokio's and futures' macros) are that build's then, not compiled again with
# another syn (10 s of CPU, 2026-12-07).
step "docs of the published crates (warnings denied)"
RUSTDOCFLAGS="-D warnings" cargo doc --no-deps --all-features --locked "${published[@]/#/-p}" "${syn_optimized[@]}"

# Each .crate is unpacked and checked on its own, as crates.io will have it: the workspace
# crates it depends on come from their .crate files too (a workspace of the unpacked crates,
# crates.io's names patched to them), and each `cargo check -p` resolves only that crate's
# dependencies and features, as its users' builds do. A check rather than the build of
# `cargo package`'s own verification: what a .crate can lack (a file left out of `include`, a
# feature only a sibling turned on, a warning with a feature left off: `od-bus` without tokio
# warned of dead code) fails the check just as it fails the build; the build also generates
# the code of each crate and its dependencies again. Fresh clones, 2026-12-07, the Python tests
# running beside both: this check 50 s, cargo package's verification build 76 s (their CPU
# figures, 142 s and 193 s, included the Python tests', counted when they ended); alone after
# the tests (5b51792), this check took 33 s and 43 s of CPU.
step "cargo package (the published crates), each checked from its .crate alone (warnings denied)"
version=$(sed -n 's/^version = "\(.*\)"$/\1/p' Cargo.toml | head -n 1)
cargo package --no-verify --locked --allow-dirty "${published[@]/#/-p}"
unpacked="$target/package/check"
rm -rf "$unpacked"
mkdir -p "$unpacked"
{
  echo '[workspace]'
  echo 'resolver = "3"'
  printf 'members = ['
  printf '"%s", ' "${published[@]/%/-$version}"
  echo ']'
  echo '[patch.crates-io]'
  for crate in "${published[@]}"; do
    tar -xzf "$target/package/$crate-$version.crate" -C "$unpacked"
    echo "$crate = { path = \"$crate-$version\" }"
  done
} >"$unpacked/Cargo.toml"
# The workspace's lock file: the same dependency versions as every other step, offline.
cp Cargo.lock "$unpacked/Cargo.lock"
package_log=$(mktemp)
for crate in "${published[@]}"; do
  cargo check --offline --manifest-path "$unpacked/Cargo.toml" --target-dir "$target" -p "$crate" 2>&1 |
    tee -a "$package_log"
done
if grep -E '^warning: `[^`]+` \([^)]*\) generated [0-9]+ warnings?' "$package_log"; then
  echo "a published crate checked from its .crate alone has compiler warnings (above)" >&2
  exit 1
fi
rm -f "$package_log"

# The host crates and programs with their own features alone, as a user's `cargo build` gets
# them (the tests' build has the dev-dependencies' features too), for this machine (SocketCAN
# and slcan on Linux), Windows and macOS (slcan adapters are reached there through the
# serialport crate): a check, not a build, so no linker or SDK is needed, with warnings denied
# (a feature left off shows up as dead code). The three targets in one cargo run share the
# proc macros and build scripts, and take the tests' build's settings: its syn (od-macros'
# generator uses it) and clippy's lints, so the host side of od-macros (the reader, the
# generator, od-sidecar) is that build's, not compiled again without the lints, and the
# workspace's code for Windows and macOS is linted too (from an empty set of target
# directories after the tests' build: 86 s and 169 s of CPU with the lints, 92 s and 181 s
# without). This machine's target is named, so its check lands beside the tests' build rather
# than over it. Before 2026-12-07 a `cargo build` of every binary did this machine's part,
# and built the proc macros and the code generator again (136 s of CPU); the binaries the
# Python tests run now come from the tests' build. `rustup target add` is a no-op when the
# targets are there.
step "cargo check: the programs with their own features, for this machine, Windows and macOS (clippy's lints, warnings denied)"
rustup target add x86_64-pc-windows-gnu aarch64-apple-darwin
host=$(rustc -vV | sed -n 's/^host: //p')
hosts=(-p od-master -p od-master-cli -p odgen -p drive -p network-boot -p xtask -p inline-macro-user)
RUSTFLAGS="-D warnings" cargo check --locked --target "$host" --target x86_64-pc-windows-gnu \
  --target aarch64-apple-darwin "${hosts[@]}" "${tests_build[@]}"

# The firmware size budget, started before the doc tests: its output and result.
step "firmware size budget's results (started ${size_started}s)"
size_rc=0
wait "$size_pid" || size_rc=$?
size_pid=
cat "$size_log"
rm -f "$size_log"
if [ "$size_rc" -ne 0 ]; then
  echo "cargo xtask size failed (exit $size_rc, above)" >&2
  exit 1
fi

step "od-runtime without its optional services (lints, tests, benchmarks, doc examples)"
# od-runtime without the services a firmware may leave out (sdo-block, cia402, store): linted
# and tested, so what each feature's absence means (block refused with 0504 0001h, no CiA 402
# state machine, "save" refused with 0800 0020h) holds, and every other service still works.
# Linted as it builds, like the workspace's tests; the benchmarks build and run once too, and
# the doc examples run without those features as well. Without the tests' optimized syn:
# od-runtime alone resolves its dev-dependencies' features apart from the workspace, so the
# derive macros' syn is built again here, where it only runs derive macros (22 s of CPU
# optimized, 4 s not).
cargo test -p od-runtime --no-default-features --features embedded-can --all-targets --locked "${lint[@]}"
cargo test -p od-runtime --no-default-features --features embedded-can --doc --locked "${lint[@]}"


step "pytest's results (started ${pytest_started}s)"
pytest_rc=0
wait "$pytest_pid" || pytest_rc=$?
cat "$pytest_logs/all.out"
rm -rf "$pytest_programs" "$pytest_logs"
echo "pytest: $((SECONDS - pytest_started)) s from its start, exit $pytest_rc"
exit "$pytest_rc"
