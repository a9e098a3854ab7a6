#!/usr/bin/env bash
# The main job: the reference task (spec/tasks/paper.toml) end to end.
# Builds host-sim with the `test` profile (opt-level 3 without the release profile's fat
# LTO, so about 2 minutes sooner on a fresh machine; cargo's progress shows on the first
# run), plans the task to its goal (the pose within 1e-6 m and 1e-4 deg), writes out/paper/
# (plan.json, summary.json, trajectory.csv, task.toml, robot.urdf), prints a short summary,
# and checks the written trajectory independently (host-sim check): the last line is its
# verdict.
# HOST_SIM=PATH runs a host-sim already built instead (CI: the one its test step built).
set -euo pipefail
cd "$(dirname "$0")"
if [ -n "${HOST_SIM:-}" ]; then
  H=$HOST_SIM
else
  cargo build --profile test -p host-sim
  H=target/debug/host-sim
fi
"$H" plan spec/tasks/paper.toml --out out/paper
echo
"$H" check out/paper
