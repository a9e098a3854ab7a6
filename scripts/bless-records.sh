#!/usr/bin/env bash
# Re-bless the golden certification records in tests/records/ after a justified change.
#
# A record pins the exact bits of a plan (eta, f, end pose, counts, trajectory digest).
# When a change is *meant* to move those bits (an algorithm change, a dependency bump), run
# this script, then review `git diff tests/records/`: say in the commit message which
# quantities moved and why. Never re-bless to silence an unexplained mismatch.
#
#   scripts/bless-records.sh                 # every record
#   scripts/bless-records.sh paper arm12-ms  # only these
#
# Each line: record name, task file, seed, refinement tolerance ("-" for none), strategy,
# what refinement drives (planner or truth), and optionally the integrator (`rk4`, `ab5`; Euler,
# the reference discretization, when absent). Every record is made with --paper (success at
# σ_e, refined only to the listed tolerance), the settings they were first blessed with,
# whatever the goal's defaults are. A task with [preshape] is recorded as a two-phase plan,
# the listed tolerance being the search's (the two-* records: 1e-6, the default goal's).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -q -p host-sim
H=target/release/host-sim
want=" $* "
while read -r name task seed refine strategy against integrator; do
  [ -z "$name" ] && continue
  if [ $# -gt 0 ] && [[ "$want" != *" $name "* ]]; then continue; fi
  args=(record "$task" --paper --seed "$seed" --strategy "$strategy"
        --refine-against "$against" --out "tests/records/$name.json")
  [ "$refine" != "-" ] && args+=(--refine-tolerance "$refine")
  [ -n "${integrator:-}" ] && args+=(--integrator "$integrator")
  "$H" "${args[@]}"
done <<'LIST'
paper             spec/tasks/paper.toml                      1  1e-6  cpso        planner
chaser7-task002   tests/records/tasks/chaser7/task_002.toml  5  -     cpso        planner
chaser7-task003   tests/records/tasks/chaser7/task_003.toml  5  1e-6  cpso        planner
arm6-task001      tests/records/tasks/arm6/task_001.toml     1  1e-6  cpso        planner
arm9-task002      tests/records/tasks/arm9/task_002.toml     2  -     cpso        planner
paper-ms          spec/tasks/paper.toml                      1  1e-9  multistart  planner
paper-ms-truth    spec/tasks/paper.toml                      2  1e-9  multistart  truth
chaser7-a005-ms   tests/tasks/a/chaser7/task_005.toml        3  -     multistart  planner
arm9-a007-ms      tests/tasks/a/arm9/task_007.toml           1  1e-9  multistart  planner
arm12-a003-ms     tests/tasks/a/arm12/task_003.toml          4  -     multistart  planner
arm6-a010-ms      tests/tasks/a/arm6/task_010.toml           5  1e-9  multistart  truth
paper-rk4-ms      spec/tasks/paper.toml                      1  1e-9  multistart  planner  rk4
paper-rk4         spec/tasks/paper.toml                      1  1e-6  cpso        planner  rk4
paper-ab5-ms      spec/tasks/paper.toml                      1  1e-9  multistart  planner  ab5
fixed-ref0-fa     tests/tasks/fixed/ref/1cm/ref-0.toml       1  1e-9  multistart  planner
two-chaser7-j20   tests/tasks/g/chaser7/joint20/task_001.toml 1  1e-6  multistart  planner
two-arm12-j30     tests/tasks/g/arm12/joint30/task_001.toml  1  1e-6  multistart  planner
LIST
