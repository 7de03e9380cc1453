#!/usr/bin/env bash
# Runs a `shoal sweep` campaign on a Slurm cluster: one array task per shard, then a job
# that merges the shards once every task has ended (docs/campaigns.md, "Running a campaign
# on a Slurm cluster").
set -euo pipefail

readonly PROG=${0##*/}

usage() {
  cat <<EOF
Usage: $PROG [OPTIONS] CAMPAIGN OUT_DIR

Submits CAMPAIGN (a shoal sweep campaign file) to Slurm as an array job of N tasks, task K
running
    shoal sweep CAMPAIGN --out OUT_DIR/shard-K --shard K/N
and a merge job that starts when every task has ended (whatever their status) and runs
    shoal sweep merge OUT_DIR/shard-1 ... OUT_DIR/shard-N --out OUT_DIR
which fails when a shard is missing or incomplete. Prints the two job ids.

Options:
  -n, --shards N        number of shards, one array task each (default 4)
  --shoal PATH          the shoal executable; it must be at the same path on the compute
                        nodes, as must CAMPAIGN, its scenario and OUT_DIR
                        (default: shoal on PATH)
  -p, --partition NAME  Slurm partition for both jobs
  -t, --time LIMIT      time limit of each array task (sbatch --time syntax)
  --merge-time LIMIT    time limit of the merge job (default: the partition's)
  --sbatch-arg ARG      one more argument for sbatch, given to both jobs; repeatable
                        (e.g. --sbatch-arg=--account=proj --sbatch-arg=--cpus-per-task=4)
  --wait                wait for the merge job; exit with its exit status
                        (0: every point passed, 1: some point failed, 2: bad input)
  --poll SECONDS        with --wait: how often to ask Slurm about the merge job (default 5)
  -h, --help            this text

OUT_DIR must not exist or be empty, so that no earlier campaign's shards are merged.
Slurm's own output goes to OUT_DIR/slurm/ (shard-K.log, merge.log).
Exit status: 0 submitted (with --wait: the merge job's status), 2 bad usage or input,
3 sbatch or scontrol failed.
EOF
}

die_usage() {
  echo "$PROG: $*" >&2
  echo "Try '$PROG --help'." >&2
  exit 2
}

die_slurm() {
  echo "$PROG: $*" >&2
  exit 3
}

# Globals set by ParseArgs.
shards=4
shoal=""
partition=""
task_time=""
merge_time=""
wait_merge=0
poll_s=5
sbatch_extra=()
positional=()

need_value() {
  [ "$2" -ge 2 ] || die_usage "option $1 needs a value"
}

parse_args() {
  while [ $# -gt 0 ]; do
    case $1 in
      -h|--help) usage; exit 0 ;;
      -n|--shards) need_value "$1" $#; shards=$2; shift 2 ;;
      --shards=*) shards=${1#*=}; shift ;;
      --shoal) need_value "$1" $#; shoal=$2; shift 2 ;;
      --shoal=*) shoal=${1#*=}; shift ;;
      -p|--partition) need_value "$1" $#; partition=$2; shift 2 ;;
      --partition=*) partition=${1#*=}; shift ;;
      -t|--time) need_value "$1" $#; task_time=$2; shift 2 ;;
      --time=*) task_time=${1#*=}; shift ;;
      --merge-time) need_value "$1" $#; merge_time=$2; shift 2 ;;
      --merge-time=*) merge_time=${1#*=}; shift ;;
      --sbatch-arg) need_value "$1" $#; sbatch_extra+=("$2"); shift 2 ;;
      --sbatch-arg=*) sbatch_extra+=("${1#*=}"); shift ;;
      --wait) wait_merge=1; shift ;;
      --poll) need_value "$1" $#; poll_s=$2; shift 2 ;;
      --poll=*) poll_s=${1#*=}; shift ;;
      --) shift; positional+=("$@"); break ;;
      -*) die_usage "unknown option $1" ;;
      *) positional+=("$1"); shift ;;
    esac
  done
}

# Makes the inputs absolute and checks them; the jobs run elsewhere, later.
check_inputs() {
  [ "${#positional[@]}" -eq 2 ] ||
    die_usage "expected CAMPAIGN and OUT_DIR (got ${#positional[@]} argument(s))"
  campaign=${positional[0]}
  out=${positional[1]}
  [[ "$shards" =~ ^[1-9][0-9]*$ ]] || die_usage "--shards must be a positive integer (got '$shards')"
  [[ "$poll_s" =~ ^[1-9][0-9]*$ ]] || die_usage "--poll must be a positive integer (got '$poll_s')"
  if [ ! -f "$campaign" ] || [ ! -r "$campaign" ]; then
    die_usage "cannot read campaign file '$campaign'"
  fi
  campaign=$(cd "$(dirname "$campaign")" && pwd)/$(basename "$campaign")
  if [ -z "$shoal" ]; then
    shoal=$(command -v shoal) || die_usage "shoal is not on PATH; give it with --shoal PATH"
  fi
  if [ ! -f "$shoal" ] || [ ! -x "$shoal" ]; then
    die_usage "'$shoal' is not an executable file"
  fi
  shoal=$(cd "$(dirname "$shoal")" && pwd)/$(basename "$shoal")
  if [ -e "$out" ] && { [ ! -d "$out" ] || [ -n "$(ls -A "$out")" ]; }; then
    die_usage "OUT_DIR '$out' exists and is not an empty directory"
  fi
  command -v sbatch >/dev/null || die_slurm "sbatch not found (is this a Slurm login node?)"
  command -v scontrol >/dev/null || die_slurm "scontrol not found"
  mkdir -p "$out/slurm" || die_usage "cannot create '$out/slurm'"
  out=$(cd "$out" && pwd)
}

