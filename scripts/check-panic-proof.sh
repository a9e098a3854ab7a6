#!/usr/bin/env bash
# Shows that the flight image's link-time panic check works: the release image links (no
# panic path survives optimisation), and the same image with one unremovable panic path
# (feature `panic-canary`) fails to link on the panic handler's undefined symbol.
set -euo pipefail
cd "$(dirname "$0")/../firmware"
build() {
  RUSTC=/usr/bin/rustc RUSTC_BOOTSTRAP=1 cargo --config ../.ci/thumb-firmware.toml \
    build --release "$@" 2>&1
}
if ! out=$(build); then
  echo "FAIL: the release image does not link:"; echo "$out"; exit 1
fi
echo "ok: the release image links: no panic path survives optimisation"
if out=$(build --features panic-canary); then
  echo "FAIL: an image with a known panic path linked; the check does not work"; exit 1
fi
if ! grep -q "reactionless_firmware_panic_path_survived_optimisation" <<<"$out"; then
  echo "FAIL: the canary build failed for another reason:"; echo "$out"; exit 1
fi
echo "ok: an image with one panic path fails to link (undefined panic-path symbol)"
# Leave the normal image in place.
build >/dev/null
