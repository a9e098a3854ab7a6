#!/usr/bin/env bash
# Regenerates the checked-in generic-target benchmark tests/tasks/{g,h}/<robot>/<kind>/ with
# `host-sim generate --kind joint|perturbed --preshape` (issue #30): targets no rollout from
# the start made, planned in two phases. Per robot: end poses at configurations 5, 10, 20,
# 30 and 40 deg per joint from the start (4 tasks each), and rollout-made targets moved by
# 1 cm / 0.5 deg and 5 cm / 2 deg (4 each): 28 tasks per robot, 112 per set. Set g uses
# generate seed 301, set h seed 302 (a second set, to show the rates are not tuned to one).
# The starts are those of scripts/make-tasks.sh. The same command always writes the same
# files.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -q -p host-sim
H=target/release/host-sim
for set in g:301 h:302; do
  name=${set%%:*}; seed=${set##*:}
  while read -r robot urdf start; do
    [ -z "$robot" ] && continue
    for d in 05 10 20 30 40; do
      "$H" generate --urdf "$urdf" --ee ee --q-deg="$start" --count 4 --seed "$seed$d" \
        --kind joint --distance-deg "$d" --preshape --out "tests/tasks/$name/$robot/joint$d"
    done
    for mv in 1cm:0.01:0.5 5cm:0.05:2; do
      tag=${mv%%:*}; rest=${mv#*:}; m=${rest%%:*}; deg=${rest##*:}
      "$H" generate --urdf "$urdf" --ee ee --q-deg="$start" --count 4 --seed "$seed${tag%cm}" \
        --kind perturbed --move-m "$m" --move-deg "$deg" --preshape \
        --out "tests/tasks/$name/$robot/moved$tag"
    done
  done <<'LIST'
arm6     tests/robots/arm6.urdf   10,-20,30,-40,50,-60
chaser7  spec/chaser7.urdf        -60,30,20,60,-100,-60,20
arm9     tests/robots/arm9.urdf   10,-20,30,-40,50,-60,15,-25,35
arm12    tests/robots/arm12.urdf  10,-20,30,-40,50,-60,15,-25,35,-45,20,-30
LIST
done
