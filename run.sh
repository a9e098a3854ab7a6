#!/usr/bin/env bash
# The main job: the reference task (spec/tasks/paper.toml) end to end.
# Builds host-sim with the `test` profile (opt-level 3 without the release profile's fat
# LTO, so about 2 minutes sooner on a fresh machine; cargo's progress shows on the first
# run), plans the task to its goal (the pose within 1e-6 m and 1e-4 deg), writes out/paper/
# (plan.json, summary.json, trajectory.csv, task.toml, robot.urdf), prints a short summary,
# and checks the written trajectory independently (host-sim check): the last line is its
# verdict.
# RUN_PROFILE=release uses the release build instead (CI: the one its earlier steps built).
set -euo pipefail
cd "$(dirname "$0")"
profile=${RUN_PROFILE:-test}
cargo build --profile "$profile" -p host-sim
case "$profile" in
  test | dev) H=target/debug/host-sim ;;
  *) H=target/$profile/host-sim ;;
esac
"$H" plan spec/tasks/paper.toml --out out/paper
echo
"$H" check out/paper
