#include "launcher/launch_script.h"

#include <algorithm>
#include <sstream>

#include "runtime/bus_auth.h"
#include "runtime/channels.h"
#include "runtime/lcm_queue_shim.h"
#include "runtime/process.h"

namespace shoal {
namespace {

// Process bookkeeping, starting and stopping, as shoal run does it (launcher.cc: Spawn,
// Stop, Shutdown). Each process's output goes to <log>.d/<tag>.txt, as with shoal run.
constexpr const char* kHelpers = R"sh(
declare -A name_of=()  # pid -> process name
run_pids=()            # the run's processes (all but the logger), in start order
logger_pid=
status=0

# start NAME TAG NICE COMMAND...: starts COMMAND in the background, output to
# $out_dir/TAG.txt, in a process group of its own (perl's setpgrp, then exec: the same pid;
# setsid would also put it in a scheduling group of its own, where its nice level ranks it
# against nothing), as shoal run does: Ctrl-C at the terminal then reaches this script
# alone, which stops the run's processes before the logger, so that the logger records
# what they send as they stop. The process dies with this script (each Shoal process asks the kernel
# for SIGTERM when its parent dies; lcm-logger is started under setpriv --pdeathsig INT,
# which asks the same for it: SIGINT, on which it closes the log). The traps below stop
# them in order when the script ends otherwise.
start() {
  local name=$1 tag=$2 nice=$3
  shift 3
  set -- /usr/bin/perl -e 'setpgrp(0, 0) or die "setpgrp: $!\n"; exec { $ARGV[0] } @ARGV or die "exec $ARGV[0]: $!\n"' -- "$@"
  if [ "$nice" != 0 ]; then set -- nice -n "$nice" "$@"; fi
  "$@" >"$out_dir/$tag.txt" 2>&1 </dev/null &
  name_of[$!]=$name
  started_pid=$!
  echo "$0: started $name (pid $!)" >&2
}

alive() { kill -0 "$1" 2>/dev/null; }

# stop SIGNAL GRACE_S PID...: sends SIGNAL (and SIGCONT, for a stopped process), then
# SIGKILL to whoever has not exited after GRACE_S seconds.
stop() {
  local sig=$1 grace=$2 pid i any
  shift 2
  for pid; do kill -s "$sig" "$pid" 2>/dev/null && kill -s CONT "$pid" 2>/dev/null || true; done
  for ((i = 0; i < grace * 20; i++)); do
    any=0
    for pid; do if alive "$pid"; then any=1; fi; done
    if [ $any = 0 ]; then return 0; fi
    sleep 0.05
  done
  for pid; do
    if alive "$pid"; then
      echo "$0: ${name_of[$pid]} did not stop within $grace s and was killed" >&2
      kill -s KILL "$pid" 2>/dev/null || true
      status=1
    fi
  done
}

# The run's processes first, the logger last (SIGINT: it flushes and closes the log), so
# that it records everything they published; it drains its socket in between, also when
# they all ended on their own (the emulator's last status is sent just before it exits).
shut_down() {
  local pid left=()
  for pid in "${run_pids[@]}"; do if alive "$pid"; then left+=("$pid"); fi; done
  if [ ${#left[@]} != 0 ]; then stop TERM 2 "${left[@]}"; fi
  if [ -n "$logger_pid" ] && alive "$logger_pid"; then
    sleep 0.2
    logger_writes_all
    stop INT 2 "$logger_pid"
  fi
  # Its count's name, if the clock master never took it over (a run stopped at its start).
  if [ -n "$logger_pid" ]; then rm -f -- "/dev/shm/shoal-logger-$logger_pid"; fi
}
# lcm-logger's writer, stopped by SIGINT, drops what it has not written yet: until it has
# written all it queued, by its count (four 64-bit words: a mark, messages handled, events
# queued, events written), for 5 s at most. With an uplink the emulator has waited for it
# already, and removed the count's name.
logger_writes_all() {
  local count="/dev/shm/shoal-logger-$logger_pid" queued written i
  for ((i = 0; i < 250; i++)); do
    [ -e "$count" ] || return 0
    read -r queued written < <(od -An -v -t u8 -j 16 -N 16 "$count") || return 0
    [ -n "$written" ] && [ "$written" -lt "$queued" ] || return 0
    sleep 0.02
  done
}
trap 'echo "$0: interrupted: stopping the run" >&2; exit 130' INT
trap 'echo "$0: terminated: stopping the run" >&2; exit 143' TERM
trap shut_down EXIT

# describe STATUS: what a wait status means.
describe() {
  if [ "$1" -gt 128 ]; then
    echo "killed by signal $(($1 - 128)) ($(kill -l $(($1 - 128))))"
  else
    echo "exited with status $1"
  fi
}
)sh";

// Watches the processes until the channel emulator ends the run, then stops the rest as
// shoal run does: the others get 2 s to finish their last tick on their own.
constexpr const char* kWatch = R"sh(
# The channel emulator ends the run. Any process that fails, and the logger exiting
# early, stops it (with keep_going=1 a vehicle or the leader that fails is reported and
# the others go on; the run has failed all the same).
watch=("$logger_pid" "${run_pids[@]}")
declare -A exit_of=()  # pid -> exit status, of those seen to end so far
while [ ${#watch[@]} != 0 ]; do
  rc=0
  done_pid=
  wait -n -p done_pid "${watch[@]}" || rc=$?
  if [ -z "$done_pid" ]; then break; fi
  rest=()
  for pid in "${watch[@]}"; do if [ "$pid" != "$done_pid" ]; then rest+=("$pid"); fi; done
  watch=("${rest[@]}")
  exit_of[$done_pid]=$rc
  if [ "$done_pid" = "$emulator_pid" ] && [ $rc = 0 ]; then break; fi
  if [ "$done_pid" = "$logger_pid" ]; then
    echo "$0: lcm-logger exited early ($(describe $rc)): the log ends here" >&2
    status=1
    break
  fi
  if [ $rc != 0 ]; then
    echo "$0: ${name_of[$done_pid]} (pid $done_pid) $(describe $rc)" >&2
    status=1
    if [ "$keep_going" = 1 ] && [ "$done_pid" != "$emulator_pid" ]; then continue; fi
    echo "$0: the run was stopped there" >&2
    break
  fi
done
if [ $status = 0 ]; then
  for ((i = 0; i < 40; i++)); do
    any=0
    for pid in "${run_pids[@]}"; do if alive "$pid"; then any=1; fi; done
    if [ $any = 0 ]; then break; fi
    sleep 0.05
  done
fi
shut_down
trap - EXIT
for pid in "${run_pids[@]}"; do
  if [ -n "${exit_of[$pid]:-}" ]; then continue; fi  # already seen (and said) above
  rc=0
  wait "$pid" || rc=$?
  if [ $rc != 0 ] && [ $status = 0 ]; then
    echo "$0: ${name_of[$pid]} (pid $pid) $(describe $rc)" >&2
    status=1
  fi
done
echo "$0: the run ended ($([ $status = 0 ] && echo "every process ran to the end" || echo "FAILED")); log: $log (shoal analyze $(printf %q "$log"))" >&2
exit $status
)sh";

bool Plain(const std::string& w) {
  if (w.empty()) return false;
  for (const char c : w) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    std::string("-_./:=,@%+").find(c) != std::string::npos;
    if (!ok) return false;
  }
  return true;
}

std::string Joined(const std::vector<std::string>& words) {
  std::string s;
  for (const std::string& w : words) s += (s.empty() ? "" : " ") + ShellWord(w);
  return s;
}

/// `text` for a `#` comment line: a control character (a newline would end the comment and
/// make the rest a command) is shown as '?'.
std::string CommentText(const std::string& text) {
  std::string out = text;
  for (char& c : out) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = '?';
  }
  return out;
}

bool AnyAtSchedFifo(const LaunchPlan& plan) {
  for (const PlannedProcess& p : plan.processes) {
    if (std::find(p.argv.begin(), p.argv.end(), "--sched-fifo") != p.argv.end()) return true;
  }
  return false;
}

/// What the script is, the processes and how they find each other.
void WriteHeader(const LaunchPlan& plan, const LaunchScriptContext& ctx, std::ostream& o) {
  const bool rt = plan.mode == Mode::kRealtime;
  o << "#!/usr/bin/env bash\n"
    << "# A Shoal SIL run of scenario " << CommentText(ctx.scenario_name) << " (" << ModeName(plan.mode)
    << "), started as shoal run starts it. Printed by:\n#   " << CommentText(Joined(ctx.command)) << "\n"
    << "# It starts, in this order (docs/run.md):\n"
    << "#   lcm-logger        records the run's channels (" << channels::kAllPattern
    << ") into the log\n"
    << "#   channel emulator  the only path between vehicles: delay, loss and rate limit per\n"
    << "#                     link; " << (rt ? "it releases each message at send time + delay"
                                            : "the clock master of lockstep")
    << "; its end ends the run\n"
    << "#   leader            publishes the leader's path state (SHOAL_STATE_0)\n"
    << "#   vehicle 1.." << plan.processes.size() - 3
    << "      one per follower: publishes SHOAL_STATE_<id>, hears only SHOAL_RX_<id>\n"
    << "# How they find each other: each publishes on its --lcm-url (an LCM URL\n"
    << "# udpm://GROUP:PORT?ttl=0: a multicast group and port that never leave the host).\n"
    << "# The logger records the run's shared bus. Where the emulator has --uplink-url, the\n"
    << "# others publish there instead (group 239.255.76.68, the block's last port) and the\n"
    << "# emulator passes what they send on to the shared bus. Where a process has --rx-url\n"
    << "# it receives there, on a bus of its own (group 239.255.<77+id/200>.<20+id%200>,\n"
    << "# port <run port> + 1 + id); the emulator delivers to each on it (--vehicle-urls,\n"
    << "# leader first). The URLs were drawn when this was printed: print it again for a\n"
    << "# run beside this one.\n";
  if (plan.insecure) {
    o << "# --insecure: the bus is not authenticated (no key).\n";
  } else {
    o << "# Every message is signed with the run's key, " << bus_auth::kKeyEnv
      << " in the environment\n# (64 hex digits, drawn below; also in <log>.key, to verify "
         "the log later).\n";
  }
  o << "# Tick k is due at t0 + k period: t0 is given on the wall clock (--t0-unix-ns,\n"
    << "# CLOCK_REALTIME ns), 4 s after the logger is up; each process converts it once to\n"
    << "# its own monotonic clock (on several hosts their wall clocks must agree).\n"
    << "# Exit status: 0 the emulator ended the run and every process ran to the end; 1 a\n"
    << "# process failed or the logger exited early; 2 multicast not kept on the host" 
    << (AnyAtSchedFifo(plan) ? ", or\n# SCHED_FIFO (--sched-fifo) not permitted here;" : ";")
    << "\n# 130/143 interrupted. What the log holds (states logged of those expected, late\n"
    << "# ticks, convergence): shoal analyze <log>.\n"
    << "set -euo pipefail\n";
}

void WriteSetup(const LaunchPlan& plan, const LaunchScriptContext& ctx, std::ostream& o) {
  o << "cd " << ShellWord(ctx.working_dir) << "  # where shoal run was; the paths are from it\n"
    << "log=" << ShellWord(plan.log) << "\nout_dir=" << ShellWord(plan.output_dir)
    << "  # each process's output, <tag>.txt\n"
    << "keep_going=" << (plan.keep_going ? 1 : 0) << "\n";
  if (AnyAtSchedFifo(plan)) {
    // The emulator is given --sched-fifo whenever any process is, at the highest priority.
    const std::string prio = std::to_string(kEmulatorFifoPriority);
    o << "\n# Processes given --sched-fifo refuse to start without the right to SCHED_FIFO:\n"
      << "# checked before anything is changed or started, as shoal run does.\n"
      << "if command -v chrt >/dev/null && ! chrt -f " << prio << " true 2>/dev/null; then\n"
      << "  echo \"$0: --sched-fifo: SCHED_FIFO priority " << prio << " refused here (it needs "
      << "CAP_SYS_NICE, which root has, or RLIMIT_RTPRIO >= " << prio << ")\" >&2\n"
      << "  exit 2\nfi\n";
  }
  if (plan.lcm_url.rfind("udpm://", 0) == 0) {
    const std::string fix = "ip link set lo multicast on && ip route add 239.255.0.0/16 dev lo";
    o << "\n# Multicast must stay on this host (as shoal run checks).\n"
      << "if ! ip route get 239.255.76.67 2>/dev/null | grep -q ' dev lo'; then\n"
      << "  if [ \"$(id -u)\" = 0 ]; then\n    " << fix << "\n  else\n"
      << "    echo \"$0: multicast is not routed to the loopback interface; as root run: "
      << fix << "\" >&2\n    exit 2\n  fi\nfi\n";
  }
  o << "\nunset " << bus_auth::kKeyEnv
    << "  # a key exported by the calling shell would reach lcm-logger and other runs\n";
  o << "\nmkdir -p -- \"$out_dir\"\n"
    << "# One run at a time writes this log: another would remove it while it is written. The\n"
    << "# lock on <log>.d/ is the one shoal run takes; every process started below holds it\n"
    << "# (fd 9) until the last ends.\n"
    << "if command -v flock >/dev/null; then\n"
    << "  exec 9<\"$out_dir\"\n"
    << "  if ! flock -n 9; then\n"
    << "    echo \"$0: another run is writing $log (it holds $out_dir/)\" >&2\n    exit 2\n  fi\n"
    << "fi\n"
    << "rm -f -- \"$out_dir\"/{vehicle,leader,emulator,logger}*.{txt,ckpt} \"$out_dir/resources.csv\"\n";
  if (plan.insecure) {
    o << "rm -f -- \"$log.key\"  # an earlier run's key would make this log look forged\n";
  } else {
    o << "\n# The run's key: 32 random bytes as 64 hex digits, also written to a new file\n"
      << "# <log>.key (mode 0600) for shoal analyze and shoal compare. Exported only after\n"
      << "# the logger has started: lcm-logger records bytes as they are and does not get it.\n"
      << bus_auth::kKeyEnv << "=$(head -c 32 /dev/urandom | od -An -v -tx1 | tr -d ' \\n')\n"
      << "rm -f -- \"$log.key\"\n"
      << "(umask 077 && set -C && printf '%s\\n' \"$" << bus_auth::kKeyEnv
      << "\" >\"$log.key\")\n";
  }
  o << kHelpers;
}

/// One `start` line: argv broken before each option. The logger's log is the script's
/// $log, so that editing the one `log=` line moves the whole run's output.
void WriteStart(const PlannedProcess& p, const std::string& nice, const std::string& log,
                std::ostream& o) {
  o << "start " << ShellWord(p.name) << " " << p.tag << " " << nice << " \\\n  ";
  std::vector<std::string> words = p.prefix;
  // Shoal's processes ask for SIGTERM when their parent dies; lcm-logger cannot, so even
  // a SIGKILLed script (no trap runs) leaves no logger behind.
  if (p.id == kLoggerId) words.insert(words.end(), {"/usr/bin/setpriv", "--pdeathsig", "INT"});
  if (!p.env.empty()) words.push_back("/usr/bin/env");  // execs in place: the same pid
  words.insert(words.end(), p.env.begin(), p.env.end());
  words.insert(words.end(), p.argv.begin(), p.argv.end());
  for (std::size_t i = 0; i < words.size(); ++i) {
    if (i > 0) o << (words[i].rfind("--", 0) == 0 ? " \\\n    " : " ");
    o << (p.id == kLoggerId && i + 1 == words.size() && words[i] == log ? "\"$log\""
                                                                         : ShellWord(words[i]));
  }
  o << "\n";
}

// Inside a wait for the logger: it exited (it could not open the bus, say) and will never
// subscribe; nothing else is started.
constexpr const char* kLoggerGone =
    "if ! alive \"$logger_pid\"; then\n"
    "    echo \"$0: lcm-logger exited before it subscribed ($out_dir/logger.txt)\" >&2\n"
    "    exit 1\n"
    "  fi\n";

// Until the logger has subscribed: it creates the log before it does, and what the
// processes sent before then would never reach it. On this host it makes its count's name
// (which stays until the end: shut_down reads it, then removes it, unless the emulator
// takes it over); on another it says so on its output.
void WriteSubscriptionWait(const PlannedProcess& logger, std::ostream& o) {
  const auto has = [&](const std::string& e) {
    return std::find(logger.env.begin(), logger.env.end(), e) != logger.env.end();
  };
  std::string subscribed;
  if (has("SHOAL_LOGGER_PROGRESS=1")) {
    std::string name = "/dev/shm" SHOAL_LOGGER_PROGRESS_NAME;
    name.replace(name.find("%ld"), 3, "$logger_pid");
    subscribed = "[ -e \"" + name + "\" ]";
    o << "# It creates the log before it subscribes, and its count once subscribed: what the\n"
      << "# processes sent before then would never reach it. The count's name stays until the\n"
      << "# end (shut_down reads it, then removes it) unless the emulator takes it over.\n";
  } else if (has(SHOAL_LOGGER_SAY_SUBSCRIBED_ENV "=1")) {
    subscribed = "grep -qF '" SHOAL_LOGGER_SUBSCRIBED_LINE "' \"$out_dir/logger.txt\"";
    o << "# It creates the log before it subscribes, and on another host says on its output\n"
      << "# once subscribed: what the processes sent before then would never reach it.\n";
  } else {
    return;
  }
  o << "for ((i = 0; i < 1500; i++)); do\n"
    << "  if " << subscribed << "; then break; fi\n"
    << "  " << kLoggerGone << "  sleep 0.02\n"
    << "done\n"
    << "if ! " << subscribed << "; then\n"
    << "  echo \"$0: warning: lcm-logger had not subscribed after 30 s: what the run\" \\\n"
    << "       \"sends before it does is not in the log\" >&2\n"
    << "fi\n";
}

void WriteProcesses(const LaunchPlan& plan, std::ostream& o) {
  const PlannedProcess& logger = plan.processes.front();
  o << "\n# lcm-logger, first (as root at nice -10: its subscription queue must not wait for\n"
    << "# the CPU; with LD_PRELOAD the queue holds more than LCM's 30 messages, and with\n"
    << "# SHOAL_LOGGER_PROGRESS=1 it counts what it has handled and written, for the\n"
    << "# emulator's --recorder-pid wait; with SHOAL_LOGGER_BATCH=1, in lockstep, it runs\n"
    << "# under SCHED_BATCH). The run's processes start once its log exists (and, counting,\n"
    << "# once it has subscribed).\n"
    << "logger_nice=0\nif [ \"$(id -u)\" = 0 ]; then logger_nice=-10; fi\n"
    << "rm -f -- \"$log\"\n";
  WriteStart(logger, "$logger_nice", plan.log, o);
  o << "logger_pid=$started_pid\n"
    << "for ((i = 0; i < 250; i++)); do\n"
    << "  if [ -e \"$log\" ] || ! alive \"$logger_pid\"; then break; fi; sleep 0.02\n"
    << "done\n"
    << "if [ ! -e \"$log\" ]; then\n"
    << "  echo \"$0: lcm-logger did not create $log (it exited, or 5 s passed):\" \\\n"
    << "       \"$out_dir/logger.txt\" >&2\n"
    << "  exit 1\nfi\n";
  // With an uplink the leader and the vehicles publish there, and the emulator passes it on.
  bool uplink = false;
  for (const PlannedProcess& p : plan.processes) {
    uplink = uplink || std::find(p.argv.begin(), p.argv.end(), "--uplink-url") != p.argv.end();
  }
  WriteSubscriptionWait(logger, o);
  if (!plan.insecure) o << "export " << bus_auth::kKeyEnv << "\n";
  o << "# Tick 0 on the wall clock, 4 s from now (ns since 1970).\n"
    << "t0=$(( $(date +%s%N) + 4000000000 ))\n";
  const std::string published = uplink ? "to the emulator's uplink (--lcm-url here), which "
                                         "passes it on\n# to the shared bus"
                                       : "on the shared bus";
  for (std::size_t i = 1; i < plan.processes.size(); ++i) {
    const PlannedProcess& p = plan.processes[i];
    o << "\n";
    if (p.id == kEmulatorId) {
      o << "# The channel emulator: hears every state " << (uplink ? "on its uplink" : "on the shared bus")
        << " and delivers it to each\n"
        << "# receiver after the link's delay (or drops it)"
        << (plan.mode == Mode::kLockstep
                ? "; the lockstep clock: it waits for every\n# process's \"ready\", "
                  "releases the ticks and waits for their states"
                : "")
        << ".\n";
    } else if (p.id == 0) {
      o << "# The leader: its path state " << published << ".\n";
    } else {
      o << "# " << p.name << ": its state " << published
        << "; its neighbours' via the emulator.\n";
    }
    WriteStart(p, std::to_string(p.nice_inc), plan.log, o);
    o << "run_pids+=(\"$started_pid\")\n";
    if (p.id == kEmulatorId) o << "emulator_pid=$started_pid\n";
  }
}

}  // namespace

std::string ShellWord(const std::string& word) {
  if (word == kT0Arg) return "\"$t0\"";
  if (word == kLoggerPidArg) return "\"$logger_pid\"";
  if (Plain(word)) return word;
  std::string q = "'";
  for (const char c : word) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

std::string LaunchScript(const LaunchPlan& plan, const LaunchScriptContext& ctx) {
  std::ostringstream o;
  WriteHeader(plan, ctx, o);
  WriteSetup(plan, ctx, o);
  WriteProcesses(plan, o);
  o << kWatch;
  return o.str();
}

}  // namespace shoal
