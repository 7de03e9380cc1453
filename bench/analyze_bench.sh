#!/usr/bin/env bash
# Benchmark: shoal analyze of a one-hour log of 6 vehicles at 50 Hz (paper Example 2, the
# leader and 5 followers, 10 links: about 1.1 M vehicle states, 1.8 M channel decisions and
# 4.9 M events in all). Target: <= 3 s and <= 500 MB peak RSS.
# Usage: bench/analyze_bench.sh [BUILD_DIR] [RUNS] [LOG]
# Writes the log with shoal sim first if LOG does not exist (kept for later runs), then
# runs `shoal analyze LOG --json` RUNS times under /usr/bin/time -v (after one warm-up
# run that brings the log into the page cache) and prints the median / min / max of the
# wall time and of the peak resident set size.
set -euo pipefail
build=${1:-build}
runs=${2:-7}
log=${3:-$build/bench_hour.lcmlog}
shoal="$build/tools/shoal"
[ -x "$shoal" ] || { echo "bench: $shoal not built" >&2; exit 2; }
[ -x /usr/bin/time ] || { echo "bench: /usr/bin/time missing (Debian package time)" >&2; exit 2; }

if [ ! -s "$log" ]; then
  echo "writing $log: shoal sim scenarios/paper_example2.toml --duration 3600 --out $log"
  "$shoal" sim scenarios/paper_example2.toml --duration 3600 --quiet --out "$log" > /dev/null || true
fi
out=$(mktemp)
trap 'rm -f "$out" "$out.time"' EXIT
"$shoal" analyze "$log" --json > "$out"  # warm-up: page cache
num() { grep -o "\"$1\":[0-9.e+-]*" "$out" | head -1 | cut -d: -f2; }
echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "log: $log, $(stat -c %s "$log") bytes, $(num log_events) events, $(num log_states) vehicle states, $(num sent) channel decisions, $(num ticks) ticks"
echo "command: /usr/bin/time -v $shoal analyze $log --json"

stats() {  # numbers on stdin -> median min max
  sort -g | awk '{a[NR]=$1} END {m=(NR%2)?a[(NR+1)/2]:(a[NR/2]+a[NR/2+1])/2; printf "median %.3f  min %.3f  max %.3f  (n=%d)\n", m, a[1], a[NR], NR}'
}
secs=(); mbs=()
for ((i = 1; i <= runs; i++)); do
  /usr/bin/time -v "$shoal" analyze "$log" --json > "$out" 2> "$out.time"
  s=$(grep 'Elapsed (wall clock)' "$out.time" | awk -F': ' '{print $2}' | awk -F: '{ if (NF == 3) print $1*3600+$2*60+$3; else print $1*60+$2 }')
  kb=$(grep 'Maximum resident set size' "$out.time" | awk -F': ' '{print $2}')
  secs+=("$s"); mbs+=("$(awk -v k="$kb" 'BEGIN{printf "%.1f", k/1024}')")
done
echo "wall time [s]:     ${secs[*]}"
printf 'wall time [s]:     '; printf '%s\n' "${secs[@]}" | stats
echo "peak RSS [MiB]:    ${mbs[*]}"
printf 'peak RSS [MiB]:    '; printf '%s\n' "${mbs[@]}" | stats
