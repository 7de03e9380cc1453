#!/usr/bin/env bash
# Benchmark: how shoal run scales with the number of followers, at a fixed two in-links
# per follower (bench/scale_scenario.sh). For each N and run: a lockstep run and a
# real-time run of the same scenario. Per run it records the lockstep real-time factor
# (overall, and once the run is going: steady_factor),
# states logged of expected, each role's CPU per tick (from the run's resources.csv:
# the difference between the 2 s sample and the last one, so start-up is not counted;
# lockstep runs of fewer than 64 followers are longer, LOCKSTEP_S * 64 / N, for enough samples),
# context switches per tick (the same way, from the columns shoal run samples: the
# benchmark starts no process while a run goes, which on two CPUs would slow the run it
# measures), UDP receive-buffer overflows on the host during
# the run (/proc/net/snmp RcvbufErrors), and in real time the loop lateness p99, the
# release (delay) error p99, overruns and states logged. Runs are interleaved N by N.
# Usage: bench/scale.sh [BUILD_DIRS] [RUNS] [LOCKSTEP_S] [REALTIME_S] [NS] [OUT_CSV] [EXTRA_ARGS]
#   RT_ARGS: arguments of the real-time runs only (e.g. RT_ARGS=--stagger)
#   e.g. bench/scale.sh build 3 20 20 "5 16 64 128" scale.csv
# BUILD_DIRS: one build directory, or several separated by commas (A/B: their runs are
# interleaved, and each row names its build). Writes OUT_CSV (one row per run) and
# OUT_CSV with .csv replaced by _median.csv (medians per build, mode and N), and, if
# <first build>/bench/scale_plot exists, a PNG of CPU per tick against N (_cpu.png; with two
# builds, the second drawn dashed as "before") in two panels, one vehicle process and all
# three roles per follower, each with its +-20 % band, and prints each one's spread.
set -euo pipefail
builds=${1:-build}
runs=${2:-3}
ls_dur=${3:-20}
rt_dur=${4:-20}
ns=${5:-"5 16 64 128"}
out=${6:-scale.csv}
extra=${7:-}
modes=${MODES:-lockstep realtime}  # e.g. MODES=lockstep bench/scale.sh ...
rt_extra=${RT_ARGS:-}  # real-time runs only, e.g. RT_ARGS=--stagger
IFS=, read -r -a build_list <<< "$builds"
for b in "${build_list[@]}"; do
  [ -x "$b/tools/shoal" ] || { echo "bench: $b/tools/shoal not built" >&2; exit 2; }
done
here=$(cd "$(dirname "$0")" && pwd)
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
num() { grep -o "\"$1\":[0-9.e+-]*" "$2" | head -1 | cut -d: -f2; }
rcvbuf_errors() { awk '/^Udp:/ {getline; print $6; exit}' /proc/net/snmp; }

# One run: build, mode, N, run index. Appends a CSV row.
one_run() {
  local build=$1 mode=$2 n=$3 r=$4 dur
  local shoal="$build/tools/shoal" tag
  tag=$(basename "$build")
  # Lockstep: LOCKSTEP_S for 64 followers and more, longer for fewer (LOCKSTEP_S * 64 / N),
  # so that every run lasts seconds of wall time and has enough resource samples.
  dur=$([ "$mode" = lockstep ] && awk -v d="$ls_dur" -v n="$n" 'BEGIN {print (n < 64) ? int(d * 64 / n) : d}' || echo "$rt_dur")
  local scen="$dir/scale_$n.toml" log="$dir/${tag}_${mode}_${n}_$r.lcmlog"
  local json="$dir/${tag}_${mode}_${n}_$r.json"
  local before after
  before=$(rcvbuf_errors)
  # shellcheck disable=SC2086
  "$shoal" run "$scen" --mode "$mode" --duration "$dur" --out "$log" --json \
    --resource-interval 1 $extra $([ "$mode" = realtime ] && echo "$rt_extra") > "$json" 2> "$dir/err" &
  wait $! || true
  after=$(rcvbuf_errors)
  # CPU and context switches per tick per role, from the run's resources.csv: (the last
  # sample - the sample at 2 s) / ticks between, per process, averaged over the vehicles.
  # shoal run samples them itself (its threads' counts from /proc/<pid>/task/*/status), so
  # the benchmark starts no process of its own while a run goes.
  local cpu cs
  read -r cpu cs < <(awk -F, 'NR > 1 {
      role = ($3 ~ /^vehicle/) ? "vehicle" : $3
      if ($1 + 0 >= 2 && !(($4) in first)) {first[$4] = $6; f_cs[$4] = $7 + $8; t0[$4] = $1; r[$4] = role}
      if (($4) in first) {last[$4] = $6; l_cs[$4] = $7 + $8; t1[$4] = $1}
    }
    END {
      for (p in first) if (t1[p] > t0[p]) {
        ticks = (t1[p] - t0[p]) * 50
        s[r[p]] += (last[p] - first[p]) / ticks; w[r[p]] += (l_cs[p] - f_cs[p]) / ticks; c[r[p]]++
      }
      printf "%.3f,%.1f,%.1f %.2f,%.1f,%.1f\n",
        c["vehicle"] ? 1e6 * s["vehicle"] / c["vehicle"] : -1,
        1e6 * s["channel emulator"], 1e6 * s["lcm-logger"],
        c["vehicle"] ? w["vehicle"] / c["vehicle"] : -1, w["channel emulator"], w["lcm-logger"]
    }' "$log.d/resources.csv")
  # The real-time factor once the run is going: mission time over wall time between the
  # emulator's sample at 2 s and its last, without the start (processes, LCM's self-test,
  # announcing) and the end, which a short lockstep run's overall factor includes.
  local steady
  steady=$(awk -F, 'NR > 1 && $3 == "channel emulator" && $1 + 0 >= 2 {
      if (!seen++) {s0 = $1; w0 = $2}; s1 = $1; w1 = $2}
    END {if (w1 > w0) printf "%.2f", (s1 - s0) / (w1 - w0)}' "$log.d/resources.csv")
  printf '%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%s\n' "$tag" "$mode" "$n" "$r" \
    "$(num realtime_factor "$json")" "$steady" "$(num log_states "$json")" \
    "$(num log_states_expected "$json")" "$cpu" "$cs" "$((after - before))" \
    "$(num lateness_p99_s "$json")" "$(num delay_error_p99_s "$json")" \
    "$(num overruns "$json")" "$(cut -d' ' -f1 /proc/loadavg)" >> "$out"
  # The log itself is not kept (its figures are read above): a 100 s run at 128 followers
  # writes about a quarter of a GB, and a sweep or an A/B of many runs would leave gigabytes.
  rm -f "$log"
}

echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), load $(cut -d' ' -f1-3 /proc/loadavg)" >&2
# What the machine alone does to a loop: a bare 1 kHz loop at SCHED_FIFO for 10 s. Its
# wake-ups later than a period are stalls of the whole machine (on a VM, the hypervisor),
# which no process of a run can avoid.
jitter="${build_list[0]}/bench/loop_jitter"
if [ -x "$jitter" ]; then
  echo "bare loop: $(chrt -f 90 "$jitter" 1000 10 2> /dev/null || "$jitter" 1000 10)" >&2
fi
echo "build,mode,followers,run,realtime_factor,steady_factor,log_states,log_states_expected,vehicle_cpu_us_per_tick,emulator_cpu_us_per_tick,logger_cpu_us_per_tick,vehicle_ctxsw_per_tick,emulator_ctxsw_per_tick,logger_ctxsw_per_tick,rcvbuf_errors,lateness_p99_s,delay_error_p99_s,overruns,load1" > "$out"
for n in $ns; do "$here/scale_scenario.sh" "$n" "$ls_dur" > "$dir/scale_$n.toml"; done
for ((r = 1; r <= runs; r++)); do
  for n in $ns; do
    for mode in $modes; do
      for b in "${build_list[@]}"; do
        one_run "$b" "$mode" "$n" "$r"
        tail -1 "$out" >&2
      done
    done
  done
done
med="${out%.csv}_median.csv"
head -1 "$out" | cut -d, -f1-3,5- > "$med"
for b in "${build_list[@]}"; do
  for mode in $modes; do
    for n in $ns; do
      awk -F, -v t="$(basename "$b")" -v m="$mode" -v n="$n" '$1 == t && $2 == m && $3 == n' "$out" |
        awk -F, -v t="$(basename "$b")" -v m="$mode" -v n="$n" '
      {for (c = 5; c <= NF; c++) v[c, NR] = $c; rows = NR; cols = NF}
      END {
        if (!rows) exit
        line = t "," m "," n
        for (c = 5; c <= cols; c++) {
          k = 0; for (i = 1; i <= rows; i++) if (v[c, i] != "") a[++k] = v[c, i] + 0
          for (i = 1; i <= k; i++) for (j = i + 1; j <= k; j++) if (a[j] < a[i]) {t = a[i]; a[i] = a[j]; a[j] = t}
          line = line "," (k ? (k % 2 ? a[(k + 1) / 2] : (a[k / 2] + a[k / 2 + 1]) / 2) : "")
        }
        print line
      }' >> "$med"
    done
  done
done
cat "$med"
first=${build_list[0]}
if [ -x "$first/bench/scale_plot" ]; then
  one="$dir/first.csv" two="$dir/second.csv"
  awk -F, -v t="$(basename "$first")" 'NR == 1 || $1 == t' "$med" > "$one"
  if [ "${#build_list[@]}" -gt 1 ]; then
    awk -F, -v t="$(basename "${build_list[1]}")" 'NR == 1 || $1 == t' "$med" > "$two"
    "$first/bench/scale_plot" "$one" "${out%.csv}_cpu.png" "$two"
  else
    "$first/bench/scale_plot" "$one" "${out%.csv}_cpu.png"
  fi
fi
