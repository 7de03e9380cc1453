#!/usr/bin/env bash
# Fuzzing of every entry point that takes bytes from outside (tests/fuzz): a bus message
# (fuzz_decode: runtime/lcm_bus.h's Decode of each type, and the datagrams a process's own
# socket reader takes, runtime/udpm_receiver.h), a log file (fuzz_log_reader:
# runtime/log_reader.h and analysis' LoadRunLog), a scenario file (fuzz_scenario:
# ParseScenario) and a campaign file (fuzz_campaign: ParseCampaign). libFuzzer with ASan +
# UBSan + LeakSanitizer, clang++ (Debian: clang, libclang-rt-14-dev).
# Usage: bench/fuzz.sh [EXECUTIONS (1000000)] [TARGET...]
#   make test runs it with FUZZ_SHORT_RUNS (50000) executions per target; the campaign
#   figures of docs/benchmarks.md are `nice -n 19 bench/fuzz.sh 10000000 TARGET`.
#   FUZZ_BUILD (build-fuzz): the build directory (configured here, SHOAL_FUZZ=ON)
#   FUZZ_TIMEOUT (10): seconds after which one input counts as a timeout. libFuzzer counts
#     wall time: at nice 19 on a loaded machine a fast input can be starved past 10 s, so
#     long campaigns beside other work use FUZZ_TIMEOUT=120 (stat::slowest_unit_time_sec in
#     the target's log tells a real slow input from a starved one).
# Each target runs EXECUTIONS inputs, one process, from its seed corpus
# (tests/fuzz/corpus/<target>), its regression inputs (tests/fuzz/regressions/<target>) and
# what earlier runs found (FUZZ_BUILD/fuzz-work/<target>, kept). libFuzzer stops a target
# at its first finding; the input is copied to tests/fuzz/regressions/<target>/, where
# ctest replays it in the ordinary build (Fuzz.Replay.<target>) once the bug is fixed.
# Prints executions, time, crashes, leaks and timeouts per target; exit status 1 if any.
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:-1000000}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(fuzz_decode fuzz_log_reader fuzz_scenario fuzz_campaign)
build=${FUZZ_BUILD:-build-fuzz}
timeout=${FUZZ_TIMEOUT:-10}
command -v clang++ > /dev/null || { echo "fuzz: clang++ missing (Debian: clang libclang-rt-14-dev)" >&2; exit 2; }

launcher=()
if command -v ccache > /dev/null; then
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
fi
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DCMAKE_C_COMPILER=clang \
  -DCMAKE_CXX_COMPILER=clang++ -DSHOAL_FUZZ=ON -DBUILD_TESTING=OFF "${launcher[@]}" > /dev/null
cmake --build "$build" -j 2 --target "${targets[@]}" > "$build/build.log" 2>&1 ||
  { tail -n 40 "$build/build.log" >&2; echo "fuzz: the build failed ($build/build.log)" >&2; exit 2; }
for t in "${targets[@]}"; do
  [ -x "$build/tests/fuzz/$t" ] || { echo "fuzz: $build/tests/fuzz/$t not built" >&2; exit 2; }
done

echo "machine: $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg); $(clang++ --version | head -1)"
# time_s: wall clock; cpu_s: the fuzzer's own CPU time (what counts on a shared machine).
printf '%-16s %12s %9s %9s %9s %7s %6s %9s %8s\n' target executions time_s cpu_s exec/s \
  crashes leaks timeouts rss_mb
found=0
for t in "${targets[@]}"; do
  work="$build/fuzz-work/$t"
  artifacts="$build/fuzz-artifacts/$t"
  regressions="tests/fuzz/regressions/$t"
  mkdir -p "$work" "$artifacts" "$regressions"
  rm -f "$artifacts"/*
  log="$build/fuzz-$t.log"
  start=$(date +%s%N)
  # New inputs go to the first directory (the work corpus); the others are read only.
  /usr/bin/time -f '%U %S' -o "$build/fuzz-$t.cpu" \
    "$build/tests/fuzz/$t" -runs="$runs" -timeout="$timeout" -rss_limit_mb=2048 \
    -print_final_stats=1 -artifact_prefix="$artifacts/" \
    "$work" "tests/fuzz/corpus/$t" "$regressions" > "$log" 2>&1 && status=0 || status=$?
  end=$(date +%s%N)
  execs=$(grep -a -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo 0)
  cpu=$(tail -n 1 "$build/fuzz-$t.cpu" | awk '{ print $1 + $2 }')  # after time's exit note
  rss=$(grep -a -o 'stat::peak_rss_mb: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo 0)
  count() { find "$artifacts" -name "$1-*" | wc -l; }
  crashes=$(( $(count crash) + $(count oom) ))
  leaks=$(count leak)
  timeouts=$(count timeout)
  awk -v t="$t" -v n="${execs:-0}" -v ns=$((end - start)) -v u="${cpu:-0}" -v c="$crashes" \
    -v l="$leaks" -v o="$timeouts" -v r="${rss:-0}" \
    'BEGIN { s = ns / 1e9; printf "%-16s %12d %9.1f %9.1f %9.0f %7d %6d %9d %8d\n",
             t, n, s, u, n / s, c, l, o, r }'
  # A target that stopped without a finding (it could not start, a bad flag) or ran fewer
  # inputs than asked fuzzed nothing worth a figure: that is a failure too, not a pass.
  if [ "$(find "$artifacts" -type f | wc -l)" -eq 0 ] && { [ "$status" -ne 0 ] || [ "${execs:-0}" -lt "$runs" ]; }; then
    echo "  $t: stopped after ${execs:-0} of $runs executions (status $status) with no finding; see $log" >&2
    found=1
  fi
  for a in "$artifacts"/crash-* "$artifacts"/oom-* "$artifacts"/leak-* "$artifacts"/timeout-*; do
    [ -e "$a" ] || continue
    cp "$a" "$regressions/"
    echo "  finding: $regressions/$(basename "$a") (libFuzzer's output: $log)"
    found=1
  done
done
exit $found
