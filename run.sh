#!/usr/bin/env bash
# The main job: the reference task (spec/tasks/paper.toml) end to end.
# Builds host-sim with the `test` profile (optimised, no LTO: the same build `cargo test
# --workspace` then reuses; cargo's progress shows on the first run), plans the task to its
# goal (the pose within 1e-6 m and 1e-4 deg), writes out/paper/ (plan.json, summary.json,
# trajectory.csv, task.toml, robot.urdf), prints a short summary, and checks the written
# trajectory independently (host-sim check): the last line is its verdict.
set -euo pipefail
cd "$(dirname "$0")"
cargo build --profile test -p host-sim
H=target/debug/host-sim
"$H" plan spec/tasks/paper.toml --out out/paper
echo
"$H" check out/paper
