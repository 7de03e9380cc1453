#!/usr/bin/env bash
# shoal run --hosts through a real ssh: three network namespaces joined by veth pairs to a
# bridge in a fourth (as netns_hosts_test.sh), a real sshd in two of them (its own config
# file, a private port, a throwaway host key and an authorized key made here; the
# machine's own ssh configuration is not read or changed). The logger, the channel
# emulator and the leader run in the first namespace (ip netns exec), the vehicles on the
# other two through `ssh -o BatchMode=yes ... root@ADDR`. Checks that
#   - lockstep: the run's log equals shoal sim's of the same scenario exactly and holds
#     every state, with a scenario and a log whose paths hold a space, a quote and shell
#     metacharacters (ssh hands its arguments to the remote shell as one line);
#   - the run's key reaches the vehicles through ssh (the run is authenticated: a vehicle
#     without it would publish nothing the others accept);
#   - a vehicle killed on its host (SIGKILL, in its namespace) is reported by name and the
#     run exits non-zero;
#   - after each run, and after SIGINT to shoal run, nothing is left on the ssh hosts:
#     no vehicle, no sshd serving a login, only the sshd listener;
#   - a real-time run with every process behind ssh (the logger too, whose LD_PRELOAD
#     goes through env(1)) logs every state;
#   - 16 vehicles on one host start although sshd drops logins beyond 10 at once
#     (MaxStartups): shoal run lets 8 log in at a time;
#   - a prefix that runs in place but shows another boot id (another machine) is not
#     taken for one that starts shoal run's own processes (no --recorder-pid);
#   - a host whose ssh login fails is refused before anything starts (exit 2).
# sshd, the namespaces (and with them every interface) and the temporary folder are
# removed on exit, also on failure.
#
# Usage: ssh_hosts_test.sh SOURCE_DIR SHOAL
# Exit 77 (ctest SKIP_RETURN_CODE) when not root, without iproute2 or without OpenSSH's
# server and client.
set -euo pipefail

src=${1:?usage: ssh_hosts_test.sh SOURCE_DIR SHOAL}
shoal=${2:?usage: ssh_hosts_test.sh SOURCE_DIR SHOAL SLOW_SUBSCRIBE_LIB}
# tests/tools/slow_logger_subscribe.c, built: preloaded into a run, it delays lcm-logger.
slow_subscribe=${3:?usage: ssh_hosts_test.sh SOURCE_DIR SHOAL SLOW_SUBSCRIBE_LIB}
readonly LOCKSTEP_S=10

fail() {
  echo "FAILED: $*" >&2
  exit 1
}
skip() {
  echo "SKIPPED: $*"
  exit 77
}
# The value of a key in shoal's --json output (keys used here are unique in it).
json() {
  grep -oE "\"$1\": *[^,}]*" "$2" | head -n 1 | sed -E 's/^[^:]*: *//; s/"//g'
}

[ -x "$shoal" ] || fail "no shoal executable at $shoal"
[ "$(id -u)" = 0 ] || skip "needs root (network namespaces, sshd)"
command -v ip >/dev/null || skip "ip not found: install Debian's iproute2"
[ -x /usr/sbin/sshd ] || skip "no /usr/sbin/sshd: install Debian's openssh-server"
command -v ssh >/dev/null && command -v ssh-keygen >/dev/null ||
  skip "no ssh or ssh-keygen: install Debian's openssh-client"