common_sbatch_args() {
  common=(--parsable)
  [ -z "$partition" ] || common+=("--partition=$partition")
  common+=("${sbatch_extra[@]}")
}

# The array job: task K runs shard K of N.
submit_shards() {
  local args=("${common[@]}" "--array=1-$shards" "--job-name=shoal-sweep"
              "--output=$out/slurm/shard-%a.log")
  [ -z "$task_time" ] || args+=("--time=$task_time")
  sbatch "${args[@]}" <<EOF
#!/bin/bash
set -euo pipefail
k=\$SLURM_ARRAY_TASK_ID
exec $(printf '%q' "$shoal") sweep $(printf '%q' "$campaign") \\
  --out $(printf '%q' "$out")/shard-\$k --shard "\$k/$shards"
EOF
}

# The merge job: names every shard, so that a missing one is an error of merge.
submit_merge() {
  local array_id=$1 k dirs=""
  for k in $(seq 1 "$shards"); do
    dirs+=" $(printf '%q' "$out/shard-$k")"
  done
  sbatch "${common[@]}" "--dependency=afterany:$array_id" --kill-on-invalid-dep=yes \
    --job-name=shoal-sweep-merge "--output=$out/slurm/merge.log" \
    ${merge_time:+"--time=$merge_time"} <<EOF
#!/bin/bash
set -euo pipefail
exec $(printf '%q' "$shoal") sweep merge$dirs --out $(printf '%q' "$out")
EOF
}

# One field (NAME=value) of `scontrol show job -o ID`.
job_field() {
  local line=$1 name=$2 word words
  read -ra words <<<"$line"
  for word in "${words[@]}"; do
    case $word in
      "$name="*) echo "${word#*=}"; return 0 ;;
    esac
  done
  return 1
}

# Waits until the merge job has ended; exits with its status.
wait_for_merge() {
  local id=$1 line state code status signal failures=0
  while :; do
    if line=$(scontrol show job -o "$id" 2>&1); then
      failures=0
      state=$(job_field "$line" JobState || echo UNKNOWN)
      case $state in
        PENDING|RUNNING|CONFIGURING|COMPLETING|SUSPENDED|REQUEUED|RESIZING|SIGNALING|\
        STAGE_OUT|REQUEUE_HOLD|REQUEUE_FED|RESV_DEL_HOLD|UNKNOWN) ;;
        *) break ;;
      esac
    else
      # A controller that does not answer for a while is not the job's end.
      failures=$((failures + 1))
      [ "$failures" -lt 12 ] || die_slurm "scontrol show job $id failed: $line"
    fi
    sleep "$poll_s"
  done
  code=$(job_field "$line" ExitCode || echo "1:0")
  status=${code%%:*}
  signal=${code##*:}
  echo "$PROG: merge job $id ended: $state, exit code $code (log: $out/slurm/merge.log)"
  if [ "$status" != 0 ] || [ "$signal" != 0 ] || [ "$state" != COMPLETED ]; then
    if [ -s "$out/slurm/merge.log" ]; then
      echo "---- $out/slurm/merge.log (last 20 lines)" >&2
      tail -n 20 "$out/slurm/merge.log" >&2
    fi
    [ "$signal" = 0 ] || exit $((128 + signal))
    [ "$status" = 0 ] || exit "$status"
    exit 1
  fi
  exit 0
}

main() {
  parse_args "$@"
  check_inputs
  common_sbatch_args
  local array_id merge_id
  if ! array_id=$(submit_shards); then
    # Leave OUT_DIR as it was, so that the same command can be run again.
    rmdir "$out/slurm" "$out" 2>/dev/null || true
    die_slurm "sbatch of the shard array failed"
  fi
  array_id=${array_id%%;*}
  echo "array job: $array_id ($shards shards, logs $out/slurm/shard-K.log)"
  if ! merge_id=$(submit_merge "$array_id"); then
    scancel "$array_id" 2>/dev/null || true
    die_slurm "sbatch of the merge job failed; cancelled array job $array_id"
  fi
  merge_id=${merge_id%%;*}
  echo "merge job: $merge_id (after $array_id; results in $out)"
  [ "$wait_merge" = 0 ] || wait_for_merge "$merge_id"
}

main "$@"
