#!/usr/bin/env bash
# Writes the linker script that gathers the functions of a vehicle's lockstep window into
# one run of pages (vehicle/window_code.ld; vehicle/CMakeLists.txt links shoal_vehicle with
# it). The functions are those a vehicle runs in the windows bench/window_footprint.sh
# counts (valgrind lackey, a lockstep run of bench/scale_scenario.sh N), in the order they
# first run. Run it again when the window's code changes: a function renamed or no longer
# run stays where the linker puts it otherwise, and Scale.VehicleWindowCodeIsGathered names
# the script's functions the program no longer has. The script is written to a temporary
# file first and replaces OUT only when complete: without its INSERT command, a script
# given to the linker with -T would replace the linker's own.
# Usage: bench/window_code.sh [BUILD_DIR] [N] [OUT]
#   e.g. bench/window_code.sh build 64 vehicle/window_code.ld
set -euo pipefail
build=${1:-build}
n=${2:-64}
here=$(cd "$(dirname "$0")" && pwd)
out=${3:-$here/../vehicle/window_code.ld}
program="$build/vehicle/shoal_vehicle"
command -v python3 > /dev/null || { echo "bench: python3 not installed" >&2; exit 2; }
addresses=$(mktemp)
script=$(mktemp)
trap 'rm -f "$addresses" "$script"' EXIT
CODE_ADDRESSES="$addresses" "$here/window_footprint.sh" "$build" "$n" 6 vehicle >&2
python3 - "$program" "$addresses" "$n" > "$script" << 'EOF'
import bisect, subprocess, sys

program, addresses, n = sys.argv[1:4]
symbols = []  # (start, end, mangled name without its clone suffixes)
for line in subprocess.run(["nm", "--defined-only", "-S", program], capture_output=True,
                           text=True, check=True).stdout.splitlines():
    parts = line.split()
    if len(parts) != 4 or parts[2] not in {"t", "T", "w", "W"} or parts[3].endswith(".cold"):
        continue
    start, size = int(parts[0], 16), int(parts[1], 16)
    # A clone or local alias (NAME.lto_priv.0, NAME.constprop.0, NAME.localalias) lies in
    # an input section named after the function with the same suffix, which the pattern
    # .text.NAME.* below takes; mangled names have no dots of their own.
    symbols.append((start, start + size, parts[3].split(".")[0]))
symbols.sort()
starts = [s[0] for s in symbols]
names = []
for line in open(addresses):
    ip = int(line, 16)
    # Every symbol that covers the instruction: where identical functions were folded into
    # one, each name is a candidate for the input section that holds the code.
    i = bisect.bisect_right(starts, ip) - 1
    if i < 0:
        continue
    for start, end, name in symbols[bisect.bisect_left(starts, starts[i]):i + 1]:
        if ip < end and name not in names:
            names.append(name)
if not names:
    sys.exit("bench: no function of the program ran in the counted windows")
plain = subprocess.run(["c++filt"], input="\n".join(names), capture_output=True, text=True,
                       check=True).stdout.splitlines()
print(f"""/* The functions a vehicle runs in a lockstep window, in the order they first run,
   gathered into one run of pages ahead of the rest of the program's code. Between two of
   its turns, a vehicle among many processes finds none of its address translations left
   in the TLB, and each page of code its window runs costs a walk of the page tables.
   Written by bench/window_code.sh (a lockstep run of {n} followers); run it again when the
   window's code changes. Compiled with -ffunction-sections, as vehicle/CMakeLists.txt
   links the vehicle, every function has an input section of its own: .text.NAME, or
   .text.hot.NAME or .text.startup.NAME when the compiler judges it hot or run once. The
   cold parts it splits off (.text.unlikely.NAME) stay with the rest. */
SECTIONS
{{
  .text.shoal_window :
  {{""")
for name, readable in zip(names, plain):
    print(f"    /* {readable.replace('*/', '* /')} */")
    print(f"    *(.text.{name} .text.{name}.*")
    print(f"      .text.hot.{name} .text.hot.{name}.*")
    print(f"      .text.startup.{name} .text.startup.{name}.*)")
print("""  }
}
INSERT BEFORE .text;""")
EOF
tail -1 "$script" | grep -qx 'INSERT BEFORE .text;' || { echo "bench: the script is incomplete" >&2; exit 1; }
chmod 644 "$script"
mv "$script" "$out"
echo "bench: wrote $out ($(grep -c '^    \*(' "$out") functions)" >&2
