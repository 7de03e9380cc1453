#include "tools/run_command.h"

#include <fcntl.h>
#include <sched.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <memory>
#include <random>
#include <sstream>
#include <thread>
#include <vector>

#include "analysis/analysis.h"
#include "core/metrics.h"
#include "runtime/channels.h"
#include "runtime/clock.h"
#include "runtime/lcm_bus.h"
#include "runtime/process.h"
#include "runtime/log_reader.h"
#include "runtime/messages.h"
#include "scenario/loader.h"
#include "tools/json.h"

namespace shoal {
namespace {

volatile sig_atomic_t g_interrupted = 0;
extern "C" void OnRunSignal(int) { g_interrupted = 1; }
// A child's exit interrupts the supervisor's wait (no SA_RESTART), so that the end of a
// run is seen at once rather than at the next 50 ms poll.
extern "C" void OnChildSignal(int) {}

struct Child {
  std::string name;  // "vehicle 3", "leader", "channel emulator", "lcm-logger"
  int id = -100;     // vehicle id, kEmulatorId, or -100 for the logger
  pid_t pid = -1;
  bool running = false;
  int status = 0;  // raw waitpid status once exited
};

std::string ExeDir() {
  char buf[4096];
  const ssize_t n = readlink("/proc/self/exe", buf, sizeof(buf) - 1);
  if (n <= 0) return ".";
  buf[n] = 0;
  std::string p(buf);
  return p.substr(0, p.rfind('/'));
}

/// Finds a sibling executable of the build tree (tools/../vehicle/shoal_vehicle) or of an
/// installation (same directory).
std::string FindExe(const std::string& subdir, const std::string& name) {
  const std::string dir = ExeDir();
  for (const std::string& c : {dir + "/../" + subdir + "/" + name, dir + "/" + name}) {
    if (access(c.c_str(), X_OK) == 0) return c;
  }
  return "";
}

std::string Describe(int status) {
  if (WIFEXITED(status)) return "exited with status " + std::to_string(WEXITSTATUS(status));
  if (WIFSIGNALED(status)) {
    return std::string("killed by signal ") + std::to_string(WTERMSIG(status)) + " (" +
           strsignal(WTERMSIG(status)) + ")";
  }
  return "stopped";
}

pid_t Spawn(const std::vector<std::string>& argv, int nice_inc, const std::string& log_path) {
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid != 0) return pid;
  // Child: its own process group (a terminal Ctrl-C reaches only shoal run, which shuts
  // the run down in order), dies with shoal run, output to a per-process file.
  setpgid(0, 0);
  prctl(PR_SET_PDEATHSIG, SIGKILL);
  if (getppid() != parent) _exit(127);
  if (nice_inc != 0) setpriority(PRIO_PROCESS, 0, nice_inc);
  const int fd = open(log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd >= 0) {
    dup2(fd, 1);
    dup2(fd, 2);
    close(fd);
  }
  const int devnull = open("/dev/null", O_RDONLY);
  if (devnull >= 0) dup2(devnull, 0);
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  execv(args[0], args.data());
  std::fprintf(stderr, "cannot exec %s: %s\n", args[0], std::strerror(errno));
  _exit(127);
}

}  // namespace

