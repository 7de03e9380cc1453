#!/usr/bin/env bash
# Benchmark: an interleaved A/B of shoal sim's speed between two builds (a change against
# the code before it), so that both see the same machine load.
# Usage: bench/sim_ab.sh SHOAL_A SHOAL_B [ROUNDS] [SCENARIO] [DURATION_S]
# Runs A, B, A, B, ... ROUNDS times each and prints every run, each side's median / min /
# max real-time factor, the ratio of the medians B / A, and the median of the ratios
# within each round.
set -euo pipefail
a=${1:?usage: bench/sim_ab.sh SHOAL_A SHOAL_B [ROUNDS] [SCENARIO] [DURATION_S]}
b=${2:?usage: bench/sim_ab.sh SHOAL_A SHOAL_B [ROUNDS] [SCENARIO] [DURATION_S]}
rounds=${3:-11}
scenario=${4:-scenarios/paper_example2.toml}
duration=${5:-1000}
for s in "$a" "$b"; do [ -x "$s" ] || { echo "bench: $s is not an executable" >&2; exit 2; }; done

stats() {  # numbers on stdin -> "median min max"
  sort -g | awk '{v[NR]=$1} END {m=(NR%2)?v[(NR+1)/2]:(v[NR/2]+v[NR/2+1])/2; printf "%.0f %.0f %.0f\n", m, v[1], v[NR]}'
}
# shoal sim exits 1 when the formation has not converged: only a status above 1 stops.
rtf() {
  { "$1" sim "$scenario" --duration "$duration" --json --quiet || [ $? -eq 1 ]; } |
    grep -o '"realtime_factor":[0-9.e+-]*' | cut -d: -f2
}
echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "A: $a"
echo "B: $b"
echo "command: shoal sim $scenario --duration $duration --json --quiet, $rounds rounds, alternating"
va=() vb=()
for ((i = 1; i <= rounds; i++)); do
  va+=("$(rtf "$a")")
  vb+=("$(rtf "$b")")
done
printf 'A runs: %s\nB runs: %s\n' "${va[*]}" "${vb[*]}"
read -r ma mina maxa < <(printf '%s\n' "${va[@]}" | stats)
read -r mb minb maxb < <(printf '%s\n' "${vb[@]}" | stats)
echo "A real-time factor: median $ma (min $mina, max $maxa)"
echo "B real-time factor: median $mb (min $minb, max $maxb)"
awk -v a="$ma" -v b="$mb" 'BEGIN { printf "B / A = %.3f (B %s by %.1f %%)\n", b / a, b < a ? "slower" : "faster", 100 * (b > a ? b / a - 1 : 1 - b / a) }'
# Each B run against the A run just before it: on a host whose speed drifts from minute to
# minute, the ratio within a pair sees the same moment, so its median resolves a few per
# cent where the medians of the two sides need many more rounds.
for ((i = 0; i < rounds; i++)); do echo "${va[i]} ${vb[i]}"; done |
  awk '{printf "%.6f %d\n", $2 / $1, ($2 > $1) ? 1 : 0}' | sort -g |
  awk '{r[NR] = $1; faster += $2}
    END {m = (NR % 2) ? r[(NR + 1) / 2] : (r[NR / 2] + r[NR / 2 + 1]) / 2
         printf "B / A within each round: median %.3f; B faster in %d of %d rounds\n", m, faster, NR}'
