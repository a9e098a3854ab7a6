#!/usr/bin/env bash
# Sets up a single-node Slurm cluster on localhost, for CI on a fresh Debian machine (as
# root, or with sudo): Debian's slurm-wlm and munge, one node (this host, all its CPUs),
# one partition `debug`, no accounting, no cgroups. The daemons are started directly (no
# systemd needed) and keep running when this script exits; it ends by running one test
# job (srun true). Running it again restarts them cleanly with a freshly written
# configuration.
#
#   scripts/slurm-ci.sh            # then: sinfo, sbatch, scripts/slurm/submit.sh ...
#
# Files: /etc/slurm/slurm.conf, /etc/munge/munge.key (made if missing), state under
# /var/spool/slurmctld and /var/spool/slurmd, logs in /var/log/slurm/.
set -euo pipefail
start=$SECONDS
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive

LOGDIR=/var/log/slurm
CONF=/etc/slurm/slurm.conf
CTLD_PID=/run/slurmctld.pid
SLURMD_PID=/run/slurmd.pid

say() { printf '[slurm-ci %3ss] %s\n' "$((SECONDS - start))" "$*"; }

dump_logs() {
  for f in "$LOGDIR/slurmctld.log" "$LOGDIR/slurmd.log" /var/log/munge/munged.log; do
    echo "----- $f (last 60 lines)"
    $SUDO tail -n 60 "$f" 2>/dev/null || echo "(none)"
  done
  echo "----- sinfo"
  sinfo -N -l 2>&1 || true
  scontrol show node 2>&1 || true
}
fail() {
  echo "slurm-ci: $*" >&2
  dump_logs >&2
  exit 1
}

# Whether process $1 runs (a zombie, dead but not yet reaped, does not).
alive() {
  $SUDO kill -0 "$1" 2>/dev/null && ! grep -qs '^[^)]*) Z' "/proc/$1/stat"
}

# Stops the daemon whose pid file is $1 (only that process), waiting up to 20 s.
stop_pidfile() {
  local pidfile=$1 name=$2 pid
  [ -f "$pidfile" ] || return 0
  pid=$($SUDO cat "$pidfile" 2>/dev/null || true)
  if [ -n "$pid" ] && alive "$pid" &&
    [ "$(cat "/proc/$pid/comm" 2>/dev/null)" = "$name" ]; then
    say "stopping $name (pid $pid)"
    $SUDO kill -TERM "$pid" 2>/dev/null || true
    for _ in $(seq 1 100); do
      alive "$pid" || break
      sleep 0.2
    done
    if alive "$pid"; then
      say "$name (pid $pid) did not stop in 20 s: SIGKILL"
      $SUDO kill -KILL "$pid" 2>/dev/null || true
      sleep 0.5
    fi
  fi
  $SUDO rm -f "$pidfile"
}

# 1. Packages. A fresh machine has neither; policy-rc.d keeps the packages' scripts from
# starting the daemons before they are configured (Docker-style images already have one).
if ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null ||
  ! command -v munged >/dev/null || ! command -v sbatch >/dev/null; then
  say "installing slurm-wlm and munge"
  made_policy=""
  if [ ! -e /usr/sbin/policy-rc.d ]; then
    printf '#!/bin/sh\nexit 101\n' | $SUDO tee /usr/sbin/policy-rc.d >/dev/null
    $SUDO chmod 755 /usr/sbin/policy-rc.d
    made_policy=1
  fi
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq -o Dpkg::Use-Pty=0 slurm-wlm munge >/dev/null
  if [ -n "$made_policy" ]; then $SUDO rm -f /usr/sbin/policy-rc.d; fi
  say "installed: $(slurmctld -V)"
else
  say "already installed: $(slurmctld -V)"
fi

# 2. munge: a key (if missing), munged running as the munge user.
$SUDO install -d -o munge -g munge -m 0700 /etc/munge /var/lib/munge /var/log/munge
$SUDO install -d -o munge -g munge -m 0755 /run/munge
if ! $SUDO test -s /etc/munge/munge.key; then
  say "creating /etc/munge/munge.key"
  $SUDO dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 status=none
