#!/usr/bin/env bash
# The functions vehicle/window_code.ld names (those a vehicle runs in a lockstep window)
# lie in the vehicle's .text.shoal_window section, one run of pages, and nowhere else but
# their cold parts. Fails, naming them, when the link left any outside (the script no
# longer reaches their sections). Skipped (77), naming them, when the build has some of
# them no longer as functions of their own (renamed, or inlined by another compiler): the
# script is then stale, to be written again with bench/window_code.sh.
#
# Usage: window_code_test.sh SOURCE_DIR PROGRAM
set -euo pipefail
src=${1:?usage: window_code_test.sh SOURCE_DIR PROGRAM}
program=${2:?usage: window_code_test.sh SOURCE_DIR PROGRAM}
script="$src/vehicle/window_code.ld"
patterns=$(grep -c '^ *\*(' "$script" || true)
names=$(sed -n 's/^ *\*(\.text\.\([A-Za-z0-9_$]*\) .*/\1/p' "$script")
count=$(printf '%s\n' "$names" | grep -c . || true)
[ "$count" -gt 0 ] || { echo "FAIL: no function named in $script"; exit 1; }
[ "$count" = "$patterns" ] ||
  { echo "FAIL: $script has $patterns patterns, of which $count name a function as expected"; exit 1; }
read -r start size < <(readelf -S -W "$program" |
  awk '$2 == ".text.shoal_window" { print $4, $6 } $3 == ".text.shoal_window" { print $5, $7 }') ||
  true
[ -n "${start:-}" ] || { echo "FAIL: $program has no .text.shoal_window section"; exit 1; }
status=0
nm --defined-only "$program" | awk -v names="$names" -v start="$start" -v size="$size" '
  function hex(s,   i, v) {
    v = 0
    for (i = 1; i <= length(s); i++) v = v * 16 + index("0123456789abcdef", substr(tolower(s), i, 1)) - 1
    return v
  }
  BEGIN { n = split(names, want, "\n"); lo = hex(start); hi = lo + hex(size) }
  $2 ~ /^[tTwW]$/ && $3 !~ /\.cold$/ {
    base = $3; sub(/\..*/, "", base)
    a = hex($1)
    if (a >= lo && a < hi) inside[base] = 1
    else outside[base] = 1
  }
  END {
    bad = 0; missing = 0
    for (i = 1; i <= n; i++) {
      if (want[i] in outside) {
        printf "FAIL: %s lies outside .text.shoal_window\n", want[i]
        bad++
      } else if (!(want[i] in inside)) {
        printf "stale: %s is not a function of the program\n", want[i]
        missing++
      }
    }
    if (bad) exit 1
    if (missing) {
      printf "skipped: %d of the %d functions are not in this build; write %s again with bench/window_code.sh\n", missing, n, "vehicle/window_code.ld"
      exit 77
    }
    printf "the %d functions of the window lie in .text.shoal_window (%d bytes)\n", n, hi - lo
  }' || status=$?
exit "$status"
