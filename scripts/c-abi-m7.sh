#!/usr/bin/env bash
# The C ABI on the Cortex-M7: builds the thumbv7em-none-eabihf staticlib of ffi/ (release,
# fat LTO), checks that no panic path survives in it (its panic handler calls a symbol that
# exists nowhere: `nm -u` must not name it), builds the C ABI test (ffi/tests/c/abi_test.c,
# the host test's program) with Debian's arm-none-eabi-gcc and newlib against it, runs it
# under QEMU mps2-an500 with semihosting, and compares its bits (eta, f, counts, trajectory
# digest) with `host-sim record` of the same task, and its closed-loop flight through rl_loop
# (the commands' digest) with the same C program's on the host (which ffi/tests/c_abi.rs holds
# to the core's PlanLoop); then the two-phase C test
# (ffi/tests/c/two_phase_test.c: a two-phase block planned with rl_two_phase across a
# checkpoint and restore, both phases streamed) in the same image, whose lines must equal
# the same C code's on the host (which ffi/tests/c_abi.rs holds to host-sim's plan). Prints
# the C program's stack high-water mark and the stack of each call.
# Needs Debian's rustc-web, rust-web-src, lld, qemu-system-arm, gcc-arm-none-eabi,
# libnewlib-arm-none-eabi, binutils-arm-none-eabi (see .ci/run).
set -euo pipefail
cd "$(dirname "$0")/.."
out=target/c-abi-m7
mkdir -p "$out"

# Only the staticlib: with the rlib crate type as well, rustc skips LTO and the archive holds
# every crate's objects (core's panic machinery included) instead of one optimised object.
RUSTC=/usr/bin/rustc RUSTC_BOOTSTRAP=1 \
  cargo --config .ci/thumb.toml rustc -q -p reactionless-ffi --release --crate-type staticlib
lib=target/thumb/thumbv7em-none-eabihf/release/libreactionless_ffi.a
ls -l "$lib"
if arm-none-eabi-nm -u "$lib" 2>/dev/null | grep -q panic_path_survived; then
  echo "FAIL: a panic path survives in $lib:"
  arm-none-eabi-nm -u "$lib" | grep panic_path_survived
  exit 1
fi
echo "ok: nm -u finds no panic path in the archive"

# HOST_SIM: a host-sim already built (CI: its test step's); else the release build.
if [ -n "${HOST_SIM:-}" ]; then
  hs=$HOST_SIM
else
  cargo build -q --release -p host-sim
  hs=target/release/host-sim
fi
$hs block spec/tasks/paper.toml --out "$out/paper.block"
$hs block tests/records/tasks/chaser7/task_002.toml --out "$out/other.block"
$hs record spec/tasks/paper.toml --out "$out/paper.json"
$hs block tests/tasks/g/chaser7/joint20/task_001.toml --out "$out/two_phase.block"
for b in other two_phase; do
  [ "$(stat -c %s "$out/$b.block")" -le 16384 ] || { echo "FAIL: $b.block exceeds its 16 KiB slot"; exit 1; }
done

# The two-phase test on the host, against the host staticlib (the test profile's, which
# the README's test command has built in CI): the reference for the M7's.
cargo build -q --profile test -p reactionless-ffi
gcc -std=c99 -O2 -Wall -Wextra -Wpedantic -Werror -I ffi/include \
  ffi/tests/c/two_phase_test.c ffi/tests/c/two_phase_main.c \
  target/debug/libreactionless_ffi.a -lpthread -ldl -lm -o "$out/two_phase_host"
"$out/two_phase_host" "$out/two_phase.block" > "$out/two_phase_host.txt"
gcc -std=c99 -O2 -Wall -Wextra -Wpedantic -Werror -I ffi/include \
  ffi/tests/c/abi_test.c ffi/tests/c/host_main.c \
  target/debug/libreactionless_ffi.a -lpthread -ldl -lm -o "$out/abi_host"
"$out/abi_host" "$out/paper.block" "$out/other.block" > "$out/abi_host.txt"

cflags=(-std=c99 -O2 -Wall -Wextra -Wpedantic -Werror -mcpu=cortex-m7 -mthumb
  -mfloat-abi=hard -mfpu=fpv5-d16 -ffunction-sections -fdata-sections)
