#!/usr/bin/env bash
# A campaign run on a Slurm cluster through scripts/slurm_sweep.sh, split into 3 array
# tasks and merged, gives the results of the same campaign run in one process: the same
# rows in the same order and the same summary, except for timings. Also checks that the
# shards split the points as --shard K/N says, and that no daemon or job process of the
# cluster outlives its stop.
#
# Usage: slurm_sweep_test.sh SOURCE_DIR SHOAL
# Exit 77 (ctest SKIP_RETURN_CODE) when not root or when Debian's slurm-wlm or munge is
# not installed (`make test` installs them); every other failure is a failure.
set -euo pipefail

src=${1:?usage: slurm_sweep_test.sh SOURCE_DIR SHOAL}
shoal=${2:?usage: slurm_sweep_test.sh SOURCE_DIR SHOAL}
readonly SHARDS=3
readonly POINTS=6
campaign=$src/tests/data/campaigns/delay_shards.toml
cluster_sh=$src/tests/slurm/slurm_cluster.sh

skip() {
  echo "SKIPPED: $*"
  exit 77
}

fail() {
  echo "FAILED: $*" >&2
  exit 1
}

[ "$(id -u)" = 0 ] || skip "needs root (slurmd starts jobs as their user)"
for tool in munged mungekey slurmctld slurmd sbatch scontrol scancel sinfo; do
  command -v "$tool" >/dev/null ||
    skip "$tool not found: install Debian's slurm-wlm and munge (make test does)"
done
command -v python3 >/dev/null || fail "python3 is needed to compare the results"
[ -x "$shoal" ] || fail "no shoal executable at $shoal"

work=$(mktemp -d /tmp/shoal-slurm-test.XXXXXX)
mkdir "$work/cluster"
cleanup() {
  local status=$?
  "$cluster_sh" stop "$work/cluster" || status=1
  rm -rf "$work"
  exit "$status"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# Two free ports in a row below the kernel's ephemeral range, so that two runs of this
# test (or a real slurmctld on 6817) do not meet.
port_base=$(python3 - <<'EOF'
import random, socket
for _ in range(200):
    base = random.randrange(20000, 32000, 2)
    socks = []
    try:
        for port in (base, base + 1):
            s = socket.socket()
            socks.append(s)
            s.bind(("", port))
    except OSError:
        continue
    finally:
        for s in socks:
            s.close()
    print(base)
    break
else:
    raise SystemExit("no two free ports in 20000..32000")
EOF
)

t0=$(date +%s.%N)
"$cluster_sh" start "$work/cluster" "$port_base"
t1=$(date +%s.%N)
# shellcheck disable=SC1091
. "$work/cluster/env"
daemon_pids=$(cat "$work/cluster/pids/"*)

status_slurm=0
"$src/scripts/slurm_sweep.sh" --shoal "$shoal" --shards "$SHARDS" --wait --poll 1 \
  "$campaign" "$work/slurm" || status_slurm=$?
t2=$(date +%s.%N)
status_local=0
"$shoal" sweep "$campaign" --out "$work/local" >"$work/local.out" 2>&1 || status_local=$?
t3=$(date +%s.%N)

# Some points pass and some fail: both runs say so with exit status 1.
if [ "$status_slurm" != 1 ] || [ "$status_local" != 1 ]; then
  cat "$work/local.out" >&2
  for f in "$work/slurm/slurm/"*.log; do
    echo "---- $f" >&2
    cat "$f" >&2
  done
  fail "exit statuses: slurm_sweep.sh --wait $status_slurm, shoal sweep $status_local (both should be 1)"
fi

python3 - "$work/slurm" "$work/local" "$SHARDS" "$POINTS" <<'EOF'
import csv, json, os, sys

slurm, local, shards, points = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
# What differs from one run of the same point to the next: the clocks.
TIMING = {"wall_s", "cpu_s", "wall_time_s", "realtime_factor"}

def fail(msg):
    sys.exit("FAILED: " + msg)

def rows(path):
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        header = [c for c in reader.fieldnames if c not in TIMING]
        return header, [{c: r[c] for c in header} for r in reader]

def untimed(node):
    if isinstance(node, dict):
        return {k: untimed(v) for k, v in node.items()
                if k not in TIMING and not k.endswith("wall_s") and not k.endswith("cpu_s")}
    if isinstance(node, list):
        return [untimed(v) for v in node]
    return node

header_s, rows_s = rows(os.path.join(slurm, "results.csv"))
header_l, rows_l = rows(os.path.join(local, "results.csv"))
if header_s != header_l:
    fail(f"results.csv columns differ:\n  merged {header_s}\n  local  {header_l}")
if len(rows_l) != points:
    fail(f"local results.csv has {len(rows_l)} rows, the campaign has {points} points")
for i, (a, b) in enumerate(zip(rows_s, rows_l)):
    if a != b:
        diff = {c: (a[c], b[c]) for c in header_s if a[c] != b[c]}
        fail(f"results.csv row {i} differs (merged, local): {diff}")
if len(rows_s) != len(rows_l):
    fail(f"merged results.csv has {len(rows_s)} rows, local {len(rows_l)}")
if [r["point"] for r in rows_s] != [str(i) for i in range(points)]:
    fail("merged results.csv is not in point order: " + str([r["point"] for r in rows_s]))
if len({r["pass"] for r in rows_l}) != 2:
    fail("the campaign should have passing and failing points: " + str([r["pass"] for r in rows_l]))

with open(os.path.join(slurm, "summary.json")) as f:
    summary_s = untimed(json.load(f))
with open(os.path.join(local, "summary.json")) as f:
    summary_l = untimed(json.load(f))
if summary_s != summary_l:
    fail("summary.json differs:\n  merged " + json.dumps(summary_s, sort_keys=True) +
         "\n  local  " + json.dumps(summary_l, sort_keys=True))

# Shard K holds the points whose index % N == K - 1.
for k in range(1, shards + 1):
    _, shard_rows = rows(os.path.join(slurm, f"shard-{k}", "results.csv"))
    got = [int(r["point"]) for r in shard_rows]
    want = [p for p in range(points) if p % shards == k - 1]
    if got != want:
        fail(f"shard {k} of {shards} ran points {got}, not {want}")
print(f"merged results of {shards} shards equal the local run: {points} rows, summary")
EOF

"$cluster_sh" stop "$work/cluster"
t4=$(date +%s.%N)
# A daemon that has exited may be a zombie for a moment, until init reaps it.
running() {
  local state
  state=$(ps -o stat= -p "$1" 2>/dev/null || true)
  [ -n "$state" ] && [ "${state:0:1}" != Z ]
}
for pid in $daemon_pids; do
  for _ in $(seq 20); do
    running "$pid" || break
    sleep 0.1
  done
  ! running "$pid" || fail "daemon pid $pid ($(ps -o args= -p "$pid")) still runs after stop"
done
for env_file in /proc/[0-9]*/environ; do
  if grep -sqzxF "SHOAL_SLURM_CLUSTER=$work/cluster" "$env_file"; then
    fail "process ${env_file//[^0-9]/} of the cluster still runs after stop"
  fi
done
awk -v t0="$t0" -v t1="$t1" -v t2="$t2" -v t3="$t3" -v t4="$t4" 'BEGIN {
  printf "times (s): cluster start %.1f, slurm sweep %.1f, local sweep %.1f, stop %.1f\n",
         t1 - t0, t2 - t1, t3 - t2, t4 - t3 }'
