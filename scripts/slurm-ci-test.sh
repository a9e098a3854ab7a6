#!/usr/bin/env bash
# CI test of the Slurm scripts (scripts/slurm/) on the single-node cluster that
# scripts/slurm-ci.sh sets up:
#   scripts/slurm-ci-test.sh HOST_SIM PLANDIR
# HOST_SIM is the host-sim binary, PLANDIR a `host-sim plan` output directory.
#  1. disperse: one run on this machine (--jobs 2) against a 3-shard job array merged by
#     the merge job (scripts/slurm/submit.sh --wait): runs.csv, summary.json, summary.md
#     and sensitivity.csv byte for byte (cmp), manifest.json but for its wall_time_s;
#  2. campaign: two 6-joint tasks x seeds 1..3, one run against a 2-shard array: runs.csv,
#     summary.md and manifest.json with their wall times left out (they differ run to run);
#  3. a failing shard: shard 2 of 3 exits 3 (through HOST_SIM_SETUP); submit.sh --wait
#     must exit 1, report shard 2 FAILED and the merge CANCELLED, and leave no merged/.
# Exits nonzero on any mismatch (with a diff), failed job or unexpected outcome.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$(pwd)

if [ $# -ne 2 ]; then
  echo "usage: $0 HOST_SIM PLANDIR" >&2
  exit 2
fi
abs() { (cd "$(dirname "$1")" && printf '%s/%s\n' "$(pwd)" "$(basename "$1")"); }
HOST_SIM=$(abs "$1")
PLANDIR=$(abs "$2")
[ -x "$HOST_SIM" ] || { echo "not executable: $HOST_SIM" >&2; exit 2; }
[ -d "$PLANDIR" ] || { echo "not a directory: $PLANDIR" >&2; exit 2; }
export HOST_SIM
submit=$repo/scripts/slurm/submit.sh
# A bound on each submit.sh --wait (s), so a stuck cluster fails the test instead of
# hanging CI; each takes a few seconds.
SUBMIT_TIMEOUT=${SUBMIT_TIMEOUT:-300}

t0=$SECONDS
step() { printf '\n-- %s (%ss)\n' "$1" "$((SECONDS - t0))"; }

sinfo -h -o %T 2>/dev/null | grep -Eq '^(idle|mixed|allocated)' || {
  echo "no Slurm node up (sinfo: $(sinfo -h -o %T 2>&1 | tr '\n' ' ')): run scripts/slurm-ci.sh first" >&2
  exit 1
}

# The work dir: under /tmp, readable and writable by the jobs (slurmd runs as root; the
# jobs run as this user).
W=$(mktemp -d /tmp/slurm-ci-test.XXXXXX)
chmod 755 "$W"
echo "work dir: $W"

passed=0 failed=0
same() { # same LABEL FILE_A FILE_B
  if cmp "$2" "$3"; then
    echo "same: $1"
    passed=$((passed + 1))
  else
    echo "DIFFERENT: $1 ($2 vs $3)"
    diff -u "$2" "$3" | head -n 60 || true
    failed=$((failed + 1))
  fi
}

# Copies SRC to DST without its wall times: the wall_time_s column of a CSV, the
# wall_time_s key of a JSON object; in a Markdown table, the columns whose header starts
# with "wall" and the rows whose first cell does.
no_wall() { # no_wall SRC DST
  python3 - "$1" "$2" <<'PY'
import csv, json, sys
src, dst = sys.argv[1], sys.argv[2]
with open(src, newline="") as f:
    text = f.read()
if src.endswith(".csv"):
    rows = list(csv.reader(text.splitlines()))
    keep = [i for i, name in enumerate(rows[0]) if name != "wall_time_s"]
    with open(dst, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        for row in rows:
            w.writerow([row[i] for i in keep if i < len(row)])
elif src.endswith(".json"):
    doc = json.loads(text)
    doc.pop("wall_time_s", None)
    with open(dst, "w") as f:
        json.dump(doc, f, indent=2)
        f.write("\n")
else:
    out, drop = [], None  # drop: the current table's wall columns (None: not in a table)
    for line in text.split("\n"):
        if not line.startswith("|"):
            out.append(line)
            drop = None
            continue
        cells = line.strip().strip("|").split("|")
        if drop is None:  # the header row
            drop = {i for i, c in enumerate(cells) if c.strip().lower().startswith("wall")}
        elif cells[0].strip().lower().startswith("wall"):
            continue
        out.append("|" + "|".join(c for i, c in enumerate(cells) if i not in drop) + "|")
    with open(dst, "w") as f:
        f.write("\n".join(out))
PY
}
same_no_wall() { # same_no_wall LABEL FILE_A FILE_B
  no_wall "$2" "$2.nowall"
  no_wall "$3" "$3.nowall"
  same "$1 (without wall times)" "$2.nowall" "$3.nowall"
}

dargs=(--samples 12 --seed 7 --mass-rel-sigma 0.05 --inertia-rel-sigma 0.10 --com-sigma-m 0.01)

step "disperse on one machine (--jobs 2)"
"$HOST_SIM" disperse "$PLANDIR" "${dargs[@]}" --jobs 2 --out "$W/one"

step "disperse as a 3-shard Slurm job array + merge (submit.sh --wait)"
timeout "$SUBMIT_TIMEOUT" "$submit" disperse --shards 3 --out "$W/array" --wait -- \
  "$PLANDIR" "${dargs[@]}"

step "disperse: one machine against the merged shards"
for f in runs.csv summary.json summary.md sensitivity.csv; do
  same "disperse $f" "$W/one/$f" "$W/array/merged/$f"
done
same_no_wall "disperse manifest.json" "$W/one/manifest.json" "$W/array/merged/manifest.json"

tasks=(tests/tasks/a/arm6/task_001.toml tests/tasks/a/arm6/task_002.toml)
for t in "${tasks[@]}"; do
  [ -f "$t" ] || { echo "missing task $t" >&2; exit 1; }
done

step "campaign on one machine: ${tasks[*]} x seeds 1..3 (--jobs 2)"
"$HOST_SIM" campaign "${tasks[@]}" --seeds 1..3 --jobs 2 --out "$W/camp-one"

step "campaign as a 2-shard Slurm job array + merge (submit.sh --wait)"
timeout "$SUBMIT_TIMEOUT" "$submit" campaign --shards 2 --out "$W/camp-array" --wait -- \
  "${tasks[@]}" --seeds 1..3

step "campaign: one machine against the merged shards"
for f in runs.csv summary.md manifest.json; do
  same_no_wall "campaign $f" "$W/camp-one/$f" "$W/camp-array/merged/$f"
done

step "a failing shard: shard 2 of 3 exits 3, so the merge must be cancelled"
cat >"$W/fail-shard-2.sh" <<'EOF'
# Sourced by the .sbatch scripts (HOST_SIM_SETUP): array task 2 fails.
if [ "${SLURM_ARRAY_TASK_ID:-}" = 2 ]; then
  echo "fail-shard-2.sh: failing array task 2 on purpose" >&2
  exit 3
fi
EOF
rc=0
HOST_SIM_SETUP="$W/fail-shard-2.sh" timeout "$SUBMIT_TIMEOUT" "$submit" disperse --shards 3 \
  --out "$W/fail" --wait -- "$PLANDIR" "${dargs[@]}" >"$W/fail.log" 2>&1 || rc=$?
sed 's/^/  | /' "$W/fail.log"
if [ "$rc" -eq 1 ] && [ ! -e "$W/fail/merged" ] &&
  grep -Eq '^  shard 2 .* FAILED +exit 3:0' "$W/fail.log" &&
  grep -Eq '^  merge .* CANCELLED .*DependencyNeverSatisfied' "$W/fail.log" &&
  grep -q '^submit.sh: FAILED' "$W/fail.log"; then
  echo "as expected: submit.sh exited 1, shard 2 FAILED, the merge CANCELLED, no merged/"
  passed=$((passed + 1))
else
  echo "UNEXPECTED: submit.sh exited $rc (want 1); log $W/fail.log"
  failed=$((failed + 1))
fi

printf '\n-- done in %ss; work dir %s\n' "$((SECONDS - t0))" "$W"
echo "slurm: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