work=$(mktemp -d /tmp/shoal-ssh-test.XXXXXX)
id=$$
h1=shoal-s1-$id h2=shoal-s2-$id h3=shoal-s3-$id br=shoal-sbr-$id
port=$((20000 + id % 20000))  # sshd's, in each namespace (its own network: no clash)
netns_was_mounted=0
if mountpoint -q /run/netns 2>/dev/null; then netns_was_mounted=1; fi
shoal_pid=
cleanup() {
  local status=$?
  [ -n "$shoal_pid" ] && kill -9 "$shoal_pid" 2>/dev/null
  for ns in "$h2" "$h3"; do  # sshd first: it would accept logins
    if [ -f "$work/sshd-$ns.pid" ]; then kill "$(cat "$work/sshd-$ns.pid")" 2>/dev/null || true; fi
  done
  sleep 0.2
  for ns in "$h1" "$h2" "$h3" "$br"; do
    if ip netns list 2>/dev/null | grep -qw "$ns"; then
      # Anything still running there is a failure of the run's supervision.
      if [ -n "$(ip netns pids "$ns" 2>/dev/null)" ]; then
        echo "FAILED: processes left in $ns: $(ip netns pids "$ns" | xargs -r ps -o pid=,args= -p)" >&2
        ip netns pids "$ns" | xargs -r kill -9 || true
        status=1
      fi
      ip netns del "$ns" || status=1
    fi
  done
  if [ "$netns_was_mounted" = 0 ] && mountpoint -q /run/netns 2>/dev/null &&
     [ -z "$(ip netns list 2>/dev/null)" ]; then
    umount /run/netns 2>/dev/null || true
  fi
  rm -rf "$work"
  exit "$status"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# --- The hosts: namespaces on a bridge. -------------------------------------------------
ip netns add "$br" || skip "cannot create network namespaces here"
ip -n "$br" link set lo up
ip -n "$br" link add br0 type bridge
ip -n "$br" link set br0 up
i=0
for ns in "$h1" "$h2" "$h3"; do
  i=$((i + 1))
  ip netns add "$ns"
  ip -n "$ns" link add eth0 type veth peer name "p$i" netns "$br"
  ip -n "$br" link set "p$i" master br0 up
  ip -n "$ns" link set lo up
  ip -n "$ns" link set eth0 up multicast on
  ip -n "$ns" addr add "10.78.0.$i/24" dev eth0
  # LCM's udpm sends and joins by the route for its group: without one it fails.
  ip -n "$ns" route add 224.0.0.0/4 dev eth0
done

# --- sshd in h2 and h3: own config, host key and authorized key, all in $work. ----------
# sshd needs its privilege separation folder (made by Debian's ssh service when it runs).
mkdir -p /run/sshd
chmod 0755 /run/sshd
ssh-keygen -q -t ed25519 -N '' -C shoal-test-host -f "$work/host_key"
ssh-keygen -q -t ed25519 -N '' -C shoal-test-client -f "$work/client_key"
cp "$work/client_key.pub" "$work/authorized_keys"
chmod 0600 "$work/authorized_keys"
for n in 2 3; do
  ns_var=h$n
  ns=${!ns_var}
  cat >"$work/sshd-$ns.conf" <<EOF
ListenAddress 10.78.0.$n:$port
HostKey $work/host_key
PidFile $work/sshd-$ns.pid
AuthorizedKeysFile $work/authorized_keys
PermitRootLogin prohibit-password
PubkeyAuthentication yes
PasswordAuthentication no
KbdInteractiveAuthentication no
UsePAM no
X11Forwarding no
PrintMotd no
AcceptEnv none
# The keys live under /tmp, which need not be as sshd's StrictModes wants it.
StrictModes no
EOF
  ip netns exec "$ns" /usr/sbin/sshd -f "$work/sshd-$ns.conf" -E "$work/sshd-$ns.log" ||
    fail "sshd did not start in $ns: $(cat "$work/sshd-$ns.log" 2>/dev/null)"
done
cat >"$work/known_hosts" <<EOF
[10.78.0.2]:$port $(cat "$work/host_key.pub")
[10.78.0.3]:$port $(cat "$work/host_key.pub")
EOF
ssh_prefix() {  # the hosts-file prefix for host number $1, as a TOML array's items
  printf '"ssh", "-o", "BatchMode=yes", "-o", "StrictHostKeyChecking=yes", '
  printf '"-o", "UserKnownHostsFile=%s", "-i", "%s", "-p", "%s", "root@10.78.0.%s"' \
    "$work/known_hosts" "$work/client_key" "$port" "$1"
}
# sshd is up: a login through the same prefix answers (from h1, as shoal run's processes
# there would: the root namespace has no route to the bridge).
for n in 2 3; do
  up=0
  for _ in $(seq 50); do
    if out=$(ip netns exec "$h1" ssh -o BatchMode=yes -o StrictHostKeyChecking=yes \
               -o UserKnownHostsFile="$work/known_hosts" -i "$work/client_key" -p "$port" \
               "root@10.78.0.$n" 'readlink /proc/self/ns/net' 2>&1); then
      up=1
      break
    fi
    sleep 0.1
  done
  [ "$up" = 1 ] || fail "no ssh login to 10.78.0.$n:$port: $out; sshd: $(cat "$work/sshd-"*.log)"
  ns_var=h$n
  [ "$out" = "$(ip netns exec "${!ns_var}" readlink /proc/self/ns/net)" ] ||
    fail "the ssh login to 10.78.0.$n did not land in its namespace ($out)"
done
echo "sshd is up in two namespaces"

# shoal run itself runs in h1 (its own processes there run in place: ip netns exec); the
# vehicles on h2 and h3 through ssh.
hosts_file() {  # $1: the placement
  cat <<EOF
[[host]]
name = "h1"
prefix = ["ip", "netns", "exec", "$h1"]
interface = "eth0"

[[host]]
name = "h2"
prefix = [$(ssh_prefix 2)]
interface = "eth0"

[[host]]
name = "h3"
prefix = [$(ssh_prefix 3)]
interface = "eth0"

[placement]
$1
EOF
}
placement='logger = "h1"
emulator = "h1"
leader = "h1"
vehicles = { h2 = ["1-2", 5], h3 = [3, 4] }'
hosts_file "$placement" >"$work/hosts.toml"

# Nothing but the sshd listener on the ssh hosts (within 5 s: the sshd serving a login
# ends just after the process it ran).
only_sshd_left() {  # WHAT
  local ns left=""
  for ns in "$h2" "$h3"; do
    for _ in $(seq 50); do
      left=$(ip netns pids "$ns" | grep -vx "$(cat "$work/sshd-$ns.pid")" || true)
      [ -z "$left" ] && break
      sleep 0.1
    done
    [ -z "$left" ] ||
      fail "$1: left running in $ns: $(echo "$left" | xargs -r ps -o pid=,args= -p)"
  done
}

# --- Lockstep through ssh equals shoal sim; paths with a space and shell characters. ----
odd="$work/a dir 'with' \$(quotes) & \"more\"; x"
mkdir -p "$odd"
scenario="$odd/paper example2.toml"
cp "$src/scenarios/paper_example2.toml" "$scenario"
status=0
ip netns exec "$h1" "$shoal" run --hosts "$work/hosts.toml" "$scenario" \
  --duration "$LOCKSTEP_S" --json --out "$odd/lock run.lcmlog" >"$work/lock.json" \
  2>"$work/lock.err" || status=$?
# Exit 1: not converged in 10 s (as shoal sim says below); every process ran to the end.
[ "$status" = 1 ] || fail "lockstep run: exit status $status: $(cat "$work/lock.err" "$work/lock.json") $(tail -n 3 "$odd/lock run.lcmlog.d/"*.txt)"
[ "$(json all_processes_ok "$work/lock.json")" = true ] || fail "lockstep run: $(cat "$work/lock.json")"
[ "$(json log_complete "$work/lock.json")" = true ] || fail "lockstep log incomplete: $(cat "$work/lock.json")"
# The key reached every process through its pipe: the log's messages are all signed.
[ "$(json bus_authenticated "$work/lock.json")" = true ] && [ "$(json unauthenticated "$work/lock.json")" = 0 ] ||
  fail "lockstep run: not authenticated: $(cat "$work/lock.json")"
[ "$(json log_states "$work/lock.json")" = "$(json log_states_expected "$work/lock.json")" ] ||
  fail "lockstep run: not every state logged: $(cat "$work/lock.json")"
status=0
"$shoal" sim "$scenario" --duration "$LOCKSTEP_S" --out "$work/sim.lcmlog" >/dev/null 2>&1 || status=$?
[ "$status" = 1 ] || fail "shoal sim: exit status $status"
status=0
"$shoal" compare "$odd/lock run.lcmlog" "$work/sim.lcmlog" --json >"$work/cmp.json" 2>&1 || status=$?
[ "$status" = 0 ] || fail "compare: exit status $status: $(cat "$work/cmp.json")"
for key in max_position_diff_m max_velocity_diff_mps only_in_a only_in_b non_finite_diffs; do
  awk -v v="$(json "$key" "$work/cmp.json")" 'BEGIN { exit !(v != "" && v == 0) }' ||
    fail "compare: $key not 0: $(cat "$work/cmp.json")"
done
[ "$(json samples "$work/cmp.json")" = $((6 * (LOCKSTEP_S * 50 + 1))) ] ||
  fail "compare: not every state: $(cat "$work/cmp.json")"
only_sshd_left "after the lockstep run"
echo "lockstep through ssh equals shoal sim (paths with spaces and shell characters)"

# --- Supervision across ssh: a vehicle killed on its host. ------------------------------
# The pid of vehicle $2 in namespace $1, once it runs there ("" after 20 s).
vehicle_pid() {
  local p
  for _ in $(seq 200); do
    for p in $(ip netns pids "$1"); do
      if tr '\0' ' ' 2>/dev/null <"/proc/$p/cmdline" | grep -q "shoal_vehicle .*--id $2 "; then
        echo "$p"
        return
      fi
    done
    sleep 0.1
  done
}
ip netns exec "$h1" "$shoal" run --hosts "$work/hosts.toml" "$src/scenarios/paper_example2.toml" \
  --mode realtime --duration 60 --json --out "$work/killed.lcmlog" >"$work/killed.json" \
  2>"$work/killed.err" &
shoal_pid=$!
victim=$(vehicle_pid "$h3" 3)
[ -n "$victim" ] || fail "vehicle 3 never ran in h3: $(cat "$work/killed.err")"
for _ in $(seq 300); do  # the mission has begun: the log holds states
  [ "$(stat -c %s "$work/killed.lcmlog" 2>/dev/null || echo 0)" -gt 20000 ] && break
  sleep 0.1
done
kill -KILL "$victim"
status=0
wait "$shoal_pid" || status=$?
shoal_pid=
[ "$status" != 0 ] || fail "a run that lost vehicle 3 exited 0: $(cat "$work/killed.json")"
grep -q '"all_processes_ok": *false' "$work/killed.json" ||
  fail "a run that lost vehicle 3: $(cat "$work/killed.json")"
grep -qE 'vehicle 3 \(pid [0-9]+\) exited with status 255 .* at t = [0-9.]+ s of the mission' "$work/killed.json" ||
  fail "the run did not say it lost vehicle 3: $(cat "$work/killed.err" "$work/killed.json")"
only_sshd_left "after a run that lost a vehicle"
echo "a vehicle killed behind ssh stops the run, which names it ($(grep -oE 'vehicle 3 \(pid [0-9]+\) exited with status [0-9]+' "$work/killed.json" | head -n 1))"

# --- SIGINT to shoal run: everything on the ssh hosts stops. ----------------------------
ip netns exec "$h1" "$shoal" run --hosts "$work/hosts.toml" "$src/scenarios/paper_example2.toml" \
  --mode realtime --duration 60 --json --out "$work/int.lcmlog" >"$work/int.json" \
  2>"$work/int.err" &
shoal_pid=$!
for v in 1 2 5; do [ -n "$(vehicle_pid "$h2" $v)" ] || fail "vehicle $v never ran in h2"; done
for v in 3 4; do [ -n "$(vehicle_pid "$h3" $v)" ] || fail "vehicle $v never ran in h3"; done
sleep 1
kill -INT "$shoal_pid"
status=0
wait "$shoal_pid" || status=$?
shoal_pid=
[ "$status" = 130 ] || fail "SIGINT: exit status $status: $(cat "$work/int.err" "$work/int.json")"
only_sshd_left "after SIGINT to shoal run"
echo "SIGINT to shoal run stops everything behind ssh"

# --- Everything behind ssh, the logger too (its LD_PRELOAD goes through env(1)). --------
hosts_file 'logger = "h2"
emulator = "h3"
leader = "h2"
vehicles = { h2 = [1, 2], h3 = ["3-5"] }' >"$work/all_ssh.toml"
status=0
ip netns exec "$h1" "$shoal" run --hosts "$work/all_ssh.toml" "$src/scenarios/paper_example2.toml" \
  --mode realtime --duration 5 --json --out "$work/all.lcmlog" >"$work/all.json" \
  2>"$work/all.err" || status=$?
[ "$status" = 1 ] || fail "run behind ssh: exit status $status: $(cat "$work/all.err" "$work/all.json")"
for key in all_processes_ok log_complete; do
  [ "$(json "$key" "$work/all.json")" = true ] || fail "run behind ssh: $key: $(cat "$work/all.json")"
done
[ "$(json log_states "$work/all.json")" = "$(json log_states_expected "$work/all.json")" ] ||
  fail "run behind ssh: not every state logged: $(cat "$work/all.json")"
only_sshd_left "after a run with everything behind ssh"
echo "a real-time run with every process behind ssh logs every state"

# --- A logger behind ssh slow to subscribe (1.5 s, preloaded) still records the start. ---
# Its /dev/shm is not shoal run's to see: it says on its output once it has subscribed, and
# nothing starts before. Else the emulator's first status, the scenario's text, sent as it
# starts, would be lost.
status=0
ip netns exec "$h1" env LD_PRELOAD="$slow_subscribe" "$shoal" run --hosts "$work/all_ssh.toml" \
  "$src/scenarios/paper_example2.toml" --mode realtime --duration 3 --json \
  --out "$work/slow.lcmlog" >"$work/slow.json" 2>"$work/slow.err" || status=$?
[ "$(json log_complete "$work/slow.json")" = true ] ||
  fail "slow logger behind ssh: log incomplete (exit $status): $(cat "$work/slow.json" "$work/slow.err")"
grep -qF "shoal lcm queue shim: subscribed" "$work/slow.lcmlog.d/logger.txt" ||
  fail "slow logger behind ssh: it did not say it had subscribed: $(cat "$work/slow.lcmlog.d/logger.txt")"
"$shoal" analyze "$work/slow.lcmlog" --json >"$work/slow_analyze.json" 2>"$work/slow_analyze.err" || true
[ "$(json scenario_source "$work/slow_analyze.json")" = log ] ||
  fail "slow logger behind ssh: the log lacks the scenario: $(cat "$work/slow_analyze.err")"
only_sshd_left "after a run with a slow logger behind ssh"
echo "a logger behind ssh slow to subscribe still records the run from its start"

# --- More processes on one host than sshd lets log in at once. --------------------------
# sshd's MaxStartups (default 10:30:100) drops connections still logging in beyond 10:
# shoal run lets at most 8 log in to a host at a time.
bash "$src/bench/scale_scenario.sh" 16 >"$work/scale16.toml"
hosts_file 'logger = "h1"
emulator = "h1"
leader = "h1"
vehicles = { h2 = ["1-16"] }' >"$work/many.toml"
status=0
ip netns exec "$h1" "$shoal" run --hosts "$work/many.toml" "$work/scale16.toml" --duration 3 \
  --json --out "$work/many.lcmlog" >"$work/many.json" 2>"$work/many.err" || status=$?
[ "$status" = 1 ] || fail "16 vehicles behind ssh: exit status $status: $(cat "$work/many.err" "$work/many.json")"
for key in all_processes_ok log_complete; do
  [ "$(json "$key" "$work/many.json")" = true ] || fail "16 vehicles behind ssh: $key: $(cat "$work/many.json")"
done
! grep -q MaxStartups "$work/sshd-$h2.log" || fail "sshd dropped logins: $(grep MaxStartups "$work/sshd-$h2.log")"
only_sshd_left "after 16 vehicles on one host"
echo "16 vehicles on one ssh host start, 8 logins at a time"

# --- A prefix that runs in place, on another machine: not the same processes. -----------
# The pid namespace of a machine's init has the same inode on every machine and a remote
# shell's pid can equal the local ssh client's: the probe's boot id tells them apart. Here
# a mount namespace shows another boot id to a process that runs in place.
echo 00000000-0000-0000-0000-000000000000 >"$work/boot_id"
cat >"$work/other_boot.toml" <<EOF
[[host]]
name = "elsewhere"
prefix = ["ip", "netns", "exec", "$h1", "unshare", "--mount", "sh", "-c",
          "mount --bind $work/boot_id /proc/sys/kernel/random/boot_id && exec \"\$@\"", "boot"]

[placement]
default = "elsewhere"
EOF
status=0
ip netns exec "$h1" "$shoal" run --hosts "$work/other_boot.toml" "$src/scenarios/paper_example2.toml" \
  --duration 2 --json --out "$work/boot.lcmlog" >"$work/boot.json" 2>"$work/boot.err" || status=$?
[ "$status" = 1 ] || fail "another boot id: exit status $status: $(cat "$work/boot.err" "$work/boot.json")"
[ "$(json all_processes_ok "$work/boot.json")" = true ] || fail "another boot id: $(cat "$work/boot.json")"
! grep -q "waited for the recorder" "$work/boot.lcmlog.d/emulator.txt" ||
  fail "a host with another boot id was taken for shoal run's own: the emulator got the logger's pid"
echo "a host with another boot id is not taken for shoal run's own processes"

# --- A host ssh cannot log in to is refused before anything starts. ---------------------
sed "s|$work/client_key\"|$work/host_key\"|" "$work/hosts.toml" >"$work/bad_key.toml"
status=0
ip netns exec "$h1" "$shoal" run --hosts "$work/bad_key.toml" "$src/scenarios/paper_example2.toml" \
  --duration 1 --out "$work/bad.lcmlog" >"$work/bad.out" 2>"$work/bad.err" || status=$?
[ "$status" = 2 ] || fail "a host ssh cannot log in to: exit status $status: $(cat "$work/bad.err")"
grep -qE "host h[23] \($work/bad_key.toml:[0-9]+\): .*Permission denied" "$work/bad.err" ||
  fail "a host ssh cannot log in to: $(cat "$work/bad.err")"
[ ! -e "$work/bad.lcmlog" ] || fail "a refused run left a log"
echo "a host ssh cannot log in to is refused"

# Every process placed on h2 and h3 went through a login there.
logins=$(cat "$work"/sshd-*.log | grep -c 'Accepted publickey for root') || true
[ "$logins" -ge 20 ] || fail "only $logins ssh logins: $(cat "$work"/sshd-*.log)"
