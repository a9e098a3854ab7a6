#!/usr/bin/env bash
# Builds the flight image (firmware/, release: opt-level 3, fat LTO, link-time panic check)
# and the QEMU instruction-counting plugin; prints the image's path.
# Needs Debian's rustc-web, rust-web-src and lld (see .ci/run) and gcc.
set -euo pipefail
cd "$(dirname "$0")/.."
(cd firmware && RUSTC=/usr/bin/rustc RUSTC_BOOTSTRAP=1 \
  cargo --config ../.ci/thumb-firmware.toml build --release -q)
mkdir -p target/qemu
gcc -shared -fPIC -O2 -Wall -Wextra -o target/qemu/libinsn.so firmware/qemu/insn.c
echo "target/firmware/thumbv7em-none-eabihf/release/reactionless-firmware"
