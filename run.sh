#!/usr/bin/env bash
# The main job: the reference task (spec/tasks/paper.toml) end to end.
# Plans it with C-PSO and refines the result to f <= 1e-6, then writes out/paper/:
# plan.json, trajectory.csv, summary.json (cargo fetches and builds everything on first use).
set -euo pipefail
cd "$(dirname "$0")"
cargo run --release -q -p host-sim -- plan spec/tasks/paper.toml --refine-tolerance 1e-6 --out out/paper
cat out/paper/summary.json
