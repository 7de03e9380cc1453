#!/usr/bin/env bash
# The work of a lockstep run grows with its links, not with its vehicles squared: at a
# fixed two in-links per follower (bench/scale_scenario.sh), one vehicle executes as many
# instructions per tick among 64 followers as among 5 (no more than 5 % above), and the
# channel emulator, lcm-logger and the three together no more than 20 % more per follower.
# Counted by bench/scale_work.sh (callgrind: user-space instructions, close on any x86-64
# machine for the same build), not timed; what a host charges for a switch among more processes is
# bench/scale.sh's to measure. A vehicle that heard every state, or an emulator or logger
# whose work per message grew with the swarm, fails here.
#
# Usage: work_per_follower_test.sh SOURCE_DIR BUILD_DIR
# Exit 77 (ctest SKIP_RETURN_CODE) without valgrind, or when not root and multicast is not
# routed to the loopback interface (the run's script adds the route as root).
set -euo pipefail
src=${1:?usage: work_per_follower_test.sh SOURCE_DIR BUILD_DIR}
build=${2:?usage: work_per_follower_test.sh SOURCE_DIR BUILD_DIR}
command -v valgrind > /dev/null || { echo "skipped: valgrind is not installed"; exit 77; }
if [ "$(id -u)" != 0 ] && ! ip route get 239.255.76.67 2> /dev/null | grep -q ' dev lo'; then
  echo "skipped: multicast is not routed to lo, and only root can add the route"
  exit 77
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$src/bench/scale_work.sh" "$build" "5 64" 4 12 "$work/work.csv"

# followers,vehicle,emulator,logger,all_per_follower (instructions per tick)
awk -F, '
  NR == 2 { n0 = $1; v0 = $2; e0 = $3 / $1; l0 = $4 / $1; a0 = $5 }
  NR == 3 { n1 = $1; v1 = $2; e1 = $3 / $1; l1 = $4 / $1; a1 = $5 }
  function check(what, lo, hi, limit) {
    if (lo < 1000 || hi < 1000) {
      printf "FAIL: %s: %d and %d instructions a tick: no real count\n", what, lo, hi
      bad = 1
    } else if (hi / lo > limit) {
      printf "FAIL: %s: %d instructions a tick at %d followers, %d at %d (%.2f times; at most %.2f)\n",
             what, lo, n0, hi, n1, hi / lo, limit
      bad = 1
    } else {
      printf "ok: %s: %d at %d followers, %d at %d (%.2f times)\n", what, lo, n0, hi, n1, hi / lo
    }
  }
  END {
    if (n0 != 5 || n1 != 64) { print "FAIL: the benchmark wrote no row for 5 and 64 followers"; exit 1 }
    check("one vehicle", v0, v1, 1.05)
    check("the emulator per follower", e0, e1, 1.2)
    check("the logger per follower", l0, l1, 1.2)
    check("all three per follower", a0, a1, 1.2)
    exit bad
  }' "$work/work.csv"
