#!/usr/bin/env bash
# Benchmark: what the campaign machinery of `shoal sweep` costs on top of the runs it makes.
# Usage: bench/campaign_throughput.sh [BUILD_DIR] [POINTS] [DURATION_S] [REPEATS]
# Runs a POINTS-point `sim` campaign of the paper's Example 2 (one axis: run.seed), each
# point DURATION_S of mission time, REPEATS times, and prints per repeat
#   overhead = campaign wall time / (sum of the points' CPU times / cores)
# where a point's CPU time is its process's user + system time (shoal sweep records it from
# wait4, in results.jsonl's cpu_s). 1.00 means the cores did nothing but the runs. It also
# times a sample of the same runs one at a time outside any campaign, so the per-run CPU
# time under the campaign can be compared with that of a run alone.
set -euo pipefail
build=${1:-build}
points=${2:-1000}
duration=${3:-600}
repeats=${4:-3}
shoal="$(realpath "$build/tools/shoal")"
[ -x "$shoal" ] || { echo "bench: $shoal not built (run make demo or make test first)" >&2; exit 2; }
repo=$(pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cores=$(nproc)

cat >"$work/campaign.toml" <<TOML
[campaign]
scenario = "$repo/scenarios/paper_example2.toml"
engine = "sim"
duration_s = $duration
[[axis]]
key = "run.seed"
range = [1, $points]
[pass]
converged = true
TOML

echo "machine: $cores cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "command: shoal sweep CAMPAIGN --out DIR --quiet  ($points points of Example 2, $duration s each, $cores workers)"
for ((r = 1; r <= repeats; r++)); do
  rm -rf "$work/out"
  start=$(date +%s.%N)
  "$shoal" sweep "$work/campaign.toml" --out "$work/out" --quiet >/dev/null || [ $? -eq 1 ]
  end=$(date +%s.%N)
  python3 - "$work/out/results.jsonl" "$start" "$end" "$cores" <<'PY'
import json, sys
rows = [json.loads(line) for line in open(sys.argv[1])]
wall = float(sys.argv[3]) - float(sys.argv[2])
cpu = sum(r["cpu_s"] for r in rows)
cores = int(sys.argv[4])
print(f"repeat: {len(rows)} points, wall {wall:.2f} s, sum of point CPU {cpu:.2f} s, "
      f"ideal {cpu / cores:.2f} s, overhead {wall / (cpu / cores):.3f}, "
      f"median point CPU {sorted(r['cpu_s'] for r in rows)[len(rows) // 2] * 1000:.1f} ms")
PY
done

# The same runs alone: 20 points one after the other, each its own process, CPU from the
# shell's children rusage (user + system).
sample=20
total=0
for ((i = 1; i <= sample; i++)); do
  cpu=$( { /usr/bin/time -f "%U %S" "$shoal" sim "$repo/scenarios/paper_example2.toml" \
    --duration "$duration" --json --quiet --set "run.seed=$i" >/dev/null; } 2>&1 | tail -1 | awk '{print $1+$2}')
  total=$(awk -v a="$total" -v b="$cpu" 'BEGIN {print a + b}')
done
echo "alone: $sample runs one at a time, mean CPU per run $(awk -v t="$total" -v n=$sample 'BEGIN {printf "%.1f", 1000 * t / n}') ms"
