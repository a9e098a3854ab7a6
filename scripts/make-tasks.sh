#!/usr/bin/env bash
# Regenerates the checked-in reachable task sets tests/tasks/{a,b}/<robot>/ with
# `host-sim generate` (the generator's own random stream, so planning a task with any
# planner seed never starts from the η that made it). Set a uses generate seed 101, set b
# seed 202; the starts are fixed per robot. The same command always writes the same files.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -q -p host-sim
H=target/release/host-sim
for set in a:101 b:202; do
  name=${set%%:*}; seed=${set##*:}
  while read -r robot urdf start; do
    [ -z "$robot" ] && continue
    "$H" generate --urdf "$urdf" --ee ee --q-deg="$start" --count 20 --seed "$seed" \
      --out "tests/tasks/$name/$robot"
  done <<'LIST'
arm6     tests/robots/arm6.urdf   10,-20,30,-40,50,-60
chaser7  spec/chaser7.urdf        -60,30,20,60,-100,-60,20
arm9     tests/robots/arm9.urdf   10,-20,30,-40,50,-60,15,-25,35
arm12    tests/robots/arm12.urdf  10,-20,30,-40,50,-60,15,-25,35,-45,20,-30
LIST
done
