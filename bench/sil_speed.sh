#!/usr/bin/env bash
# Benchmark: shoal run (SIL) — lockstep real-time factor, and real-time accuracy.
# Usage: bench/sil_speed.sh [BUILD_DIR] [RUNS] [LOCKSTEP_DURATION_S (600: the scenario's own)] [REALTIME_DURATION_S]
set -euo pipefail
build=${1:-build}
runs=${2:-5}
ls_dur=${3:-600}
rt_dur=${4:-60}
scenario=scenarios/paper_example2.toml
shoal="$build/tools/shoal"
[ -x "$shoal" ] || { echo "bench: $shoal not built" >&2; exit 2; }
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
num() { grep -o "\"$1\":[0-9.e+-]*" | head -1 | cut -d: -f2; }
median() { sort -g | awk '{a[NR]=$1} END {m=(NR%2)?a[(NR+1)/2]:(a[NR/2]+a[NR/2+1])/2; printf "median %.4g  min %.4g  max %.4g  (n=%d)\n", m, a[1], a[NR], NR}'; }

echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "lockstep: $shoal run $scenario --mode lockstep --duration $ls_dur --json"
vals=()
logged=()
# shoal run exits 1 when the formation has not converged (a short --duration): the run
# still measured what is wanted here; only a status above 1 stops the benchmark.
run_json() { "$shoal" run "$@" --json || [ $? -eq 1 ]; }
for ((i = 1; i <= runs; i++)); do
  j=$(run_json "$scenario" --mode lockstep --duration "$ls_dur" --out "$dir/ls$i.lcmlog")
  vals+=("$(echo "$j" | num realtime_factor)")
  logged+=("$(echo "$j" | num log_states)/$(echo "$j" | num log_states_expected)")
done
echo "  real-time factors: ${vals[*]}"
echo "  states logged: ${logged[*]}"
printf '  '; printf '%s\n' "${vals[@]}" | median

echo "realtime: $shoal run $scenario --mode realtime --duration $rt_dur --json"
j=$(run_json "$scenario" --mode realtime --duration "$rt_dur" --out "$dir/rt.lcmlog")
echo "  delay_error_p99_s $(echo "$j" | num delay_error_p99_s)  states logged $(echo "$j" | num log_states)/$(echo "$j" | num log_states_expected)  lateness_p99_s $(echo "$j" | num lateness_p99_s)  overruns $(echo "$j" | num overruns)  final_position_error_m $(echo "$j" | num final_position_error_m)"
echo "  load after: $(cut -d' ' -f1-3 /proc/loadavg)"