int RunRun(const RunOptions& opt) {
  Scenario s;
  if (!LoadScenarioOrReport("shoal run", opt.scenario, &s)) return 2;
  if (opt.mode != "lockstep" && opt.mode != "realtime") {
    std::cerr << "shoal run: --mode must be lockstep or realtime (got " << opt.mode << ")\n";
    return 2;
  }
  if (opt.duration_s == 0 || (opt.duration_s < 0 && opt.duration_s != -1)) {
    std::cerr << "shoal run: --duration must be a positive number of seconds\n";
    return 2;
  }
  const double duration = opt.duration_s > 0 ? opt.duration_s : s.duration_s;
  const std::string out = opt.out.empty() ? s.name + ".lcmlog" : opt.out;
  {  // The log must be writable before anything starts.
    const int fd = open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd < 0) {
      std::cerr << "shoal run: " << out << ": cannot open log for writing ("
                << std::strerror(errno) << ")\n";
      return 2;
    }
    close(fd);
    unlink(out.c_str());
  }
  const std::string vehicle_exe = FindExe("vehicle", "shoal_vehicle");
  const std::string leader_exe = FindExe("leader", "shoal_leader");
  const std::string emulator_exe = FindExe("channel_emulator", "shoal_channel_emulator");
  if (vehicle_exe.empty() || leader_exe.empty() || emulator_exe.empty()) {
    std::cerr << "shoal run: cannot find shoal_vehicle, shoal_leader or "
                 "shoal_channel_emulator next to " << ExeDir() << "\n";
    return 2;
  }
  if (std::system("command -v lcm-logger >/dev/null 2>&1") != 0) {
    std::cerr << "shoal run: lcm-logger not found (Debian package liblcm-bin)\n";
    return 2;
  }
  std::string url = opt.lcm_url;
  int port = 0;
  if (url.empty() || url.rfind("udpm://", 0) == 0) {
    std::string err;
    if (!EnsureLoopbackMulticast(&err)) {
      std::cerr << "shoal run: " << err << "\n";
      return 2;
    }
  }
  if (url.empty()) {
    port = RandomPrivatePort(s.followers);
    url = PrivateLcmUrl(port) + "&recv_buf_size=4194304";
  }
  // Each vehicle receives on its own group unless asked otherwise: on one shared group
  // every vehicle's socket would receive -- and wake up for -- every message of the run.
  std::vector<std::string> vurls;
  if (opt.per_vehicle_urls && opt.shared_url) {
    std::cerr << "shoal run: --per-vehicle-urls and --shared-url exclude each other\n";
    return 2;
  }
  if (opt.per_vehicle_urls || (port != 0 && !opt.shared_url)) {
    if (port == 0) {
      std::cerr << "shoal run: --per-vehicle-urls needs the default private URL\n";
      return 2;
    }
    vurls = PerVehicleLcmUrls(port, s.followers);
  }

  // Child output goes next to the log.
  const std::string out_dir = out.find('/') == std::string::npos ? "." : out.substr(0, out.rfind('/'));
  const std::string stem = out.substr(out.rfind('/') + 1);
  auto child_log = [&](const std::string& tag) { return out_dir + "/." + stem + "." + tag + ".txt"; };

  struct sigaction sa = {};
  sa.sa_handler = OnRunSignal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGHUP, &sa, nullptr);
  struct sigaction sc = {};
  sc.sa_handler = OnChildSignal;
  sigemptyset(&sc.sa_mask);
  sigaction(SIGCHLD, &sc, nullptr);
  g_interrupted = 0;

  // Held until shoal run exits (after every child has stopped).
  std::unique_ptr<CpuLatencyRequest> latency;
  if (!opt.deep_idle) latency = std::make_unique<CpuLatencyRequest>();

  std::vector<Child> kids;
  auto start = [&](const std::string& name, int id, const std::vector<std::string>& argv,
                   int nice_inc, const std::string& tag) {
    Child c;
    c.name = name;
    c.id = id;
    c.pid = Spawn(argv, nice_inc, child_log(tag));
    c.running = c.pid > 0;
    kids.push_back(c);
  };
  // Lockstep saturates the CPU: its processes run at a lower priority than the logger,
  // under SCHED_BATCH (they set it themselves: a woken process does not preempt the one
  // sending it a burst). Real time is paced by the clock.
  const int run_nice = opt.mode == "lockstep" ? 5 : 0;
  // The logger first. lcm-logger's subscription queue holds 30 messages and drops beyond
  // that (LCM's default; lcm-logger has no option for it): the logger must not wait long
  // for the CPU while the run saturates it. As root it runs at nice -10 against the run's
  // +5 (CFS weight 9548 against 335), else at 0. SCHED_FIFO was tried (session 3) and
  // dropped: it preempts the run at every message, and with SHOAL_CHANNEL batched it lost
  // no fewer states (README "The SIL runtime": 600 s runs, 36-39x against 50-56x).
  const bool root = geteuid() == 0;
  start("lcm-logger", -100, {"/usr/bin/lcm-logger", "--lcm-url=" + url, "-f", "-q", out},
        root ? -10 : 0, "logger");
  const pid_t logger_pid = kids.back().running ? kids.back().pid : 0;
  for (int i = 0; i < 100 && access(out.c_str(), F_OK) != 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  const std::int64_t t0_ns = MonotonicNs() + 4000000000LL;  // real time: start margin
  std::vector<std::string> common = {"--scenario", opt.scenario, "--lcm-url", url, "--mode",
                                     opt.mode, "--t0-ns", std::to_string(t0_ns), "--duration",
                                     std::to_string(duration)};
  auto with = [&](std::vector<std::string> a, const std::vector<std::string>& more) {
    a.insert(a.end(), common.begin(), common.end());
    a.insert(a.end(), more.begin(), more.end());
    return a;
  };
  std::string vlist;
  for (std::size_t i = 0; i < vurls.size(); ++i) vlist += (i ? "," : "") + vurls[i];
  std::vector<std::string> emulator_more = {"--max-lookahead", std::to_string(opt.max_lookahead)};
  if (opt.mode == "lockstep" && logger_pid > 0) {
    emulator_more.push_back("--recorder-pid");  // back-pressure: the log stays complete
    emulator_more.push_back(std::to_string(logger_pid));
  }
  if (!vurls.empty()) {
    emulator_more.push_back("--vehicle-urls");
    emulator_more.push_back(vlist);
  }
  // The clock master is every window's critical path (it waits for the last state, then
  // releases the next window): in lockstep it runs at nice 0, above the vehicles' +5.
  start("channel emulator", kEmulatorId, with({emulator_exe}, emulator_more), 0,
        "emulator");
  start("leader", 0,
        with({leader_exe}, vurls.empty() ? std::vector<std::string>{}
                                         : std::vector<std::string>{"--rx-url", vurls[0]}),
        run_nice, "leader");
  for (int id = 1; id <= s.followers; ++id) {
    std::vector<std::string> more = {"--id", std::to_string(id)};
    if (!vurls.empty()) {
      more.push_back("--rx-url");
      more.push_back(vurls[id]);
    }
    start("vehicle " + std::to_string(id), id, with({vehicle_exe}, more), run_nice,
          "vehicle" + std::to_string(id));
  }

  // Supervise: progress from the log as lcm-logger writes it (not from the bus: a
  // listener on the run's group would receive, and wake up for, every message of the run),
  // process deaths from waitpid.
  LogTail tail(out);
  // The worst formation error: each follower's newest error against the leader's state at
  // the same time (the log interleaves ticks, so the leader's recent states are kept).
  std::int64_t last_tick_utime = 0;
  std::map<Micros, StateMsg> leader_states;  // recent ones only
  std::vector<double> follower_error(s.followers + 1, 0.0);
  const LogTail::Handler on_event = [&](const std::string& ch, const void* d, int n) {
    if (ch.rfind("SHOAL_STATE_", 0) != 0) return;
    vehicle_state_t m{};
    if (!Decode(d, n, &m) || m.vehicle_id < 0 || m.vehicle_id > s.followers) return;
    const StateMsg st = FromLcm(m);
    last_tick_utime = std::max<std::int64_t>(last_tick_utime, m.utime);
    if (m.vehicle_id == 0) {
      leader_states[st.utime] = st;
      while (leader_states.size() > 256) leader_states.erase(leader_states.begin());
      return;
    }
    const auto l = leader_states.find(st.utime);
    if (l != leader_states.end()) {
      follower_error[m.vehicle_id] =
          ErrorsOf(st, s.offsets_m[m.vehicle_id - 1], l->second).position_m;
    }
  };
  auto worst_error = [&] {
    double w = 0.0;
    for (double e : follower_error) w = std::max(w, e);
    return w;
  };
  const bool show = !opt.quiet && !opt.json && isatty(2);
  const auto wall0 = std::chrono::steady_clock::now();
  auto last_show = wall0;
  std::vector<std::string> problems;
  bool emulator_done = false;
  while (!emulator_done && !g_interrupted) {
    const timespec poll = {0, 50000000};
    nanosleep(&poll, nullptr);  // returns early when a child exits
    for (Child& c : kids) {
      if (!c.running) continue;
      if (waitpid(c.pid, &c.status, WNOHANG) == c.pid) {
        c.running = false;
        if (c.id == kEmulatorId) {
          emulator_done = true;
        } else if (!(WIFEXITED(c.status) && WEXITSTATUS(c.status) == 0)) {
          const std::string msg = c.name + " (pid " + std::to_string(c.pid) + ") " + Describe(c.status);
          problems.push_back(msg);
          if (!opt.json) std::fprintf(stderr, "%sshoal run: %s; the others keep running\n",
                                      show ? "\n" : "", msg.c_str());
        }
      }
    }
    const auto now = std::chrono::steady_clock::now();
    if (show && now - last_show > std::chrono::milliseconds(500)) {
      last_show = now;
      tail.Poll(on_event);
      int alive = 0;
      for (const Child& c : kids) alive += c.running && c.id != -100;
      const double wall = opt.mode == "realtime"
                              ? std::max(1e-9, (MonotonicNs() - t0_ns) * 1e-9)
                              : std::chrono::duration<double>(now - wall0).count();
      std::fprintf(stderr, "\r  t = %7.1f / %.0f s  (%.1fx real time)  worst position error %.2f m  processes alive %d/%d   ",
                   ToSeconds(last_tick_utime), duration, ToSeconds(last_tick_utime) / wall,
                   worst_error(), alive, s.followers + 2);
    }
  }
  // Real time: from the common start time t0 (the start margin before it is not the run's).
  const double wall_s =
      opt.mode == "realtime"
          ? std::max(0.0, (MonotonicNs() - t0_ns) * 1e-9)
          : std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  if (show) std::fprintf(stderr, "\r%110s\r", "");

  // Shutdown: the run's processes first (SIGTERM, SIGKILL after 2 s), the logger last so
  // that it records everything they published.
  auto stop = [&](bool logger) {
    for (Child& c : kids) {
      if (c.running && (c.id == -100) == logger) kill(c.pid, logger ? SIGINT : SIGTERM);
    }
    const auto t = std::chrono::steady_clock::now();
    for (;;) {
      bool any = false;
      for (Child& c : kids) {
        if (!c.running || (c.id == -100) != logger) continue;
        if (waitpid(c.pid, &c.status, WNOHANG) == c.pid) {
          c.running = false;
        } else {
          any = true;
        }
      }
      if (!any) break;
      if (std::chrono::steady_clock::now() - t > std::chrono::seconds(2)) {
        for (Child& c : kids) {
          if (c.running && (c.id == -100) == logger) {
            kill(c.pid, SIGKILL);
            // SIGCHLD has a handler without SA_RESTART: an exit elsewhere interrupts this.
            while (waitpid(c.pid, &c.status, 0) < 0 && errno == EINTR) {
            }
            c.running = false;
            problems.push_back(c.name + " did not stop within 2 s and was killed");
          }
        }
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  };
  if (!g_interrupted) {
    // Normal end: give the vehicles a moment to finish their last tick on their own.
    const auto t = std::chrono::steady_clock::now();
    while (std::chrono::steady_clock::now() - t < std::chrono::seconds(2)) {
      bool any = false;
      for (Child& c : kids) {
        if (c.running && c.id != -100) {
          if (waitpid(c.pid, &c.status, WNOHANG) == c.pid) {
            c.running = false;
          } else {
            any = true;
          }
        }
      }
      if (!any) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
  stop(false);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // logger drains its socket
  stop(true);
  for (const Child& c : kids) {
    if (c.id == -100 || g_interrupted) continue;
    const bool ok = WIFEXITED(c.status) && WEXITSTATUS(c.status) == 0;
    const std::string msg = c.name + " (pid " + std::to_string(c.pid) + ") " + Describe(c.status);
    if (!ok && std::find(problems.begin(), problems.end(), msg) == problems.end()) {
      problems.push_back(msg);
    }
  }

  // The summary is read back from the run's log (the single source of truth), with the
  // same code as shoal analyze (analysis/).
  RunSummary sum;
  if (!SummariseRunLog(out, s, &sum)) problems.push_back("the log " + out + " cannot be read");
  const double lateness_p99 = sum.lateness_p99_s, delay_err_p99 = sum.release_error_p99_s;
  const std::int64_t overruns = sum.overruns;
  const bool converged = sum.converged;
  // lcm-logger drops messages when it cannot keep up (LCM's 30-message subscription
  // queue); say so instead of hiding it.
  const std::int64_t expected_states =
      (s.final_tick(duration) + 1) * (s.followers + 1);
  const bool all_ok = problems.empty() && !g_interrupted;

  if (opt.json) {
    JsonWriter ch, loop, j;
    ch.Int("delivered", sum.delivered).Int("dropped", sum.dropped)
        .Num("delay_error_p99_s", opt.mode == "realtime" ? delay_err_p99 : 0.0);
    loop.Num("lateness_p99_s", lateness_p99).Int("overruns", overruns);
    std::string probs = "[";
    for (std::size_t i = 0; i < problems.size(); ++i) {
      probs += (i ? "," : "") + JsonWriter::Quote(problems[i]);
    }
    j.Str("scenario", s.name)
        .Str("mode", opt.mode)
        .Bool("converged", converged)
        .Num("convergence_time_s", converged ? sum.convergence_time_s : NAN)
        .Num("final_position_error_m", sum.final_worst.position_m)
        .Num("final_velocity_error_mps", sum.final_worst.velocity_mps)
        .Num("final_attitude_error_rad", sum.final_worst.attitude_rad)
        .Num("sim_time_s", sum.sim_time_s)
        .Num("wall_time_s", wall_s)
        .Num("realtime_factor", wall_s > 0 ? sum.sim_time_s / wall_s : NAN)
        .Raw("channel", ch.Done())
        .Raw("loop", loop.Done())
        .Bool("all_processes_ok", all_ok)
        .Raw("problems", probs + "]")
        .Bool("interrupted", g_interrupted != 0)
        .Str("log", out)
        .Int("log_states", sum.states)
        .Int("log_states_expected", expected_states)
        .Str("lcm_url", url)
        .Bool("cpu_latency_request", latency && latency->held());
    std::cout << j.Done() << "\n";
  } else {
    std::printf("shoal run: %s (%s, %d followers, %.0f Hz)\n", s.name.c_str(), opt.mode.c_str(),
                s.followers, s.control_rate_hz);
    std::printf("  simulated %.1f s in %.2f s wall (%.1fx real time)%s\n", sum.sim_time_s,
                wall_s, wall_s > 0 ? sum.sim_time_s / wall_s : 0.0,
                g_interrupted ? "  -- interrupted" : "");
    std::printf("  %s\n", latency ? latency->note().c_str()
                                   : "no CPU latency request (--deep-idle)");
    if (converged) {
      std::printf("  converged: yes, at %.2f s\n", sum.convergence_time_s);
    } else {
      std::printf("  converged: NO\n");
    }
    std::printf("  final errors, worst follower: position %.4f m, velocity %.4f m/s, attitude %.4f rad\n",
                sum.final_worst.position_m, sum.final_worst.velocity_mps,
                sum.final_worst.attitude_rad);
    std::printf("  channel (as recorded in the log): %lld delivered, %lld dropped",
                static_cast<long long>(sum.delivered), static_cast<long long>(sum.dropped));
    if (opt.mode == "realtime") std::printf(", release error p99 %.3f ms", delay_err_p99 * 1e3);
    std::printf("\n");
    if (opt.mode == "realtime") {
      std::printf("  loops: lateness p99 %.3f ms, %lld overruns\n", lateness_p99 * 1e3,
                  static_cast<long long>(overruns));
    }
    for (const std::string& p : problems) std::printf("  PROBLEM: %s\n", p.c_str());
    std::printf("  log: %s (URL %s), %lld of %lld vehicle states recorded\n", out.c_str(),
                url.c_str(), static_cast<long long>(sum.states),
                static_cast<long long>(expected_states));
  }
  if (g_interrupted) return 130;
  return all_ok ? 0 : 1;
}

}  // namespace shoal
