#!/usr/bin/env bash
# Benchmark: lockstep windows that follow the channel's delay against windows of a fixed
# length (--max-lookahead L; L = the channel's smallest lag gives the fixed windows a
# constant-lag bound would). Alternating runs of the same build; per run the real-time
# factor, states logged of expected, and the emulator's windows line.
# Usage: bench/window_ab.sh BUILD_DIR SCENARIO DURATION_S [RUNS=3] [FIXED_L=3]
#   e.g. bench/scale_scenario.sh 64 60 > s64.toml; bench/window_ab.sh build s64.toml 60 4
#        bench/window_ab.sh build scenarios/paper_example2.toml 600 3
set -euo pipefail
if [ $# -lt 3 ] || [ "$1" = --help ] || [ "$1" = -h ]; then
  sed -n '2,8p' "$0" | sed 's/^# \{0,1\}//'
  [ $# -ge 3 ] && exit 0 || exit 2
fi
build=$1 scenario=$2 dur=$3 runs=${4:-3} fixed=${5:-3}
shoal=$build/tools/shoal
[ -x "$shoal" ] || { echo "window_ab: $shoal not built" >&2; exit 2; }
[ -r "$scenario" ] || { echo "window_ab: cannot read $scenario" >&2; exit 2; }
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
num() { grep -o "\"$1\":[0-9.e+-]*" "$2" | head -1 | cut -d: -f2; }
echo "variant,run,realtime_factor,log_states,log_states_expected,windows"
for r in $(seq 1 "$runs"); do
  for v in follow fixed; do
    extra=()
    [ "$v" = fixed ] && extra=(--max-lookahead "$fixed")
    "$shoal" run "$scenario" --mode lockstep --duration "$dur" --json --out "$dir/run.lcmlog" \
      "${extra[@]}" > "$dir/run.json" 2> /dev/null || true
    windows=$(grep -o "lockstep, [0-9]* windows of [^,]*" "$dir/run.lcmlog.d/emulator.txt" | sed 's/^lockstep, //')
    echo "$v,$r,$(num realtime_factor "$dir/run.json"),$(num log_states "$dir/run.json"),$(num log_states_expected "$dir/run.json"),$windows"
  done
done
