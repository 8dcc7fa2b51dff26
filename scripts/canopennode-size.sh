#!/usr/bin/env bash
# The C reference of `cargo xtask size` (issue #29): CANopenNode v4 at a pinned commit, built
# for the example firmware's Cortex-M4F the way a size-conscious C firmware is built, and its
# flash and RAM printed. A benchmark to repeat by hand, not a CI step.
#
#   scripts/canopennode-size.sh [CANOPENNODE_CHECKOUT]
#
# Needs arm-none-eabi-gcc and newlib-nano from the Debian packages:
#   apt-get install gcc-arm-none-eabi libnewlib-arm-none-eabi
# Without an argument, CANopenNode is cloned from GitHub and checked out at $COMMIT; with one,
# that checkout is used (it must be at $COMMIT).
#
# The build: its blank CAN driver and blank storage (example/CO_driver_blank.c,
# CO_storageBlank.c), its DS301 example dictionary (example/OD.c, 193 entries) and its default
# configuration (NMT, heartbeat producer and consumer, EMCY with history, SDO server
# segmented, SYNC, RPDO/TPDO with timers, TIME, LEDs, LSS slave, storage); static allocation
# (CO_USE_GLOBALS); example/main_blank.c with its log_printf made empty (no printf); the two
# functions a port calls from interrupts (tmrTask_thread, CO_CAN1InterruptHandler) kept as a
# vector table would keep them. -mcpu=cortex-m4 -mfpu=fpv4-sp-d16 -mfloat-abi=hard -Os -flto
# -ffunction-sections -fdata-sections, linked with --gc-sections and newlib-nano
# (nano.specs, nosys.specs). No vector table is counted (the Rust figure has 392 B of it).
set -euo pipefail

COMMIT=9b8beed
REPO=https://github.com/CANopenNode/CANopenNode.git
CC=${CC:-arm-none-eabi-gcc}
SIZE=${SIZE:-arm-none-eabi-size}

command -v "$CC" >/dev/null || { echo "no $CC: apt-get install gcc-arm-none-eabi libnewlib-arm-none-eabi" >&2; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

if [ $# -ge 1 ]; then
  src=$(cd "$1" && pwd)
else
  git clone --quiet "$REPO" "$work/CANopenNode"
  git -C "$work/CANopenNode" checkout --quiet "$COMMIT"
  src=$work/CANopenNode
fi
if [ -d "$src/.git" ] || git -C "$src" rev-parse --git-dir >/dev/null 2>&1; then
  have=$(git -C "$src" rev-parse --short=7 HEAD)
  [ "$have" = "$COMMIT" ] || { echo "$src is at $have, not $COMMIT" >&2; exit 1; }
fi

# main_blank.c without its printf logging.
sed 's/^#define log_printf(macropar_message, \.\.\.).*/#define log_printf(macropar_message, ...)/' \
  "$src/example/main_blank.c" >"$work/main_blank.c"
grep -q '^#define log_printf(macropar_message, ...)$' "$work/main_blank.c" \
  || { echo "main_blank.c: its log_printf definition changed; update this script" >&2; exit 1; }

sources=(
  "$src/example/CO_driver_blank.c" "$src/example/CO_storageBlank.c"
  "$src/301/CO_ODinterface.c" "$src/301/CO_NMT_Heartbeat.c" "$src/301/CO_HBconsumer.c"
  "$src/301/CO_Emergency.c" "$src/301/CO_SDOserver.c" "$src/301/CO_TIME.c" "$src/301/CO_SYNC.c"
  "$src/301/CO_PDO.c" "$src/303/CO_LEDs.c" "$src/305/CO_LSSslave.c" "$src/storage/CO_storage.c"
  "$src/CANopen.c" "$src/example/OD.c" "$work/main_blank.c"
)
flags=(-mcpu=cortex-m4 -mthumb -mfpu=fpv4-sp-d16 -mfloat-abi=hard -Os -flto
  -ffunction-sections -fdata-sections -DCO_USE_GLOBALS
  -I"$src/example" -I"$src")
"$CC" "${flags[@]}" "${sources[@]}" -o "$work/canopennode.elf" \
  --specs=nano.specs --specs=nosys.specs -Wl,--gc-sections \
  -Wl,--undefined=tmrTask_thread -Wl,--undefined=CO_CAN1InterruptHandler

"$SIZE" -A "$work/canopennode.elf" | awk '
  $1 == ".text" { text = $2 } $1 == ".rodata" { rodata = $2 } $1 == ".data" { data = $2 }
  $1 == ".bss" { bss = $2 }
  END {
    printf "CANopenNode %s (DS301 example): .text %d .rodata %d .data %d .bss %d\n", commit, text, rodata, data, bss
    printf "flash %d B (.text + .rodata + .data), RAM %d B (.data + .bss; heap and stack on top)\n", text + rodata + data, data + bss
  }' commit="$COMMIT"
