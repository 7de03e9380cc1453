#!/usr/bin/env bash
# Benchmark: the user-space cache lines a vehicle (or the channel emulator) touches in one
# lockstep window, counted exactly (valgrind lackey, bench/window_lines.cc), not timed: the
# same on any machine. Runs a lockstep run of bench/scale_scenario.sh N from a script of
# shoal run --print-launch, with vehicle 1 (ROLE vehicle) or the channel emulator (ROLE
# emulator) under valgrind --tool=lackey --trace-mem=yes (lockstep waits for it), and
# counts, per window, the distinct 64-byte data lines, code lines, data pages and code
# pages. A vehicle's window begins at each call of ClockedNode::HandleBus, the emulator's at
# each call of ChannelEmulatorApp::WindowLast (once a window, when it opens the next).
# What the emulator touches in a window is what passes through the caches of the CPUs the
# vehicles share between two of their turns. A window's lines must
# come back from L3 or memory when the processes that ran on its CPU since its last turn
# have pushed them out of that CPU's L2: the count times the followers per CPU, against the
# L2's size, says when that begins. Its pages each cost a walk of the page tables when the
# TLB no longer holds the process's translations. Kernel lines (socket, task, page tables)
# are not counted.
# CODE_ADDRESSES=FILE: also writes to FILE the address of every instruction the counted
# windows ran, in the order first run, as nm gives the program's addresses (those in the
# libraries come out as numbers beyond the program's; bench/window_code.sh).
# Usage: bench/window_footprint.sh [BUILD_DIR] [N] [DURATION_S] [ROLE]
#   e.g. bench/window_footprint.sh build 16 10; bench/window_footprint.sh build 64 6 emulator
set -euo pipefail
build=${1:-build}
n=${2:-16}
dur=${3:-10}
role=${4:-vehicle}
here=$(cd "$(dirname "$0")" && pwd)
shoal="$build/tools/shoal"
case "$role" in
  vehicle)
    program="$build/vehicle/shoal_vehicle" started="vehicle 1"
    mark_re=' [tT] shoal::ClockedNode::HandleBus\(int, long\)$' ;;
  emulator)
    program="$build/channel_emulator/shoal_channel_emulator" started="channel emulator"
    mark_re=' [tT] shoal::ChannelEmulatorApp::WindowLast\(long\) const$' ;;
  *) echo "bench: ROLE must be vehicle or emulator, not '$role'" >&2; exit 2 ;;
esac
counter="$build/bench/window_lines"
for f in "$shoal" "$program" "$counter"; do
  [ -x "$f" ] || { echo "bench: $f not built" >&2; exit 2; }
done
command -v valgrind > /dev/null || { echo "bench: valgrind not installed" >&2; exit 2; }
program=$(cd "$(dirname "$program")" && pwd)/$(basename "$program")
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT

# valgrind loads a position-independent program at 0x108000 (amd64), any other where it
# was linked: the window's mark is its function's entry there. A link-time optimised build
# makes it a local symbol (t), and GCC may split off its cold part ([clone .cold]).
# The pattern goes through the environment: awk -v would read its backslashes as escapes.
offset=$(nm -C "$program" | re="$mark_re" awk '$0 ~ ENVIRON["re"] && !n++ {print $1}')
[ -n "$offset" ] || { echo "bench: the window's function ($mark_re) not found in $program" >&2; exit 2; }
base=0
if readelf -h "$program" | grep -q 'Type:.*DYN'; then base=0x108000; fi
mark=$(printf '%x' $((base + 0x$offset)))

"$here/scale_scenario.sh" "$n" "$dur" > "$dir/scale.toml"
"$shoal" run "$dir/scale.toml" --mode lockstep --duration "$dur" --out "$dir/run.lcmlog" \
  --print-launch > "$dir/printed.sh"
mkfifo "$dir/trace"
awk -v vg="valgrind --tool=lackey --trace-mem=yes --log-file=$dir/trace " '
  lead { sub(/^  /, "  " vg); lead = 0 }
  index($0, "start " q started q " ") == 1 { lead = 1 }
  { print }' q="'" started="$started" "$dir/printed.sh" > "$dir/run.sh"
grep -q "tool=lackey" "$dir/run.sh" || { echo "bench: $started not found in the script" >&2; exit 2; }

echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'); $(valgrind --version)"
echo "command: $shoal run (scale_scenario.sh $n $dur) --mode lockstep --print-launch, $started under lackey"
"$counter" "$mark" 20 ${CODE_ADDRESSES:+"$dir/code.txt"} < "$dir/trace" > "$dir/windows.txt" \
  2> "$dir/summary.txt" &
counter_pid=$!
status=0
bash "$dir/run.sh" > "$dir/run.out" 2>&1 || status=$?
wait "$counter_pid" || { cat "$dir/summary.txt" >&2; exit 1; }
[ "$status" = 0 ] || { echo "bench: the run failed ($status):" >&2; tail -5 "$dir/run.out" >&2; exit 1; }
echo "followers $n: $(cat "$dir/summary.txt")"
if [ -n "${CODE_ADDRESSES:-}" ]; then
  # From where valgrind loaded the program back to the addresses nm gives.
  while read -r a; do printf '%x\n' $((0x$a - base)); done < "$dir/code.txt" > "$CODE_ADDRESSES"
fi