fi
$SUDO chown munge:munge /etc/munge/munge.key
$SUDO chmod 0400 /etc/munge/munge.key
if munge -n 2>/dev/null | unmunge >/dev/null 2>&1; then
  say "munged already running"
else
  stop_pidfile /run/munge/munged.pid munged
  say "starting munged"
  $SUDO rm -f /run/munge/munge.socket.2.lock
  $SUDO runuser -u munge -- /usr/sbin/munged
  for _ in $(seq 1 50); do
    munge -n 2>/dev/null | unmunge >/dev/null 2>&1 && break
    sleep 0.2
  done
  munge -n | unmunge >/dev/null || fail "munged does not answer"
fi

# 3. slurm.conf for this one node: CPUs = nproc, RealMemory as slurmd itself detects it
# (slurmd -C); config_overrides keeps a mismatch from draining the node anyway.
node=$(hostname -s)
cpus=$(nproc)
mem=$(slurmd -C 2>/dev/null | sed -n 's/.*RealMemory=\([0-9]*\).*/\1/p' | head -1)
if [ -z "$mem" ]; then mem=$(awk '/^MemTotal:/ {print int($2 / 1024)}' /proc/meminfo); fi
$SUDO install -d -m 0755 /etc/slurm "$LOGDIR" /var/spool/slurmctld /var/spool/slurmd
say "writing $CONF: node $node, CPUs=$cpus, RealMemory=$mem MB"
$SUDO tee "$CONF" >/dev/null <<EOF
# Written by scripts/slurm-ci.sh: a single-node CI cluster on localhost.
ClusterName=ci
SlurmctldHost=$node(127.0.0.1)
AuthType=auth/munge
CredType=cred/munge
SlurmUser=root
SlurmdUser=root
SlurmctldPort=6817
SlurmdPort=6818
StateSaveLocation=/var/spool/slurmctld
SlurmdSpoolDir=/var/spool/slurmd
SlurmctldPidFile=$CTLD_PID
SlurmdPidFile=$SLURMD_PID
SlurmctldLogFile=$LOGDIR/slurmctld.log
SlurmdLogFile=$LOGDIR/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
MpiDefault=none
MailProg=/bin/true
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SchedulerType=sched/backfill
# Schedule at once when a job is submitted or ends (the default waits up to 3 s), and run
# backfill every 2 s: the CI jobs take seconds.
SchedulerParameters=batch_sched_delay=0,bf_interval=2
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
ReturnToService=2
# Finished jobs stay visible to scontrol for 10 min (submit.sh --wait reads their states).
MinJobAge=600
SlurmctldTimeout=60
SlurmdTimeout=60
InactiveLimit=0
KillWait=10
Waittime=0
# The node as configured here, whatever slurmd detects (never drained for a mismatch).
SlurmdParameters=config_overrides
NodeName=$node NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=debug Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF

# 4. (Re)start the daemons: the old ones (if any) by their pid files, slurmd first.
stop_pidfile "$SLURMD_PID" slurmd
stop_pidfile "$CTLD_PID" slurmctld
say "starting slurmctld"
$SUDO slurmctld || fail "slurmctld did not start"
for _ in $(seq 1 50); do
  scontrol ping 2>/dev/null | grep -q UP && break
  sleep 0.2
done
scontrol ping | grep -q UP || fail "slurmctld does not answer"
say "starting slurmd"
$SUDO slurmd || fail "slurmd did not start"

# 5. Wait (60 s at most) until the node is idle; resume it if a previous run left it
# down or drained.
state=""
for i in $(seq 1 120); do
  state=$(sinfo -h -n "$node" -o %T 2>/dev/null | head -1 || true)
  case "$state" in
    idle) break ;;
    down* | drain*)
      if [ $((i % 10)) -eq 0 ]; then
        $SUDO scontrol update NodeName="$node" State=RESUME 2>/dev/null || true
      fi
      ;;
  esac
  sleep 0.5
done
[ "$state" = idle ] || fail "node $node is '${state:-unknown}', not idle, after 60 s"
sinfo
# 6. One step through the whole path (munge credentials, slurmd, slurmstepd).
timeout 60 srun --immediate=30 --nodes=1 --ntasks=1 true || fail "a test job (srun true) did not run"
say "single-node Slurm up (node $node idle, a test job ran) in $((SECONDS - start)) s"
