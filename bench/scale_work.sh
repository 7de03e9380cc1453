#!/usr/bin/env bash
# Benchmark: the work each role of a lockstep run does per tick against the number of
# followers, counted in user-space instructions (valgrind callgrind), not timed: what
# Shoal's code asks of the CPU, close on any x86-64 machine for the same build (the
# compiler, glibc and the string functions it picks for the CPU move it a little), apart
# from the waits
# (the clock master's polls of the logger's count, the logger's own loop) whose number
# depends on how fast the others are. bench/scale.sh times the same runs; the two together
# tell Shoal's work from what the host charges for it (a switch between processes, lines
# and pages brought back), which grows with the number of processes on some hosts.
#
# For each N: a lockstep run of bench/scale_scenario.sh N, from the script of shoal run
# --print-launch, with vehicle 1, the channel emulator and lcm-logger under callgrind
# (lockstep waits for them; the other processes run as they are), once for D1 s of mission
# and once for D2 s. A role's instructions per tick is the difference between the two
# runs over the difference in ticks (50 Hz), so the start and the end, the same in both,
# drop out. Per follower: (N x one vehicle + emulator + logger) / N, as bench/scale.sh
# sums CPU. Kernel work (system calls, wake-ups) is not counted: bench/scale.sh gives the
# context switches per tick.
# Usage: bench/scale_work.sh [BUILD_DIR] [NS] [D1] [D2] [OUT_CSV]
#   e.g. bench/scale_work.sh build "5 16 64 128" 4 12 work.csv
set -euo pipefail
build=${1:-build}
ns=${2:-"5 16 64 128"}
d1=${3:-4}
d2=${4:-12}
out=${5:-scale_work.csv}
here=$(cd "$(dirname "$0")" && pwd)
shoal="$build/tools/shoal"
[ -x "$shoal" ] || { echo "bench: $shoal not built" >&2; exit 2; }
command -v valgrind > /dev/null || { echo "bench: valgrind not installed" >&2; exit 2; }
[[ $d1 =~ ^[1-9][0-9]*$ && $d2 =~ ^[1-9][0-9]*$ ]] ||
  { echo "bench: D1 and D2 are whole seconds (got $d1 and $d2)" >&2; exit 2; }
[ "$d2" -gt "$d1" ] || { echo "bench: D2 ($d2) must be longer than D1 ($d1)" >&2; exit 2; }
# bench/scale_scenario.sh's control rate: a run of D s has D * 50 ticks.
readonly RATE_HZ=50
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT

# Total instructions of one callgrind output (its "summary:" line; "totals:" in some
# versions).
instructions() { awk '/^(summary|totals):/ {print $2; exit}' "$1"; }

# One run: N, duration. Leaves $dir/N_D/{vehicle,emulator,logger}.out.
one_run() {
  local n=$1 d=$2 run="$dir/${1}_$2"
  mkdir -p "$run"
  "$here/scale_scenario.sh" "$n" "$d" > "$run/scale.toml"
  "$shoal" run "$run/scale.toml" --mode lockstep --duration "$d" --out "$run/run.lcmlog" \
    --print-launch > "$run/printed.sh"
  local cg="valgrind --tool=callgrind --callgrind-out-file=$run"
  # vehicle 1's and the emulator's commands are the line after their start line;
  # lcm-logger's is named on the line that starts it under its environment.
  awk -v vehicle="$cg/vehicle.out " -v emulator="$cg/emulator.out " \
      -v logger="$cg/logger.out /usr/bin/lcm-logger" '
    lead != "" { sub(/^  /, "  " lead); lead = "" }
    /^start .vehicle 1. / { lead = vehicle }
    /^start .channel emulator. / { lead = emulator }
    /\/usr\/bin\/lcm-logger / { sub(/\/usr\/bin\/lcm-logger/, logger) }
    { print }' "$run/printed.sh" > "$run/run.sh"
  # Each wrapped line must start its own program, not an argument of it.
  local prog
  for prog in "vehicle.out [^ ]*/shoal_vehicle " "emulator.out [^ ]*/shoal_channel_emulator " \
              "logger.out /usr/bin/lcm-logger "; do
    grep -q "callgrind-out-file=[^ ]*/$prog" "$run/run.sh" ||
      { echo "bench: the script's command for ${prog%%.out*} was not wrapped" >&2; exit 2; }
  done
  (cd "$run" && bash run.sh > run.out 2>&1) || {
    echo "bench: the run of $n followers, $d s failed:" >&2
    tail -5 "$run/run.out" >&2
    local f
    for f in "$run"/run.lcmlog.d/emulator.txt "$run"/run.lcmlog.d/vehicle1.txt \
             "$run"/run.lcmlog.d/logger.txt; do
      [ -f "$f" ] && { echo "--- $f" >&2; tail -5 "$f" >&2; }
    done
    exit 1
  }
  for role in vehicle emulator logger; do
    [ -n "$(instructions "$run/$role.out" 2> /dev/null)" ] ||
      { echo "bench: no count for the $role ($run/$role.out)" >&2; exit 1; }
  done
}

echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'); $(valgrind --version)"
echo "command: bench/scale_work.sh $build \"$ns\" $d1 $d2"
echo "followers,vehicle_instr_per_tick,emulator_instr_per_tick,logger_instr_per_tick,all_per_follower_instr_per_tick" > "$out"
for n in $ns; do
  echo "followers $n: runs of $d1 s and $d2 s under callgrind..." >&2
  one_run "$n" "$d1"
  one_run "$n" "$d2"
  row="$n"
  for role in vehicle emulator logger; do
    a=$(instructions "$dir/${n}_$d1/$role.out")
    b=$(instructions "$dir/${n}_$d2/$role.out")
    row="$row,$(awk -v a="$a" -v b="$b" -v t=$(( (d2 - d1) * RATE_HZ )) 'BEGIN {printf "%.0f", (b - a) / t}')"
  done
  echo "$row" | awk -F, -v OFS=, '{print $0, sprintf("%.0f", ($1 * $2 + $3 + $4) / $1)}' >> "$out"
done
column -s, -t "$out" 2> /dev/null || cat "$out"
# Each role's dearest size over its cheapest (per follower for the whole run).
awk -F, 'NR > 1 {
    for (c = 2; c <= 5; c++) {
      v = $c + 0; if (c == 3 || c == 4) v /= $1
      if (NR == 2 || v < lo[c]) lo[c] = v
      if (NR == 2 || v > hi[c]) hi[c] = v
    }
  }
  END {
    for (c = 2; c <= 5; c++) if (lo[c] <= 0) { print "bench: a count of 0 instructions a tick"; exit 1 }
    printf "dearest / cheapest size: one vehicle %.2f, emulator per follower %.2f, " \
           "logger per follower %.2f, all three per follower %.2f\n",
           hi[2] / lo[2], hi[3] / lo[3], hi[4] / lo[4], hi[5] / lo[5]
  }' "$out"
