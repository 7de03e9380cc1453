#!/usr/bin/env bash
# Benchmark: shoal sim speed (real-time factor) on a scenario, median over several runs.
# Usage: bench/sim_speed.sh [BUILD_DIR] [RUNS] [SCENARIO] [DURATION_S]
# Prints every run and the median / min / max, without and with an LCM log (--out).
set -euo pipefail
build=${1:-build}
runs=${2:-7}
scenario=${3:-scenarios/paper_example2.toml}
duration=${4:-1000}
shoal="$build/tools/shoal"
[ -x "$shoal" ] || { echo "bench: $shoal not built (run make demo or make test first)" >&2; exit 2; }
log=$(mktemp --suffix=.lcmlog)
trap 'rm -f "$log"' EXIT

stats() {  # reads numbers on stdin, prints median min max
  sort -g | awk '{a[NR]=$1} END {m=(NR%2)?a[(NR+1)/2]:(a[NR/2]+a[NR/2+1])/2; printf "median %.0f  min %.0f  max %.0f  (n=%d)\n", m, a[1], a[NR], NR}'
}
rtf() { grep -o '"realtime_factor":[0-9.e+-]*' | cut -d: -f2; }

echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "command: $shoal sim $scenario --duration $duration --json --quiet [--out LOG]"
# shoal sim exits 1 when the formation has not converged (a short duration): only a status
# above 1 stops the benchmark.
sim_json() { "$shoal" sim "$scenario" --duration "$duration" --json --quiet "$@" || [ $? -eq 1 ]; }
for mode in nolog log; do
  vals=()
  for ((i = 1; i <= runs; i++)); do
    if [ $mode = log ]; then
      v=$(sim_json --out "$log" | rtf)
    else
      v=$(sim_json | rtf)
    fi
    vals+=("$v")
  done
  printf '%-6s runs: %s\n' "$mode" "${vals[*]}"
  printf '%-6s real-time factor: ' "$mode"
  printf '%s\n' "${vals[@]}" | stats
done
echo "log size for $duration s: $(stat -c %s "$log") bytes"
