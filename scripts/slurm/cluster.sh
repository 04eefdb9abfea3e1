#!/usr/bin/env bash
# A one-node Slurm cluster for tests and for trying the --slurm path: munged, slurmctld and
# slurmd on this host, every file (munge key, slurm.conf, state, spool, logs, pid files) in
# one folder, every daemon started and stopped by its PID.
#
#   bash scripts/slurm/cluster.sh start DIR   start; prints the line to use it:
#                                             export SLURM_CONF=DIR/slurm/slurm.conf
#   bash scripts/slurm/cluster.sh stop DIR    cancel its jobs, stop its daemons, then end any
#                                             process still carrying this cluster's marker
#
# Needs Debian's slurm-wlm and munge (scripts/setup.sh installs them) and root (slurmd runs
# jobs as their submitting user). No cgroups: proctrack/linuxproc, task/none.
# Accounting is off (accounting_storage/none), so sacct has nothing; squeue and scontrol work.
set -euo pipefail

die() { echo "cluster: $*" >&2; exit 1; }
# the daemons live in sbin, which a non-login root shell may not have on its PATH
export PATH="$PATH:/usr/sbin:/sbin"

cmd=${1:-}
dir=${2:-}
if [ -z "$cmd" ] || [ -z "$dir" ]; then echo "usage: $0 start|stop DIR" >&2; exit 2; fi
dir=$(realpath -m "$dir")
conf=$dir/slurm/slurm.conf

# Every daemon (and so every job step it starts) carries this variable: `stop` ends exactly
# the processes whose environment holds it, and nothing else.
marker="PINSIM_SLURM_CLUSTER=$dir"

free_port() {  # a TCP port nobody listens on, 20000-59999
  local p used
  used=$(ss -Htln 2>/dev/null | awk '{print $4}' | sed 's/.*://' || true)
  for _ in $(seq 200); do
    p=$((20000 + RANDOM % 40000))
    grep -qx "$p" <<<"$used" || { echo "$p"; return; }
  done
  die "no free TCP port found"
}

start_daemon() {  # name, then the command; records the PID in DIR/pids/NAME
  local name=$1; shift
  env "$marker" setsid "$@" </dev/null >>"$dir/logs/$name.out" 2>&1 &
  echo $! >"$dir/pids/$name"
}

wait_until() {  # seconds, command...: 0 once the command succeeds, 1 if it never did
  local secs=$1; shift
  local end=$((SECONDS + secs))
  until "$@" >/dev/null 2>&1; do
    [ $SECONDS -lt $end ] || return 1
    sleep 0.2
  done
}

alive() { [ -f "$dir/pids/$1" ] && kill -0 "$(cat "$dir/pids/$1")" 2>/dev/null; }

show_log() { echo "---- $1 (last lines)" >&2; tail -n 15 "$1" >&2 2>/dev/null || true; }

