#!/usr/bin/env bash
# A single-node Slurm cluster that lives entirely inside one directory, for tests.
#
#   slurm_cluster.sh start  DIR [PORT_BASE]   start munged, slurmctld and slurmd; wait until
#                                             the node is idle; write DIR/env
#   slurm_cluster.sh stop   DIR               stop everything started in DIR (also after a
#                                             start that failed halfway)
#   slurm_cluster.sh status DIR               print the daemons and the node; exit 0 when
#                                             all daemons run and the node answers
#
# After start, `. DIR/env` sets SLURM_CONF so that sbatch, squeue, scontrol... talk to this
# cluster. PORT_BASE (default 16817): SlurmctldPort = PORT_BASE, SlurmdPort = PORT_BASE + 1;
# two clusters on one machine need different bases. Needs root (slurmd starts jobs as
# their user) and Debian's slurm-wlm and munge. Nothing outside DIR is written: munged
# gets its own key, socket, pid, log and seed files; the daemons run in the foreground,
# detached by setsid, each with its pid in DIR/pids and, in its environment,
# SHOAL_SLURM_CLUSTER=DIR, which every process they start (slurmstepd) inherits: stop
# ends exactly the processes carrying that mark, by pid.
set -euo pipefail

readonly START_TIMEOUT_S=${SLURM_CLUSTER_START_TIMEOUT_S:-30}
readonly STOP_TIMEOUT_S=10

usage() {
  sed -n '2,12p' "$0" | sed 's/^# \{0,1\}//'
}

die() {
  echo "slurm_cluster.sh: $*" >&2
  exit 1
}

