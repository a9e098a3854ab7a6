#!/usr/bin/env bash
# Runs every fuzz target for a bounded time (default 60 s each) from the seed corpus in
# fuzz/corpus/ (copied, so the checked-in corpus stays small). Needs cargo-fuzz
# (`cargo install cargo-fuzz --locked`); RUSTC_BOOTSTRAP=1 lets this stable toolchain use
# the sanitizer flags cargo-fuzz passes. Exit code non-zero on any crash.
# `scripts/fuzz.sh --build-only` builds every target and runs none (CI builds them while
# the single-threaded QEMU steps run).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-60}"
export RUSTC_BOOTSTRAP=1
# 16 codegen units instead of cargo-fuzz's 1: the ASan build of host-sim in parallel on
# every core, at the cost of somewhat slower runs (`cargo fuzz build --help`). Build and
# run must pass the same options, or the run rebuilds.
opts=(--codegen-units 16)
if [ "$seconds" = "--build-only" ]; then
  exec cargo fuzz build "${opts[@]}"
fi
for t in rollout task_block parse; do
  work="target/fuzz-corpus/$t"
  mkdir -p "$work"
  cp -n fuzz/corpus/$t/* "$work/" 2>/dev/null || true
  echo "== fuzz $t for ${seconds}s"
  log="target/fuzz-$t.log"
  status=0
  cargo fuzz run "${opts[@]}" "$t" "$work" -- -max_total_time="$seconds" -rss_limit_mb=4096 >"$log" 2>&1 \
    || status=$?
  grep -E "^#[0-9]+.*(DONE|pulse)|ERROR|panicked|SUMMARY|Done [0-9]+ runs" "$log" | tail -3 || true
  if [ "$status" -ne 0 ]; then
    # A build error or a crash: show what happened, not just that it did.
    tail -n 40 "$log"
    exit "$status"
  fi
done
