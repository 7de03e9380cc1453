#!/usr/bin/env bash
# The functions vehicle/window_code.ld names (those a vehicle runs in a lockstep window)
# all lie in the vehicle's .text.shoal_window section, one run of pages. A function
# renamed, no longer in the program as a function of its own, or left out of the section
# fails here, with its name: write the script again with bench/window_code.sh.
#
# Usage: window_code_test.sh SOURCE_DIR PROGRAM
set -euo pipefail
src=${1:?usage: window_code_test.sh SOURCE_DIR PROGRAM}
program=${2:?usage: window_code_test.sh SOURCE_DIR PROGRAM}
script="$src/vehicle/window_code.ld"
names=$(sed -n 's/^ *\*(\.text\.\([^ .]*\) .*/\1/p' "$script")
[ -n "$names" ] || { echo "FAIL: no function named in $script"; exit 1; }
read -r start size < <(readelf -S -W "$program" |
  awk '$2 == ".text.shoal_window" { print $4, $6 } $3 == ".text.shoal_window" { print $5, $7 }') ||
  true
[ -n "${start:-}" ] || { echo "FAIL: $program has no .text.shoal_window section"; exit 1; }
nm --defined-only "$program" | awk -v names="$names" -v start="$start" -v size="$size" '
  function hex(s,   i, c, v) {
    v = 0
    for (i = 1; i <= length(s); i++) v = v * 16 + index("0123456789abcdef", substr(tolower(s), i, 1)) - 1
    return v
  }
  BEGIN { n = split(names, want, "\n"); lo = hex(start); hi = lo + hex(size) }
  $2 ~ /^[tTwW]$/ {
    base = $3; sub(/\..*/, "", base)
    a = hex($1)
    if (a >= lo && a < hi) inside[base] = 1
    else if ($3 !~ /\.cold$/) outside[base] = 1
  }
  END {
    bad = 0
    for (i = 1; i <= n; i++) {
      if (!(want[i] in inside)) {
        printf "FAIL: %s is %s\n", want[i], (want[i] in outside) ? "outside .text.shoal_window" : "not a function of the program"
        bad++
      }
    }
    if (bad) exit 1
    printf "the %d functions of the window lie in .text.shoal_window (%d bytes)\n", n, hi - lo
  }'
