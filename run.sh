#!/usr/bin/env bash
# The main job: the reference task of spec/tasks/paper.toml end to end.
# Rolls out the paper's published optimum eta-hat and writes out/paper/{trajectory.csv,
# summary.json} (cargo fetches and builds everything on first use).
set -euo pipefail
cd "$(dirname "$0")"
ETA_HAT=3.14771,0.809316,1.12249,0.754006,4.7352,0.406031,-4.1572,4.29895
cargo run --release -q -p host-sim -- rollout spec/tasks/paper.toml --eta="$ETA_HAT" --out out/paper
cat out/paper/summary.json