# The pids of the processes that carry this cluster's mark (daemons and what they started).
marked_pids() {
  local dir=$1 env_file pid
  for env_file in /proc/[0-9]*/environ; do
    pid=${env_file#/proc/}
    pid=${pid%/environ}
    if grep -sqzxF "SHOAL_SLURM_CLUSTER=$dir" "$env_file"; then
      echo "$pid"
    fi
  done
}

is_ours() {
  local dir=$1 pid=$2
  grep -sqzxF "SHOAL_SLURM_CLUSTER=$dir" "/proc/$pid/environ"
}

write_config() {
  local dir=$1 port_base=$2 node cpus
  node=$(hostname -s)
  cpus=$(nproc)
  cat >"$dir/slurm.conf" <<EOF
# Single-node test cluster in $dir (written by slurm_cluster.sh).
ClusterName=shoaltest
SlurmctldHost=$node(127.0.0.1)
SlurmctldPort=$port_base
SlurmdPort=$((port_base + 1))
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$dir/munge/munge.socket
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool/%n
SlurmctldPidFile=$dir/run/slurmctld.pid
SlurmdPidFile=$dir/run/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
SchedulerParameters=batch_sched_delay=0
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
MpiDefault=none
MailProg=/bin/true
ReturnToService=2
MinJobAge=600
NodeName=$node NodeAddr=127.0.0.1 CPUs=$cpus State=UNKNOWN
PartitionName=debug Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF
  # The default cgroup/v2 fails on a mixed v1/v2 hierarchy; with proctrack/linuxproc and
  # task/none nothing else of cgroups is used.
  echo "CgroupPlugin=cgroup/v1" >"$dir/cgroup.conf"
  mkdir -p "$dir/spool/$node"
  echo "export SLURM_CONF=$dir/slurm.conf" >"$dir/env"
}

# Starts one daemon in the foreground, under setsid, its output in DIR/log/NAME.out.
launch() {
  local dir=$1 name=$2
  shift 2
  SHOAL_SLURM_CLUSTER=$dir SLURM_CONF=$dir/slurm.conf \
    setsid "$@" </dev/null >"$dir/log/$name.out" 2>&1 &
  echo $! >"$dir/pids/$name"
}

show_logs() {
  local dir=$1 f
  for f in "$dir"/log/*; do
    [ -s "$f" ] || continue
    echo "---- $f (last 30 lines)" >&2
    tail -n 30 "$f" >&2
  done
}

node_state() {
  SLURM_CONF=$1/slurm.conf timeout 5 sinfo -h -N -o '%T' 2>/dev/null | head -n 1
}

wait_idle() {
  local dir=$1 deadline state name
  deadline=$((SECONDS + START_TIMEOUT_S))
  while [ "$SECONDS" -lt "$deadline" ]; do
    for name in munged slurmctld slurmd; do
      if ! kill -0 "$(cat "$dir/pids/$name")" 2>/dev/null; then
        echo "slurm_cluster.sh: $name exited during start" >&2
        return 1
      fi
    done
    state=$(node_state "$dir" || true)
    [ "$state" = idle ] && return 0
    sleep 0.1
  done
  echo "slurm_cluster.sh: the node is not idle after ${START_TIMEOUT_S} s" \
       "(state: ${state:-no answer})" >&2
  return 1
}

wait_munge() {
  local dir=$1 i
  for i in $(seq 100); do
    [ -S "$dir/munge/munge.socket" ] && return 0
    kill -0 "$(cat "$dir/pids/munged")" 2>/dev/null || break
    sleep 0.05
  done
  echo "slurm_cluster.sh: munged did not open its socket (iteration $i)" >&2
  return 1
}

start() {
  local dir=$1 port_base=$2
  [ "$(id -u)" = 0 ] || die "start needs root (slurmd runs jobs as their user)"
  local tool
  for tool in munged mungekey slurmctld slurmd sinfo setsid; do
    command -v "$tool" >/dev/null ||
      die "$tool not found (Debian packages slurm-wlm and munge)"
  done
  if ! [[ "$port_base" =~ ^[0-9]+$ ]] || [ "$port_base" -lt 1024 ] ||
     [ "$port_base" -gt 65534 ]; then
    die "PORT_BASE must be an integer in 1024..65534 (got '$port_base')"
  fi
  [ -d "$dir" ] || die "no directory $dir"
  [ ! -e "$dir/pids" ] || die "$dir already holds a cluster (stop it first)"
  mkdir -p "$dir"/{munge,state,spool,run,log,pids}
  # munged refuses a socket directory that others can write to.
  chmod 700 "$dir" "$dir/munge"
  write_config "$dir" "$port_base"
  mungekey --create --keyfile="$dir/munge/munge.key" >"$dir/log/mungekey.out" 2>&1 ||
    { show_logs "$dir"; die "mungekey failed"; }
  launch "$dir" munged munged --foreground --force \
    --key-file="$dir/munge/munge.key" --socket="$dir/munge/munge.socket" \
    --pid-file="$dir/munge/munged.pid" --log-file="$dir/log/munged.log" \
    --seed-file="$dir/munge/munged.seed"
  if ! wait_munge "$dir"; then
    show_logs "$dir"
    stop "$dir"
    exit 1
  fi
  launch "$dir" slurmctld slurmctld -D -c -f "$dir/slurm.conf"
  launch "$dir" slurmd slurmd -D -f "$dir/slurm.conf"
  if ! wait_idle "$dir"; then
    show_logs "$dir"
    stop "$dir"
    exit 1
  fi
  echo "slurm_cluster.sh: cluster up in $dir (ports $port_base, $((port_base + 1)));" \
       "use: . $dir/env"
}

# Sends SIG to every pid given that still carries the mark, then waits for them to end.
end_pids() {
  local dir=$1 sig=$2 pid left deadline
  shift 2
  for pid in "$@"; do
    if is_ours "$dir" "$pid"; then
      kill "-$sig" "$pid" 2>/dev/null || true
    fi
  done
  deadline=$((SECONDS + STOP_TIMEOUT_S))
  while :; do
    left=0
    for pid in "$@"; do
      is_ours "$dir" "$pid" && left=1
    done
    [ "$left" = 0 ] && return 0
    [ "$SECONDS" -ge "$deadline" ] && return 1
    sleep 0.1
  done
}

stop() {
  local dir=$1 name pid pids=()
  [ -d "$dir/pids" ] || return 0
  # Jobs first, while slurmctld still answers: their processes end with their steps.
  if [ -f "$dir/slurm.conf" ] && [ -f "$dir/pids/slurmctld" ] &&
     is_ours "$dir" "$(cat "$dir/pids/slurmctld")"; then
    SLURM_CONF=$dir/slurm.conf timeout 5 scancel --user=root >/dev/null 2>&1 || true
  fi
  # slurmd before slurmctld before munged: each still has what it talks to while it ends.
  for name in slurmd slurmctld munged; do
    [ -f "$dir/pids/$name" ] || continue
    pid=$(cat "$dir/pids/$name")
    end_pids "$dir" TERM "$pid" || end_pids "$dir" KILL "$pid" || true
  done
  # Whatever the daemons started and left behind (slurmstepd, a job's processes).
  mapfile -t pids < <(marked_pids "$dir")
  if [ "${#pids[@]}" -gt 0 ]; then
    end_pids "$dir" TERM "${pids[@]}" || end_pids "$dir" KILL "${pids[@]}" || true
  fi
  mapfile -t pids < <(marked_pids "$dir")
  if [ "${#pids[@]}" -gt 0 ]; then
    echo "slurm_cluster.sh: processes of $dir still running: ${pids[*]}" >&2
    return 1
  fi
  rm -rf "$dir/pids"
}

status() {
  local dir=$1 name pid ok=0
  [ -d "$dir/pids" ] || { echo "no cluster in $dir"; return 1; }
  for name in munged slurmctld slurmd; do
    pid=$(cat "$dir/pids/$name" 2>/dev/null || echo "")
    if [ -n "$pid" ] && is_ours "$dir" "$pid"; then
      echo "$name: running (pid $pid)"
    else
      echo "$name: not running"
      ok=1
    fi
  done
  echo "node: $(node_state "$dir" || echo "no answer")"
  return "$ok"
}

main() {
  [ $# -ge 1 ] || { usage >&2; exit 2; }
  case $1 in
    -h|--help) usage; exit 0 ;;
  esac
  if [ $# -lt 2 ] || [ $# -gt 3 ]; then
    usage >&2
    exit 2
  fi
  local cmd=$1 dir
  dir=$(cd "$2" 2>/dev/null && pwd) || die "no directory $2"
  case $cmd in
    start) start "$dir" "${3:-16817}" ;;
    stop) stop "$dir" ;;
    status) status "$dir" ;;
    *) usage >&2; exit 2 ;;
  esac
}

main "$@"
