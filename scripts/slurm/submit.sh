#!/usr/bin/env bash
# Submits a sharded host-sim Monte Carlo run to Slurm: a job array of M shards
# (disperse.sbatch or campaign.sbatch, array tasks 1..M) and a merge job that runs once
# every shard has succeeded (--dependency=afterok:ARRAYJOB). A failed shard leaves the
# merge's dependency unsatisfiable, and Slurm cancels the merge (--kill-on-invalid-dep=yes).
#
#   scripts/slurm/submit.sh disperse|campaign --shards M --out OUTROOT [options] -- ARGS...
#
# ARGS are host-sim's own (disperse: PLANDIR --samples N --seed S ...; campaign:
# TASK.toml... --seeds A..B ...), without --out and --shard. Results: OUTROOT/shard-1..M,
# OUTROOT/merged (what one run on one machine writes), logs in OUTROOT/logs/.
#
# Options:
#   --shards M          number of shards (array tasks 1..M)
#   --out OUTROOT       output root (made absolute; must not hold a previous run)
#   --wait              block until the array and the merge have ended (polling squeue),
#                       print every job's final state; exit 0 only if every shard and the
#                       merge completed, 1 otherwise (with the failed jobs' logs)
#   --partition P       partition for both jobs (default: the cluster's default)
#   --cpus-per-task C   CPUs per shard (host-sim --jobs C; default: the script's 1)
#   --max-running K     at most K shards running at once (--array=1-M%K)
#   --sbatch-opt OPT    one more sbatch option for both jobs, e.g. --sbatch-opt=--time=4:00:00
#                       or --sbatch-opt=--account=proj (repeatable); SBATCH_* environment
#                       variables work too
# Environment: HOST_SIM (the binary; default host-sim on PATH; resolved to an absolute
# path here), HOST_SIM_SETUP (a file each job sources first, e.g. module loads),
# SUBMIT_POLL_MAX (--wait's longest interval between polls, s; default 30).
# Prints the job ids (`array_job=ID`, `merge_job=ID` lines).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)

usage() {
  sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//' >&2
  exit 2
}
die() { echo "submit.sh: $*" >&2; exit 2; }

[ $# -ge 1 ] || usage
kind=$1
shift
case "$kind" in
  disperse | campaign) ;;
  -h | --help) usage ;;
  *) die "first argument must be disperse or campaign, not '$kind'" ;;
esac

shards="" out="" wait="" throttle="" sbopts=() arrayopts=()
while [ $# -gt 0 ]; do
  case "$1" in
    --shards) shards=${2:?--shards needs a value}; shift 2 ;;
    --shards=*) shards=${1#*=}; shift ;;
    --out) out=${2:?--out needs a value}; shift 2 ;;
    --out=*) out=${1#*=}; shift ;;
    --wait) wait=1; shift ;;
    --partition) sbopts+=(--partition "${2:?--partition needs a value}"); shift 2 ;;
    --partition=*) sbopts+=(--partition "${1#*=}"); shift ;;
    --cpus-per-task) arrayopts+=(--cpus-per-task "${2:?--cpus-per-task needs a value}"); shift 2 ;;
    --cpus-per-task=*) arrayopts+=(--cpus-per-task "${1#*=}"); shift ;;
    --max-running) throttle=${2:?--max-running needs a value}; shift 2 ;;
    --max-running=*) throttle=${1#*=}; shift ;;
    --sbatch-opt) sbopts+=("${2:?--sbatch-opt needs a value}"); shift 2 ;;
    --sbatch-opt=*) sbopts+=("${1#*=}"); shift ;;
    --) shift; break ;;
    -h | --help) usage ;;
    *) die "unknown option '$1' (host-sim's arguments go after --)" ;;
  esac
done
[[ $shards =~ ^[1-9][0-9]*$ ]] || die "--shards M: a positive integer, not '$shards'"
[ -z "$throttle" ] || [[ $throttle =~ ^[1-9][0-9]*$ ]] || die "--max-running K: a positive integer, not '$throttle'"
[ -n "$out" ] || die "--out OUTROOT is required"
[ $# -gt 0 ] || die "no host-sim arguments after --"
for a in "$@"; do
  case "$a" in
    --out | --out=* | --shard | --shard=*) die "do not pass $a after --: submit.sh sets --out and --shard" ;;
  esac
done
command -v sbatch >/dev/null || die "sbatch not found (load the cluster's slurm module?)"

