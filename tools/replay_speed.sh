#!/usr/bin/env bash
# Which lcm-logplayer speeds shoal analyze --live keeps up with (docs/analyze.md, Replay):
# plays LOG at each SPEED, RUNS times, into `shoal analyze --live --json` on a private
# multicast URL (ttl=0), and prints per run the exit status (0 complete, 3 missed), the
# states missed of those expected, and the other messages missed (sequence gaps).
# Usage: tools/replay_speed.sh SHOAL LOG RUNS SPEED... (the key: LOG.key if it exists)
set -euo pipefail
shoal=${1:?usage: tools/replay_speed.sh SHOAL LOG RUNS SPEED...}
log=${2:?log}
runs=${3:?runs}
shift 3
port=$(( 20000 + (RANDOM % 20000) * 2 ))
url="udpm://239.255.76.67:${port}?ttl=0"
key=()
[ -f "$log.key" ] && key=(--key "$log.key")
out=$(mktemp)
trap 'rm -f "$out"' EXIT
printf '%-28s %6s %4s %5s %16s %8s %8s\n' log speed run exit states_missed_of messages wall_s
for speed in "$@"; do
  for run in $(seq 1 "$runs"); do
    "$shoal" analyze --live --json --until-idle 5 --lcm-url "$url" "${key[@]}" >"$out" 2>/dev/null &
    ana=$!
    for _ in $(seq 100); do  # until it listens on the port
      grep -qi ":$(printf '%04X' "$port") " /proc/net/udp && break
      sleep 0.05
    done
    sleep 0.5  # the multicast join completes after the bind: the first ticks would be lost
    t0=$(date +%s.%N)
    lcm-logplayer --lcm-url="$url" --speed="$speed" "$log" >/dev/null 2>&1
    t1=$(date +%s.%N)
    status=0
    wait "$ana" || status=$?
    python3 - "$out" "$log" "$speed" "$run" "$status" "$t0" "$t1" <<'PY'
import json, os, sys
path, log, speed, run, status, t0, t1 = sys.argv[1:]
try:
    j = json.load(open(path))
    missed = "%d/%d" % (j["states_missed"], j["log_states_expected"])
    msgs = j["stream"]["messages_missed"]
except Exception:
    missed, msgs = "-", "-"
print("%-28s %6s %4s %5s %16s %8s %8.2f" % (os.path.basename(log)[:28], speed, run, status,
                                           missed, msgs, float(t1) - float(t0)))
PY
  done
done
