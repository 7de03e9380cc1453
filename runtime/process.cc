#include "runtime/process.h"

#include <fcntl.h>
#include <sched.h>
#include <signal.h>
#include <pthread.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <thread>

#include <CLI/CLI.hpp>

#include "runtime/clock.h"
#include "runtime/stop_signals.h"
#include "scenario/loader.h"

namespace shoal {

namespace {

// How a process started alone (not by shoal run) finds the others of its run.
constexpr const char* kStartAloneHelp =
    "Starting it alone (shoal run --print-launch SCENARIO prints every command of a run; "
    "docs/run.md, \"Launching by hand or by script\"). Every process of a run gets the "
    "same --scenario, --set, --mode and --duration, and:\n"
    "  bus: --lcm-url is the run's shared LCM bus (states SHOAL_STATE_<id>, health, status, "
    "the channel's decisions; lcm-logger records it); a vehicle (and the leader) receives "
    "what the channel emulator delivers to it, and the lockstep clock, on its --rx-url "
    "(default: --lcm-url), and the emulator is given those URLs in --vehicle-urls (leader "
    "first). Nothing goes from vehicle to vehicle but through the emulator.\n"
    "  key: the run's key in the environment, SHOAL_BUS_KEY=<64 hex digits>, the same for "
    "every process (e.g. export SHOAL_BUS_KEY=$(head -c32 /dev/urandom | od -An -v -tx1 | "
    "tr -d ' \\n')); or --insecure on every process.\n"
    "  start time (realtime; required): tick k is due at t0 + k period. --t0-unix-ns is t0 "
    "on the wall clock (CLOCK_REALTIME ns, e.g. $(( $(date +%s%N) + 4000000000 )) for 4 s "
    "from now), which processes on several hosts can share: each converts it once at its "
    "start to its own monotonic clock and keeps to that, so a wall-clock step or slew during "
    "the run does not move its ticks. This assumes the hosts' wall clocks agree; how well "
    "they agree (NTP: typically 1-10 ms, PTP: microseconds) bounds how well the hosts' "
    "ticks line up. --t0-ns is t0 on CLOCK_MONOTONIC, on this host only. A start time in "
    "the past is allowed (a restarted process goes on with the run's t0); one more than a "
    "day from now is refused.\n"
    "  lockstep: the channel emulator is the clock; the others wait for it (no t0 needed).";

}  // namespace

void AddProcessOptions(CLI::App* app, ProcessOptions* opt) {
  app->add_option("--scenario", opt->scenario, "Scenario file (TOML)")->required();
  app->add_option("--set", opt->set,
                  "KEY=VALUE: change the scenario as shoal run was told to (repeatable)")
      ->allow_extra_args(false);
  app->add_option("--lcm-url", opt->lcm_url,
                  "LCM URL of the run's shared bus; the leader and the vehicles of a run "
                  "whose emulator has --uplink-url are given that URL here instead, and "
                  "publish there")
      ->required();
  app->add_option("--rx-url", opt->rx_url,
                  "LCM URL on which this process receives (default: --lcm-url)");
  app->add_option("--mode", opt->mode, "lockstep (the default) or realtime")
      ->check(CLI::IsMember({ModeName(Mode::kLockstep), ModeName(Mode::kRealtime)}));
  app->add_option("--t0-ns", opt->t0_ns,
                  "realtime: CLOCK_MONOTONIC ns of tick 0 (this host only; shoal run's "
                  "default)");
  app->add_option("--t0-unix-ns", opt->t0_unix_ns,
                  "realtime: CLOCK_REALTIME ns (since 1970) of tick 0, shared by hosts whose "
                  "wall clocks agree; converted once at start to CLOCK_MONOTONIC");
  app->add_option("--duration", opt->duration_s, "Simulated seconds (default: the scenario's)")
      ->check(CLI::Validator(
          [](std::string& text) {
            // As the scenario's run.duration_s: inf or 1e30 would count no tick.
            char* end = nullptr;
            const double v = std::strtod(text.c_str(), &end);
            const bool ok = end != text.c_str() && *end == '\0' && v > 0 && v <= 1e9;
            return ok ? std::string() : "must be a positive number of seconds, at most 1e9";
          },
          "SECONDS"));
  app->add_flag("--insecure", opt->insecure,
                "Do not authenticate the bus's messages (else the run's key is read from "
                "SHOAL_BUS_KEY, docs/run.md)");
  app->add_flag("--sched-fifo", opt->sched_fifo,
                "realtime: run at SCHED_FIFO (shoal run --sched-fifo); a process that may "
                "not (it needs CAP_SYS_NICE, which root has, or RLIMIT_RTPRIO) refuses to "
                "start");
  app->footer(kStartAloneHelp);
}

std::int64_t RealtimeNs() {
  timespec ts;
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
}

std::int64_t MonotonicFromUnixNs(std::int64_t unix_ns) {
  // Monotonic before and after the wall clock: the wall clock was read at about their
  // middle, give or take half the gap. Five pairs; the tightest wins.
  std::int64_t best_gap = -1, offset = 0;  // offset: realtime - monotonic
  for (int i = 0; i < 5; ++i) {
    const std::int64_t before = MonotonicNs();
    const std::int64_t wall = RealtimeNs();
    const std::int64_t after = MonotonicNs();
    if (best_gap < 0 || after - before < best_gap) {
      best_gap = after - before;
      offset = wall - (before + (after - before) / 2);
    }
  }
  return unix_ns - offset;
}

bool ResolveStartTime(bool monotonic_given, bool unix_given, ProcessOptions* opt,
                      std::string* error) {
  if (monotonic_given && unix_given) {
    *error = "give the start time once: --t0-ns (CLOCK_MONOTONIC) or --t0-unix-ns "
             "(CLOCK_REALTIME), not both";
    return false;
  }
  if (!monotonic_given && !unix_given) {
    if (opt->parsed_mode() != Mode::kRealtime) return true;  // lockstep reads no clock
    *error = "real time needs the run's start time (tick 0): give --t0-unix-ns NS "
             "(CLOCK_REALTIME ns, the same for every process of the run, e.g. "
             "$(( $(date +%s%N) + 4000000000 ))) or --t0-ns NS (CLOCK_MONOTONIC ns, this "
             "host only); see --help";
    return false;
  }
  // Lockstep reads no clock: a start time given there is not used, so not judged.
  if (opt->parsed_mode() != Mode::kRealtime) return true;
  const char* name = unix_given ? "--t0-unix-ns" : "--t0-ns";
  const char* clock = unix_given ? "CLOCK_REALTIME (date +%s%N)" : "CLOCK_MONOTONIC";
  const std::int64_t given = unix_given ? opt->t0_unix_ns : opt->t0_ns;
  const std::int64_t now = unix_given ? RealtimeNs() : MonotonicNs();
  // As doubles: a wild value must not overflow the difference. A start time in the past
  // is a restarted process resuming its run, however long that run has lasted; only one
  // before the clock can have read (before boot, or on the wall clock before 2000: the
  // other clock's value) is a mistake.
  const double away_s = (static_cast<double>(given) - static_cast<double>(now)) * 1e-9;
  const std::int64_t floor = unix_given ? kEarliestUnixStartNs : 0;
  if (away_s > kMaxStartOffsetNs * 1e-9 || given < floor) {
    char text[360];
    std::snprintf(text, sizeof(text),
                  "%s %lld is %.0f s %s now, %s: refused as a mistake (%s is %s ns; now it "
                  "reads %lld)",
                  name, static_cast<long long>(given), std::fabs(away_s),
                  away_s < 0 ? "before" : "after", 
                  given < floor ? (unix_given ? "before the year 2000" : "before boot")
                                : "more than a day ahead",
                  name, clock, static_cast<long long>(now));
    *error = text;
    return false;
  }
  if (unix_given) opt->t0_ns = MonotonicFromUnixNs(opt->t0_unix_ns);
  return true;
}

namespace {

/// For the process's output: where its ticks come from, and so how to compare its
/// timing with that of processes on other hosts.
void SayStartTime(const std::string& name, const ProcessOptions& opt, bool unix_given) {
  if (opt.parsed_mode() != Mode::kRealtime) return;
  if (unix_given) {
    std::fprintf(stderr, "%s: tick 0 at --t0-unix-ns %lld (wall clock) = CLOCK_MONOTONIC %lld "
                 "on this host, %.3f s from now\n", name.c_str(),
                 static_cast<long long>(opt.t0_unix_ns), static_cast<long long>(opt.t0_ns),
                 (opt.t0_ns - MonotonicNs()) * 1e-9);
  } else {
    std::fprintf(stderr, "%s: tick 0 at --t0-ns %lld (CLOCK_MONOTONIC), %.3f s from now\n",
                 name.c_str(), static_cast<long long>(opt.t0_ns),
                 (opt.t0_ns - MonotonicNs()) * 1e-9);
  }
}

}  // namespace

int StartProcess(CLI::App* app, int argc, char** argv, const std::string& name,
                 ProcessOptions* opt, Scenario* scenario) {
  try {
    app->parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app->exit(e) == 0 ? 0 : 2;
  }
  if (opt->sched_fifo && opt->parsed_mode() != Mode::kRealtime) {
    std::fprintf(stderr, "%s: --sched-fifo is for real time; lockstep runs under SCHED_BATCH "
                 "(add --mode realtime, or leave --sched-fifo out)\n", name.c_str());
    return 2;
  }
  std::string error;
  const bool unix_given = app->count("--t0-unix-ns") > 0;
  if (!ResolveStartTime(app->count("--t0-ns") > 0, unix_given, opt, &error)) {
    std::fprintf(stderr, "%s: %s\n", name.c_str(), error.c_str());
    return 2;
  }
  SayStartTime(name, *opt, unix_given);
  InstallProcessSignals();
  return LoadScenarioWithSetsOrReport(name, opt->scenario, opt->set, scenario) ? -1 : 2;
}

void InstallProcessSignals() {
  static StopSignals signals;  // for the life of the process, never restored
  prctl(PR_SET_PDEATHSIG, SIGTERM);
  if (getppid() == 1) StopSignals::Request();  // the parent died before prctl took effect
}

bool StopRequested() { return StopSignals::Requested(); }

std::string EnableRealtimeScheduling(int priority, bool clock_master, bool required,
                                     bool* refused) {
  if (refused != nullptr) *refused = false;
  prctl(PR_SET_TIMERSLACK, 1UL);
  // SCHED_FIFO is opt-in: under load a late FIFO loop catching up starves lcm-logger and
  // the others (docs/benchmarks.md, real time). The emulator alone does a bounded burst of
  // work at each release and sleeps between: "emulator" gives it the CPU at its release
  // instants without letting the vehicles' loops take anyone's.
  const char* fifo = std::getenv("SHOAL_SCHED_FIFO");
  const bool from_env =
      fifo != nullptr && (std::strcmp(fifo, "emulator") != 0 || clock_master);
  if (!required && !from_env) return "SCHED_OTHER, timer slack 1 ns";
  sched_param sp = {};
  sp.sched_priority = priority;
  if (sched_setscheduler(0, SCHED_FIFO, &sp) == 0) {
    return "SCHED_FIFO priority " + std::to_string(priority) + ", timer slack 1 ns";
  }
  const int err = errno;
  if (required && refused != nullptr) *refused = true;
  return std::string("SCHED_OTHER (SCHED_FIFO refused: ") + std::strerror(err) +
         (err == EPERM ? "; it needs CAP_SYS_NICE, which root has, or RLIMIT_RTPRIO >= " +
                             std::to_string(priority)
                       : std::string()) +
         "), timer slack 1 ns";
}

bool EnterScheduling(const std::string& name, const ProcessOptions& opt, int priority,
                     bool clock_master) {
  if (opt.parsed_mode() != Mode::kRealtime) {
    std::fprintf(stderr, "%s: %s\n", name.c_str(), EnableBatchScheduling().c_str());
    return true;
  }
  bool refused = false;
  const std::string said =
      EnableRealtimeScheduling(priority, clock_master, opt.sched_fifo, &refused);
  std::fprintf(stderr, "%s: %s\n", name.c_str(), said.c_str());
  if (refused) {
    std::fprintf(stderr, "%s: --sched-fifo asked for SCHED_FIFO and the kernel refused it; "
                 "not starting\n", name.c_str());
  }
  return !refused;
}

bool SchedFifoPermitted(int priority, std::string* why) {
  int err = 0;
  std::thread probe([&err, priority] {
    sched_param sp = {};
    sp.sched_priority = priority;
    err = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
  });
  probe.join();
  if (err == 0) return true;
  *why = std::string("SCHED_FIFO priority ") + std::to_string(priority) + " refused: " +
         std::strerror(err) +
         (err == EPERM ? " (it needs CAP_SYS_NICE, which root has, or RLIMIT_RTPRIO >= " +
                             std::to_string(priority) + ")"
                       : std::string());
  return false;
}

void LeaveRealtimeScheduling() {
  sched_param sp = {};
  sp.sched_priority = 0;
  sched_setscheduler(0, SCHED_OTHER, &sp);
  setpriority(PRIO_PROCESS, 0, 10);
}

std::string EnableBatchScheduling() {
  sched_param sp = {};
  sp.sched_priority = 0;
  if (sched_setscheduler(0, SCHED_BATCH, &sp) == 0) return "SCHED_BATCH";
  return std::string("SCHED_OTHER (SCHED_BATCH refused: ") + std::strerror(errno) + ")";
}

std::string LockMemory() {
#if defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
#define SHOAL_SANITIZED 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__) || defined(SHOAL_SANITIZED)
  // Locking would fault in the sanitizer's terabytes of reserved shadow memory.
  return "memory not locked (sanitizer build)";
#endif
  if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) return "memory locked (mlockall)";
  return std::string("memory not locked (mlockall: ") + std::strerror(errno) + ")";
}

CpuLatencyRequest::CpuLatencyRequest() {
  fd_ = open("/dev/cpu_dma_latency", O_WRONLY | O_CLOEXEC);
  if (fd_ < 0) {
    note_ = std::string("no CPU latency request (/dev/cpu_dma_latency: ") + std::strerror(errno) + ")";
    return;
  }
  const std::int32_t zero_us = 0;
  if (write(fd_, &zero_us, sizeof(zero_us)) != static_cast<ssize_t>(sizeof(zero_us))) {
    note_ = std::string("no CPU latency request (write: ") + std::strerror(errno) + ")";
    close(fd_);
    fd_ = -1;
    return;
  }
  note_ = "CPU latency request 0 us held (idle CPUs poll)";
}

CpuLatencyRequest::~CpuLatencyRequest() {
  if (fd_ >= 0) close(fd_);
}

}  // namespace shoal