# The binary: an absolute path, so that the jobs find it wherever they start.
HOST_SIM=${HOST_SIM:-host-sim}
if [[ $HOST_SIM == */* ]]; then
  [ -x "$HOST_SIM" ] || die "HOST_SIM=$HOST_SIM is not executable"
  HOST_SIM=$(cd "$(dirname "$HOST_SIM")" && pwd)/$(basename "$HOST_SIM")
elif p=$(command -v "$HOST_SIM" 2>/dev/null); then
  HOST_SIM=$p
elif [ -z "${HOST_SIM_SETUP:-}" ]; then
  die "HOST_SIM=$HOST_SIM is not on PATH (set HOST_SIM=/path/to/host-sim)"
fi
if [ -n "${HOST_SIM_SETUP:-}" ]; then
  [ -r "$HOST_SIM_SETUP" ] || die "HOST_SIM_SETUP=$HOST_SIM_SETUP is not readable"
  HOST_SIM_SETUP=$(cd "$(dirname "$HOST_SIM_SETUP")" && pwd)/$(basename "$HOST_SIM_SETUP")
fi

mkdir -p "$out"
OUTROOT=$(cd "$out" && pwd)
for d in "$OUTROOT/merged" "$OUTROOT"/shard-*; do
  [ -e "$d" ] && die "$OUTROOT already holds a run ($d): choose a fresh --out"
done
mkdir -p "$OUTROOT/logs"
SHARDS=$shards
export OUTROOT SHARDS HOST_SIM
[ -z "${HOST_SIM_SETUP:-}" ] || export HOST_SIM_SETUP

# sbatch --parsable prints "jobid" or "jobid;cluster".
array_out=$(sbatch --parsable --export=ALL --array="1-$shards${throttle:+%$throttle}" "${sbopts[@]}" "${arrayopts[@]}" \
  --output="$OUTROOT/logs/$kind-%A_%a.out" "$here/$kind.sbatch" "$@") ||
  die "sbatch refused the array job (see its message above)"
array_job=${array_out%%;*}
echo "array_job=$array_job ($kind, shards 1..$shards, logs $OUTROOT/logs/$kind-${array_job}_I.out)"

merge_out=$(sbatch --parsable --export=ALL "${sbopts[@]}" --dependency="afterok:$array_job" \
  --kill-on-invalid-dep=yes --output="$OUTROOT/logs/merge-%j.out" "$here/merge.sbatch") || {
  echo "submit.sh: the merge job could not be submitted; array job $array_job goes on (scancel $array_job)" >&2
  exit 1
}
merge_job=${merge_out%%;*}
echo "merge_job=$merge_job (after every shard succeeds: $OUTROOT/merged)"
if [ -z "$wait" ]; then
  echo "watch with: squeue -j $array_job,$merge_job"
  exit 0
fi

# --wait: poll squeue until neither the array nor the merge is pending, running or
# completing. (Not sbatch --wait: it sleeps 2, 8, then 32 s between polls, and it exits 0
# for a merge cancelled because a shard failed.) The interval is about a tenth of the time
# waited so far, from 1 s up to SUBMIT_POLL_MAX seconds (default 30).
poll_max=${SUBMIT_POLL_MAX:-30}
[[ $poll_max =~ ^[1-9][0-9]*$ ]] || die "SUBMIT_POLL_MAX=$poll_max: a positive integer"
echo "waiting for the jobs to end (Ctrl-C stops waiting; the jobs go on: scancel $array_job $merge_job)"
waited=0 errors=0
while :; do
  if left=$(squeue -h -j "$array_job,$merge_job" -o %i 2>/dev/null); then
    errors=0
    [ -n "$left" ] || break
  else
    errors=$((errors + 1))
    if [ "$errors" -ge 10 ]; then
      echo "submit.sh: squeue failed 10 times in a row; stopped waiting" >&2
      break
    fi
  fi
  dt=$((1 + waited / 10))
  [ "$dt" -le "$poll_max" ] || dt=$poll_max
  sleep "$dt"
  waited=$((waited + dt))
done

# The final states, while slurmctld still holds the jobs (MinJobAge, 300 s by default).
failed=() merge_state="" bad_logs=()
echo "job states:"
while read -r line; do
  [ -n "$line" ] || continue
  id=$(sed -n 's/^JobId=\([0-9]*\).*/\1/p' <<<"$line")
  task=$(sed -n 's/.* ArrayTaskId=\([^ ]*\).*/\1/p' <<<"$line")
  state=$(sed -n 's/.* JobState=\([^ ]*\).*/\1/p' <<<"$line")
  reason=$(sed -n 's/.* Reason=\([^ ]*\).*/\1/p' <<<"$line")
  code=$(sed -n 's/.* ExitCode=\([^ ]*\).*/\1/p' <<<"$line")
  if [ -n "$task" ]; then
    name="shard $task (job ${array_job}_$task)"
    log="$OUTROOT/logs/$kind-${array_job}_$task.out"
  else
    name="merge (job $id)"
    log="$OUTROOT/logs/merge-$id.out"
    merge_state=$state
  fi
  [ "$reason" = None ] && reason=""
  printf '  %-28s %-10s exit %-5s %s\n' "$name" "$state" "$code" "$reason"
  if [ "$state" != COMPLETED ]; then
    failed+=("$name $state${reason:+ ($reason)}")
    [ -s "$log" ] && bad_logs+=("$log")
  fi
done < <({ scontrol show job -o "$array_job" 2>/dev/null || true; } |
  sed -n 's/.* ArrayTaskId=\([0-9][^ ]*\) .*/\1 &/p' | sort -n | cut -d' ' -f2-
  scontrol show job -o "$merge_job" 2>/dev/null || true)

if [ -z "$merge_state" ]; then
  # slurmctld no longer knows the merge: trust its log.
  echo "  merge (job $merge_job): no longer known to slurmctld; reading its log"
  if ! grep -qs '^merge: host-sim exited 0,' "$OUTROOT/logs/merge-$merge_job.out"; then
    failed+=("merge (job $merge_job): no success in its log")
  fi
fi
if [ ${#failed[@]} -ne 0 ]; then
  {
    echo "submit.sh: FAILED: ${#failed[@]} job(s) did not complete; logs in $OUTROOT/logs/"
    printf '  %s\n' "${failed[@]}"
    for f in "${bad_logs[@]}"; do
      echo "----- $f (last 20 lines)"
      tail -n 20 "$f"
    done
  } >&2
  exit 1
fi
echo "done: $OUTROOT/merged"
