#!/usr/bin/env bash
# Re-bless the golden certification records in tests/records/ after a justified change.
#
# A record pins the exact bits of a plan (eta, f, end pose, counts, trajectory digest).
# When a change is *meant* to move those bits (an algorithm change, a dependency bump), run
# this script, then review `git diff tests/records/`: say in the commit message which
# quantities moved and why. Never re-bless to silence an unexplained mismatch.
#
# Each line: record name, task file, seed, refinement tolerance ("-" for none).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -q -p host-sim
H=target/release/host-sim
while read -r name task seed refine; do
  [ -z "$name" ] && continue
  args=(record "$task" --seed "$seed" --out "tests/records/$name.json")
  [ "$refine" != "-" ] && args+=(--refine-tolerance "$refine")
  "$H" "${args[@]}"
done <<'LIST'
paper             spec/tasks/paper.toml              1  1e-6
chaser7-task002   tests/records/tasks/chaser7/task_002.toml  5  -
chaser7-task003   tests/records/tasks/chaser7/task_003.toml  5  1e-6
arm6-task001      tests/records/tasks/arm6/task_001.toml     1  1e-6
arm9-task002      tests/records/tasks/arm9/task_002.toml     2  -
LIST