arm-none-eabi-gcc "${cflags[@]}" -I ffi/include -nostartfiles --specs=nosys.specs \
  -T ffi/tests/c/m7/link.ld -Wl,--gc-sections \
  ffi/tests/c/m7/main.c ffi/tests/c/abi_test.c ffi/tests/c/two_phase_test.c "$lib" -lc -lgcc \
  -o "$out/abi_test.elf"
arm-none-eabi-size "$out/abi_test.elf"

timeout 1200 qemu-system-arm -machine mps2-an500 -cpu cortex-m7 -nographic -monitor none \
  -serial none -semihosting-config enable=on,target=native \
  -icount shift=0,align=off,sleep=off \
  -device loader,file="$out/paper.block",addr=0x203f0000 \
  -device loader,file="$out/other.block",addr=0x203f8000 \
  -device loader,file="$out/two_phase.block",addr=0x203fc000 \
  -kernel "$out/abi_test.elf" 2>&1 | tee "$out/output.txt"

python3 - "$out/output.txt" "$out/paper.json" "$out/two_phase_host.txt" "$out/abi_host.txt" <<'PY'
import json, sys
lines = open(sys.argv[1]).read().splitlines()
got = dict(l.rsplit(" ", 1) for l in lines if " " in l)
rec = json.load(open(sys.argv[2]))["outputs"]
want = {
    "RESULT": "ok", "FAILURES": "0", "STATUS": rec["status"],
    "ITERATIONS": str(rec["iterations"]), "ROLLOUTS": str(rec["rollouts"]),
    "STAGNATION": str(rec["stagnation_events"]), "RESTARTS": str(rec["restarts"]),
    "F": rec["f_bits"], "SAMPLES": str(rec["trajectory_samples"]),
    "DIGEST": rec["trajectory_digest"],
}
want.update({f"ETA {i}": b for i, b in enumerate(rec["eta_bits"])})
host = dict(l.rsplit(" ", 1) for l in open(sys.argv[3]).read().splitlines() if " " in l)
# The stack and the checkpoint's size are the target's own.
two = {k: v for k, v in host.items()
       if k.startswith("TWO_") and k not in ("TWO_STACK_STEP", "TWO_CHECKPOINT_BYTES")}
if len(two) < 20 or host.get("TWO_STATUS") != "2":  # RL_CONVERGED
    print(f"FAIL: the host's two-phase C test did not converge: {host}")
    sys.exit(1)
want.update(two)
abi_host = dict(l.rsplit(" ", 1) for l in open(sys.argv[4]).read().splitlines() if " " in l)
loop = {k: abi_host.get(k) for k in ("LOOP_DIGEST", "LOOP_CYCLES", "LOOP_MODE")}
if None in loop.values() or loop["LOOP_MODE"] != "4":  # RL_LOOP_DONE
    print(f"FAIL: the host's C test did not fly the loop to its end: {loop}")
    sys.exit(1)
want.update(loop)
bad = [(k, got.get(k), v) for k, v in want.items() if got.get(k) != v]
if bad:
    for k, g, v in bad:
        print(f"FAIL {k}: Cortex-M7 {g}, host record {v}")
    sys.exit(1)
print(f"ok: the Cortex-M7 C program matches host-sim's record bit for bit "
      f"(eta, f, {rec['rollouts']} rollouts, digest {rec['trajectory_digest']}), "
      f"across a checkpoint and restore at frame {got['RESTORED_AT_FRAME']}")
print(f"ok: the Cortex-M7 closed-loop flight through rl_loop matches the host's bit for bit "
      f"({got['LOOP_CYCLES']} cycles, commands' digest {got['LOOP_DIGEST']}); "
      f"sizeof(rl_loop) {got['SIZES loop']} bytes")
print(f"ok: the Cortex-M7 two-phase C test matches the host's bit for bit ({len(two)} lines: "
      f"q_s, eta, f, {got['TWO_ROLLOUTS']} rollouts, both phases' digests), across a "
      f"checkpoint and restore at frame 10; stack of rl_two_phase_step {got['TWO_STACK_STEP']} bytes, "
      f"two-phase checkpoint {got['TWO_CHECKPOINT_BYTES']} bytes")
print(f"stack high-water {got['STACK max']} bytes of {got['STACK size']}; per call: "
      + ", ".join(f"{k.split()[1]} {v}" for k, v in got.items() if k.startswith("STACK ")
                  and k.split()[1] not in ("max", "size")))
PY
