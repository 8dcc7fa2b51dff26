#!/bin/sh
# The main job end to end: generate the typed dictionaries from the device files (rewriting only
# what changed, with a diff of the device files since the last generation), then
# run a simulated Camozzi DRVI in process on the virtual clock (boot-up, PDO mapping, NMT start,
# CiA 402 state machine, homing, an absolute move in degrees through real CANopen frames),
# print what happened and write the plot and the trace.
#
#   scripts/demo.sh            (from anywhere inside the repository)
set -eu
cd "$(dirname "$0")/.."
cargo xtask gen
cargo run -q -p drive --bin drive-sim -- demo --plot target/demo/drvi.svg --trace target/demo/drvi.csv
echo
echo "plot:  $(pwd)/target/demo/drvi.svg"
echo "trace: $(pwd)/target/demo/drvi.csv"
