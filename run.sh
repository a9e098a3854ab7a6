#!/usr/bin/env bash
# The main job: the reference task (spec/tasks/paper.toml) end to end.
# Builds host-sim (cargo's progress shows on the first run, a few minutes), plans the task
# with the default strategy and refines to f <= 1e-6, writes out/paper/ (plan.json,
# summary.json, trajectory.csv, task.toml, robot.urdf), prints a short summary, and checks
# the written trajectory independently (host-sim check): the last line is its verdict.
set -euo pipefail
cd "$(dirname "$0")"
cargo build --release -p host-sim
H=target/release/host-sim
"$H" plan spec/tasks/paper.toml --refine-tolerance 1e-6 --out out/paper
echo
"$H" check out/paper