start() {
  for c in munged mungekey slurmctld slurmd sbatch squeue scontrol sinfo; do
    command -v "$c" >/dev/null ||
      die "'$c' not found: install Debian's slurm-wlm and munge (bash scripts/setup.sh does)"
  done
  [ "$(id -u)" -eq 0 ] || die "needs root (slurmd starts jobs as their user); run as root"
  [ ! -e "$dir/pids/slurmctld" ] || die "$dir already holds a cluster (stop it first)"
  mkdir -p "$dir"/{munge,slurm/state,slurm/spool,logs,pids}
  chmod 700 "$dir" "$dir/munge"

  # munge: its own key, socket, pid and seed files
  mungekey --create --keyfile="$dir/munge/munge.key" 2>/dev/null ||
    dd if=/dev/urandom of="$dir/munge/munge.key" bs=1024 count=1 status=none
  chmod 400 "$dir/munge/munge.key"
  local sock=$dir/munge/munged.sock
  start_daemon munged munged --foreground --force --socket="$sock" \
    --key-file="$dir/munge/munge.key" --pid-file="$dir/munge/munged.pid" \
    --seed-file="$dir/munge/munged.seed" --log-file="$dir/logs/munged.log"
  if ! wait_until 10 test -S "$sock" || ! alive munged; then
    show_log "$dir/logs/munged.log"; show_log "$dir/logs/munged.out"
    die "munged did not start (see above)"
  fi

  # slurm.conf for this host: its short name, its real CPUs and memory (slurmd -C)
  local host node ctld_port slurmd_port
  host=$(hostname -s)
  node=$(slurmd -C | head -n 1 | sed 's/^NodeName=[^ ]*//')
  ctld_port=$(free_port)
  slurmd_port=$(free_port)
  [ "$ctld_port" != "$slurmd_port" ] || slurmd_port=$((ctld_port + 1))
  cat >"$conf" <<CONF
# One-node test cluster written by scripts/slurm/cluster.sh; everything lives in $dir.
ClusterName=pinsimtest
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$sock
CredType=cred/munge
StateSaveLocation=$dir/slurm/state
SlurmdSpoolDir=$dir/slurm/spool
SlurmctldPidFile=$dir/slurm/slurmctld.pid
SlurmdPidFile=$dir/slurm/slurmd.pid
SlurmctldLogFile=$dir/logs/slurmctld.log
SlurmdLogFile=$dir/logs/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
# no cgroups on this machine: track processes by parent pid, bind nothing
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SwitchType=switch/none
ReturnToService=2
SchedulerType=sched/backfill
# start a pending shard as soon as a CPU frees (the default may hold batch jobs submitted in
# the last 3 s: a 3 s gap before the third of three short shards)
SchedulerParameters=batch_sched_delay=0
SelectType=select/cons_tres
# cores only: a job without --mem does not take the whole node's memory
SelectTypeParameters=CR_Core
InactiveLimit=0
KillWait=5
MinJobAge=300
SlurmdTimeout=300
NodeName=$host NodeAddr=127.0.0.1$node State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF

  export SLURM_CONF=$conf
  start_daemon slurmctld slurmctld -D -i -f "$conf"
  start_daemon slurmd slurmd -D -f "$conf"
  if ! wait_until 30 bash -c "sinfo -h -n $host -o %t | grep -qx idle"; then
    alive slurmctld || echo "cluster: slurmctld is not running" >&2
    alive slurmd || echo "cluster: slurmd is not running" >&2
    show_log "$dir/logs/slurmctld.log"; show_log "$dir/logs/slurmctld.out"
    show_log "$dir/logs/slurmd.log"; show_log "$dir/logs/slurmd.out"
    stop
    die "the cluster did not come up within 30 s (ports $ctld_port/$slurmd_port; logs above)"
  fi
  echo "cluster: up in $dir (node $host, ports $ctld_port/$slurmd_port)"
  echo "export SLURM_CONF=$conf"
}

# PIDs of processes whose environment carries this cluster's marker.
marked_pids() {
  local f
  # -z: environ entries are NUL separated; -x: the whole entry
  grep -lzxF "$marker" /proc/[0-9]*/environ 2>/dev/null | while read -r f; do
    f=${f#/proc/}
    [ "${f%/environ}" = "$$" ] || echo "${f%/environ}"
  done
  true
}

stop() {
  export SLURM_CONF=$conf
  if alive slurmctld; then
    scancel --quiet --full --user="$(id -un)" 2>/dev/null || true
    # shellcheck disable=SC2016  # expanded by the inner shell, on every try
    wait_until 10 bash -c '[ -z "$(squeue -h -o %i 2>/dev/null)" ]' || true
  fi
  local name pid
  for name in slurmd slurmctld munged; do
    if alive "$name"; then kill -TERM "$(cat "$dir/pids/$name")" 2>/dev/null || true; fi
  done
  for name in slurmd slurmctld munged; do
    if alive "$name"; then
      pid=$(cat "$dir/pids/$name")
      wait_until 10 bash -c "! kill -0 $pid 2>/dev/null" || kill -KILL "$pid" 2>/dev/null || true
    fi
    rm -f "$dir/pids/$name"
  done
  for pid in $(marked_pids); do kill -KILL "$pid" 2>/dev/null || true; done
  local left
  left=$(marked_pids)
  [ -z "$left" ] || die "processes still running after stop: $left"
  echo "cluster: stopped ($dir)"
}

case $cmd in
  start) start ;;
  stop) stop ;;
  *) echo "usage: $0 start|stop DIR" >&2; exit 2 ;;
esac
