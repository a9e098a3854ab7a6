#!/usr/bin/env bash
# Checks the checked-in C header: regenerates ffi/include/reactionless.h with cbindgen (the
# crates.io release, ^0.29: Debian's 0.24 cannot parse edition 2024's #[unsafe(no_mangle)])
# and fails on any difference; then compiles it with gcc -std=c99, g++ -std=c++11 and
# arm-none-eabi-gcc, every warning an error.
# BLESS=1 scripts/check-header.sh writes the regenerated header (commit it with the change
# to ffi/src that caused it; an ABI change also bumps RL_ABI_VERSION).
set -euo pipefail
cd "$(dirname "$0")/.."
if ! cbindgen --version 2>/dev/null | grep -q '^cbindgen 0\.29'; then
  echo "needs cbindgen 0.29: cargo install cbindgen --version ^0.29 --locked" >&2
  exit 2
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
(cd ffi && cbindgen -q --config cbindgen.toml --crate reactionless-ffi --output "$tmp/reactionless.h" .)
if [ "${BLESS:-0}" = 1 ]; then
  cp "$tmp/reactionless.h" ffi/include/reactionless.h
  echo "blessed ffi/include/reactionless.h"
fi
if ! diff -u ffi/include/reactionless.h "$tmp/reactionless.h"; then
  echo "FAIL: ffi/include/reactionless.h differs from cbindgen's output for ffi/src;" \
    "run BLESS=1 scripts/check-header.sh if the change is intended" >&2
  exit 1
fi
echo "ok: the header is cbindgen's output for ffi/src"
cat > "$tmp/use.c" <<'C'
#include "reactionless.h"
int main(void) {
    static rl_planner p;
    rl_plan plan;
    return RL_PLANNER_INIT(&p) == RL_OK && rl_planner_step(&p, 1, &plan) == RL_E_NO_TASK ? 0 : 1;
}
C
warn=(-Wall -Wextra -Wpedantic -Werror)
gcc -std=c99 "${warn[@]}" -fsyntax-only -I ffi/include "$tmp/use.c"
echo "ok: gcc -std=c99 ${warn[*]}"
g++ -std=c++11 "${warn[@]}" -fsyntax-only -I ffi/include -x c++ "$tmp/use.c"
echo "ok: g++ -std=c++11 ${warn[*]}"
if command -v arm-none-eabi-gcc >/dev/null; then
  arm-none-eabi-gcc -std=c99 "${warn[@]}" -mcpu=cortex-m7 -mthumb -mfloat-abi=hard \
    -mfpu=fpv5-d16 -fsyntax-only -I ffi/include "$tmp/use.c"
  echo "ok: arm-none-eabi-gcc -std=c99 ${warn[*]} (cortex-m7)"
else
  echo "FAIL: arm-none-eabi-gcc not found (apt-get install gcc-arm-none-eabi)" >&2
  exit 1
fi
