#include "launcher/launcher.h"

#include <dirent.h>
#include <fcntl.h>
#include <pthread.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <set>
#include <sstream>
#include <memory>
#include <thread>

#include "core/metrics.h"
#include "core/swarm.h"
#include "launcher/idle_poller.h"
#include "launcher/remote_host.h"
#include "runtime/channels.h"
#include "runtime/checkpoint.h"
#include "runtime/clocked_node.h"
#include "runtime/clock.h"
#include "runtime/lcm_bus.h"
#include "runtime/lcm_queue_shim.h"
#include "runtime/log_reader.h"
#include "runtime/messages.h"
#include "runtime/process.h"
#include "runtime/stop_signals.h"
#include "scenario/overrides.h"
#include "scenario/regular_file.h"

namespace shoal {
namespace {

struct Child {
  std::string name;  // "vehicle 3", "leader", "channel emulator", "lcm-logger"
  int id = kLoggerId;  // vehicle id, kEmulatorId, or kLoggerId
  pid_t pid = -1;
  bool running = false;
  int status = 0;  // raw waitpid status once exited
  bool stopped = false;   // stopped by a signal (SIGSTOP, SIGTSTP, ...), not continued yet
  bool reported = false;  // its fault is already among the problems
  bool stop_sent = false;  // shoal run asked it to stop (Launch::Stop)
  std::string output;     // its output file, <log>.d/<tag>.txt
  // What it was started with, to start it again (--restart on-failure).
  std::vector<std::string> argv;
  std::vector<std::string> env;  // NAME=VALUE on top of shoal run's (PlannedProcess::env)
  bool gets_key = true;          // lcm-logger records bytes as they are: it does not
  int nice_inc = 0;
  std::string tag;
  std::string checkpoint;  // its checkpoint file ("" without restarts or resets)
  int restarts = 0;
  // A vehicle's controller resets still to come (ticks, ascending): it stops itself after
  // the tick before each, and is restarted there (ClockedNode::StopBeforeResets).
  std::vector<std::int64_t> reset_ticks;
  // --hosts: a process started through its host's prefix reads the key from this pipe and
  // is stopped when it closes (remote_host.h); -1 for a child of shoal run itself.
  int stdin_fd = -1;
  bool signals_reach = true;  // its pid is the process's own (HostCheck::same_process)
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
  if (WIFSTOPPED(status)) {
    return std::string("stopped by signal ") + std::to_string(WSTOPSIG(status)) + " (" +
           strsignal(WSTOPSIG(status)) + ")";
  }
  return "stopped";
}

std::string Failure(const Child& c) {
  return c.name + " (pid " + std::to_string(c.pid) + ") " + Describe(c.status);
}

/// `envp`: the child's environment (the run's key is handed over there, not on the
/// command line, which every user of the host can read).
/// `stdin_fd`: its standard input (-1: /dev/null).
/// vfork, not fork: shoal run starts a process per vehicle, and fork copies the page tables
/// of shoal run (a large program) for each, then faults in a copy of every page the parent
/// writes before the child has exec'd (64 followers: 6,500 page faults, most of shoal run's
/// start-up CPU). The child therefore only makes system calls, on memory prepared before,
/// and, as posix_spawn does, runs with every signal blocked until its handlers (shoal
/// run's, which would write to shoal run's memory) are back to their defaults.
pid_t Spawn(const std::vector<std::string>& argv, int nice_inc, const std::string& output,
            char* const* envp, int stdin_fd = -1) {
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  const std::string cannot = "cannot exec " + argv[0] + ": ";
  const char* out = output.c_str();
  const pid_t parent = getpid();
  sigset_t all, before;
  sigfillset(&all);
  pthread_sigmask(SIG_SETMASK, &all, &before);
  const pid_t pid = vfork();
  if (pid != 0) {
    pthread_sigmask(SIG_SETMASK, &before, nullptr);
    return pid;
  }
  for (int sig = 1; sig < NSIG; ++sig) {
    struct sigaction sa {};
    if (sigaction(sig, nullptr, &sa) != 0 || sa.sa_handler == SIG_IGN ||
        sa.sa_handler == SIG_DFL) {
      continue;
    }
    sa.sa_handler = SIG_DFL;
    sa.sa_flags = 0;
    sigaction(sig, &sa, nullptr);
  }
  sigprocmask(SIG_SETMASK, &before, nullptr);
  // Child: its own process group (a terminal Ctrl-C reaches only shoal run, which shuts
  // the run down in order), dies with shoal run, output to a per-process file.
  setpgid(0, 0);
  prctl(PR_SET_PDEATHSIG, SIGKILL);
  if (getppid() != parent) _exit(127);
  if (nice_inc != 0) setpriority(PRIO_PROCESS, 0, nice_inc);
  const int fd = open(out, O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd >= 0) {
    dup2(fd, 1);
    dup2(fd, 2);
    close(fd);
  }
  const int devnull = stdin_fd >= 0 ? stdin_fd : open("/dev/null", O_RDONLY);
  if (devnull >= 0) dup2(devnull, 0);
  execve(args[0], args.data(), envp);
  const char* why = strerror(errno);
  if (write(2, cannot.data(), cannot.size()) >= 0 && write(2, why, std::strlen(why)) >= 0) {
    (void)!write(2, "\n", 1);
  }
  _exit(127);
}

/// The log must be writable before anything starts. An existing log is only checked: it
/// stays as it is until lcm-logger replaces it. It must be a regular file: lcm-logger
/// fails on a directory only once the run has started, waits on a FIFO until something
/// reads it, writes into a device (/dev/full), and the key and the process output would
/// be put beside it (/dev/full.key, /dev/full.d/).
bool CheckLogWritable(const std::string& log, std::string* error) {
  struct stat st {};
  if (stat(log.c_str(), &st) == 0) {
    if (!S_ISREG(st.st_mode)) {
      *error = log + ": cannot open log for writing: it is " + KindOf(st.st_mode) +
               ", not a regular file";
      return false;
    }
    if (access(log.c_str(), W_OK) == 0) return true;
  } else {
    const int fd = open(log.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0644);
    if (fd >= 0) {
      close(fd);
      unlink(log.c_str());
      return true;
    }
  }
  *error = log + ": cannot open log for writing (" + std::strerror(errno) + ")";
  return false;
}

/// Creates <log>.d/ and removes the output files a previous run left there, so that the
/// folder holds this run's processes only.
/// Makes `dir`, the output folder of the run that writes `log`, and locks it for the run
/// (*lock_fd, held until shoal run ends): a second run on the same log, a shoal run or a
/// printed script (which takes the same flock), would remove the log while it is written.
/// Then removes what an earlier run left there.
bool PrepareOutputDir(const std::string& dir, const std::string& log, int* lock_fd,
                      std::string* error) {
  if (mkdir(dir.c_str(), 0755) != 0 && errno != EEXIST) {
    *error = dir + ": cannot create the process output folder (" + std::strerror(errno) + ")";
    return false;
  }
  struct stat st {};
  if (stat(dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) {
    *error = dir + ": exists and is not a folder (shoal run keeps each process's output there)";
    return false;
  }
  const int fd = open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd >= 0 && flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int e = errno;
    close(fd);
    // A file system without locks (ENOLCK, EINVAL) only loses the guard.
    if (e == EWOULDBLOCK) {
      *error = "another run is writing " + log + " (it holds " + dir +
               "/); wait for it to end, or give another --out";
      return false;
    }
  } else if (fd >= 0) {
    *lock_fd = fd;
  }
  if (DIR* d = opendir(dir.c_str())) {
    while (const dirent* e = readdir(d)) {
      const std::string n = e->d_name;
      // Output (.txt) and checkpoints (.ckpt) of the run's processes, restarted ones too.
      auto ends = [&n](const std::string& e) {
        return n.size() > e.size() && n.compare(n.size() - e.size(), e.size(), e) == 0;
      };
      const bool process = n.rfind("vehicle", 0) == 0 || n.rfind("leader", 0) == 0 ||
                           n.rfind("emulator", 0) == 0 || n.rfind("logger", 0) == 0;
      const bool ours = (process && (ends(".txt") || ends(".ckpt"))) || n == "resources.csv";
      if (ours) unlink((dir + "/" + n).c_str());
    }
    closedir(d);
  }
  return true;
}

/// The folder that holds `path` ("." for a bare name).
std::string FolderOf(const std::string& path) {
  const std::size_t slash = path.rfind('/');
  return slash == std::string::npos ? "." : slash == 0 ? "/" : path.substr(0, slash);
}

/// Whether PrepareKey can replace `key_file`, checked before anything is removed or
/// written: a folder in its place cannot be removed, and removing the file or making a new
/// one writes the folder that holds it. Changes nothing.
bool CheckKeyFile(const LaunchOptions& opt, const std::string& key_file, std::string* error) {
  struct stat st {};
  const bool exists = lstat(key_file.c_str(), &st) == 0;
  const std::string cannot = opt.insecure ? ": cannot remove an earlier run's key file ("
                             : exists     ? ": cannot replace the key file ("
                                          : ": cannot create the key file (";
  if (exists && S_ISDIR(st.st_mode)) {
    *error = key_file + cannot + std::strerror(EISDIR) + ")";
    return false;
  }
  if ((exists || !opt.insecure) && access(FolderOf(key_file).c_str(), W_OK | X_OK) != 0) {
    *error = key_file + cannot + std::strerror(errno) + ")";
    return false;
  }
  return true;
}

/// The bus key of the run: a new one, written to <log>.key (mode 0600) so that the log can
/// be verified later; with --insecure none, and a key file an earlier run left there is
/// removed (it would make the new log's messages look forged).
bool PrepareKey(const LaunchOptions& opt, LaunchResult* r, std::string* error) {
  r->key_file = r->log + ".key";
  if (opt.insecure) {
    if (unlink(r->key_file.c_str()) != 0 && errno != ENOENT) {
      *error = r->key_file + ": cannot remove an earlier run's key file (" +
               std::strerror(errno) + ")";
      return false;
    }
    r->key_file.clear();
    return true;
  }
  r->key = bus_auth::NewKey();
  return bus_auth::WriteKeyFile(r->key_file, *r->key, error);
}

/// The environment of the run's processes: shoal run's, with SHOAL_BUS_KEY set to the
/// run's key (`key` null: without SHOAL_BUS_KEY).
std::vector<std::string> ChildEnvironment(const std::optional<bus_auth::Key>* key) {
  std::vector<std::string> env;
  const std::string name = std::string(bus_auth::kKeyEnv) + "=";
  for (char** e = environ; e != nullptr && *e != nullptr; ++e) {
    if (std::strncmp(*e, name.c_str(), name.size()) != 0) env.emplace_back(*e);
  }
  if (key != nullptr && key->has_value()) env.push_back(name + bus_auth::ToHex(**key));
  return env;
}

/// Follows the log as lcm-logger writes it, for the progress line: the newest tick and the
/// worst formation error, each follower's newest error against the leader's state at the
/// same time (the log interleaves ticks, so the leader's recent states are kept).
class ProgressTracker {
 public:
  ProgressTracker(const Scenario& s, const std::string& log,
                  const std::optional<bus_auth::Key>& key)
      : s_(s),
        tail_(log),
        recent_(2 * static_cast<std::size_t>(s.followers + 1)),
        follower_error_(s.followers + 1, 0.0) {
    if (key) auth_.emplace(*key);
  }
  /// Only the newest two ticks' worth of states written since the last call are verified
  /// and decoded: they are all the progress line shows, and verifying every state of a
  /// large lockstep run as the log grows cost this process as much CPU as the recorder.
  void Poll() {
    kept_ = 0;
    tail_.Poll([this](const std::string& ch, const void* d, int n) { Keep(ch, d, n); });
    const std::size_t k = std::min(kept_, recent_.size());
    for (std::size_t i = kept_ - k; i < kept_; ++i) {
      const Kept& e = recent_[i % recent_.size()];
      OnEvent(e.channel, e.bytes.data(), static_cast<int>(e.bytes.size()));
    }
  }
  double sim_time_s() const { return ToSeconds(last_tick_utime_); }
  bool any_state() const { return any_state_; }  // the log holds a state: the mission began
  double worst_error() const {
    return *std::max_element(follower_error_.begin(), follower_error_.end());
  }

 private:
  void OnEvent(const std::string& ch, const void* d, int n) {
    if (!channels::ParseStateId(ch)) return;
    if (auth_) n = auth_->Verify(ch, d, n);  // forged states move nothing
    vehicle_state_t m{};
    if (!Decode(d, n, &m) || m.vehicle_id < 0 || m.vehicle_id > s_.followers) return;
    const StateMsg st = FromLcm(m);
    last_tick_utime_ = std::max<std::int64_t>(last_tick_utime_, m.utime);
    any_state_ = true;
    if (m.vehicle_id == 0) {
      leader_states_[st.utime] = st;
      while (leader_states_.size() > 256) leader_states_.erase(leader_states_.begin());
      return;
    }
    const auto l = leader_states_.find(st.utime);
    if (l != leader_states_.end()) {
      follower_error_[m.vehicle_id] =
          ErrorsOf(st, s_.offsets_m[m.vehicle_id - 1], l->second).position_m;
    }
  }
  struct Kept {
    std::string channel;
    std::vector<unsigned char> bytes;
  };
  void Keep(const std::string& ch, const void* d, int n) {
    if (!channels::ParseStateId(ch)) return;
    Kept& e = recent_[kept_++ % recent_.size()];
    e.channel = ch;
    const auto* p = static_cast<const unsigned char*>(d);
    e.bytes.assign(p, p + (n > 0 && p != nullptr ? n : 0));
  }
  const Scenario& s_;
  LogTail tail_;
  std::optional<bus_auth::Authenticator> auth_;
  std::vector<Kept> recent_;  // a ring: the newest states of one Poll
  std::size_t kept_ = 0;      // states seen by this Poll
  std::int64_t last_tick_utime_ = 0;
  bool any_state_ = false;
  std::map<Micros, StateMsg> leader_states_;  // recent ones only
  std::vector<double> follower_error_;
};

/// The context switches of a process's threads that are alive, summed from
/// /proc/<pid>/task/<tid>/status (each thread's own counts: the process's status file
/// shows its main thread's only, and lcm-logger does its work in three threads).
void ReadContextSwitches(pid_t pid, long long* voluntary, long long* involuntary) {
  *voluntary = *involuntary = 0;
  const std::string dir = "/proc/" + std::to_string(pid) + "/task";
  DIR* d = opendir(dir.c_str());
  if (d == nullptr) return;
  while (const dirent* e = readdir(d)) {
    if (e->d_name[0] < '0' || e->d_name[0] > '9') continue;
    FILE* f = std::fopen((dir + "/" + e->d_name + "/status").c_str(), "r");
    if (f == nullptr) continue;  // the thread ended meanwhile
    char line[256];
    long long v = 0;
    while (std::fgets(line, sizeof(line), f) != nullptr) {
      if (std::sscanf(line, "voluntary_ctxt_switches: %lld", &v) == 1) *voluntary += v;
      if (std::sscanf(line, "nonvoluntary_ctxt_switches: %lld", &v) == 1) *involuntary += v;
    }
    std::fclose(f);
  }
  closedir(d);
}

/// One process's resource use, read from /proc: false if it is gone.
bool ReadProcessResources(pid_t pid, long long* rss_kib, double* cpu_s) {
  char path[64];
  std::snprintf(path, sizeof(path), "/proc/%d/stat", static_cast<int>(pid));
  char buf[1024];
  FILE* f = std::fopen(path, "r");
  if (f == nullptr) return false;
  const std::size_t n = std::fread(buf, 1, sizeof(buf) - 1, f);
  std::fclose(f);
  buf[n] = 0;
  // The command name (field 2) may hold spaces and parentheses: the fields after it start
  // after the last ')'. utime and stime are fields 14 and 15, in clock ticks.
  const char* p = std::strrchr(buf, ')');
  unsigned long long utime = 0, stime = 0;
  if (p == nullptr ||
      std::sscanf(p + 1, " %*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %llu %llu", &utime,
                  &stime) != 2) {
    return false;
  }
  std::snprintf(path, sizeof(path), "/proc/%d/statm", static_cast<int>(pid));
  f = std::fopen(path, "r");
  if (f == nullptr) return false;
  unsigned long long size = 0, resident = 0;
  const bool ok = std::fscanf(f, "%llu %llu", &size, &resident) == 2;
  std::fclose(f);
  if (!ok || resident == 0) return false;  // 0: exiting, its memory already released
  *rss_kib = static_cast<long long>(resident * static_cast<unsigned long long>(sysconf(_SC_PAGESIZE)) / 1024);
  // The process's CPU clock counts every thread's time, those that ended included, to the
  // nanosecond; /proc/<pid>/stat rounds down to clock ticks (10 ms), which is more than a
  // vehicle of a short lockstep run uses in all (a few ms): figures per tick taken from it
  // would be mostly rounding. The ticks remain for a kernel that refuses the clock.
  clockid_t clock = 0;
  timespec cpu{};
  if (clock_getcpuclockid(pid, &clock) == 0 && clock_gettime(clock, &cpu) == 0) {
    *cpu_s = static_cast<double>(cpu.tv_sec) + 1e-9 * static_cast<double>(cpu.tv_nsec);
  } else {
    *cpu_s = static_cast<double>(utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK));
  }
  return true;
}

/// <log>.d/resources.csv (docs/run.md): a row per process and sample. Read from /proc by
/// shoal run between its waitpid polls, so the supervised processes never wait for it.
/// Each sample is flushed: a run that is killed keeps what was measured up to then.
class ResourceLog {
 public:
  ResourceLog(const std::string& path, double interval_s) : interval_s_(interval_s) {
    if (interval_s_ > 0) f_ = std::fopen(path.c_str(), "w");
    if (f_ != nullptr) {
      std::fprintf(f_, "sim_time_s,wall_time_s,process,pid,rss_kib,cpu_s,voluntary_ctxsw,"
                       "involuntary_ctxsw\n");
    }
  }
  ~ResourceLog() {
    if (f_ != nullptr) std::fclose(f_);
  }
  ResourceLog(const ResourceLog&) = delete;
  ResourceLog& operator=(const ResourceLog&) = delete;
  bool open() const { return f_ != nullptr; }
  /// Whether mission time `sim_s` has reached the next multiple of the interval.
  bool Due(double sim_s) const { return f_ != nullptr && sim_s >= next_k_ * interval_s_; }
  /// Samples every running child. Multiples missed since the last sample are skipped (one
  /// row per process each time, never a burst of the same figures).
  void Sample(double sim_s, double wall_s, const std::vector<Child>& kids) {
    if (f_ == nullptr) return;
    for (const Child& c : kids) {
      long long rss = 0;
      double cpu = 0.0;
      if (!c.running || c.pid <= 0 || !ReadProcessResources(c.pid, &rss, &cpu)) continue;
      long long voluntary = 0, involuntary = 0;
      ReadContextSwitches(c.pid, &voluntary, &involuntary);
      std::fprintf(f_, "%.3f,%.3f,%s,%d,%lld,%.6f,%lld,%lld\n", sim_s, wall_s, c.name.c_str(),
                   static_cast<int>(c.pid), rss, cpu, voluntary, involuntary);
    }
    std::fflush(f_);
    next_k_ = std::max(next_k_ + 1, static_cast<long long>(std::floor(sim_s / interval_s_)) + 1);
  }

 private:
  double interval_s_;
  FILE* f_ = nullptr;
  long long next_k_ = 0;
};

/// One run: prepared (checks, nothing started), started, supervised, shut down.
// How often the supervisor polls a lockstep run (real time: every 50 ms).
constexpr std::chrono::milliseconds kLockstepPoll(10);

class Launch {
 public:
  Launch(const Scenario& s, const LaunchOptions& opt, LaunchResult* r)
      : s_(s), opt_(opt), r_(r), wall_clock_t0_(opt.wall_clock_t0) {}
  ~Launch() {
    for (Child& c : kids_) CloseStdin(c);
    if (output_lock_fd_ >= 0) close(output_lock_fd_);
  }
  Launch(const Launch&) = delete;
  Launch& operator=(const Launch&) = delete;
  /// Checks everything that can refuse the run and makes its plan; unless `for_print`,
  /// also makes sure multicast stays on the host (or, with --hosts, that each host can
  /// take part) and prepares the log, the output folder and the key. Nothing is started.
  bool Prepare(bool for_print, std::string* error);
  /// --hosts: the multicast groups each host that runs a process sends or joins on.
  std::map<std::string, std::vector<std::string>> GroupsByHost(const HostsFile& hosts,
                                                               const std::string& url) const;
  const LaunchPlan& plan() const { return plan_; }
  void StartAll();
  void Supervise(const LaunchCallbacks& cb);
  void Shutdown();
  /// Once every process has exited: what each dropped for failed authentication.
  void GatherRejections();
  /// Real time: tick 0 on CLOCK_MONOTONIC (once StartAll has set it).
  std::int64_t t0_ns() const { return t0_ns_; }
  /// The run's processes on a host with another kernel than shoal run's (--hosts).
  std::vector<int> ElsewhereIds();

 private:
  /// Mode, duration, size and executables.
  bool CheckOptions(std::string* error);
  bool ChooseUrls(bool ensure_multicast, std::string* error);
  /// The run's processes, in start order (plan_): every command shoal run starts.
  void BuildPlan();
  void PlanEmulator();
  void PlanNodes();
  /// Starts planned process p, with `values` in place of the plan's placeholders.
  void Start(const PlannedProcess& p, const std::map<std::string, std::string>& values);
  /// Starts child c's `argv` on its host (--hosts), with the run's key; -1 if it failed.
  pid_t SpawnChild(Child& c, const std::vector<std::string>& argv);
  /// The host that runs the process `id` (nullptr without --hosts).
  const Host* HostFor(int id) const;
  static void CloseStdin(Child& c);
  /// Whether the emulator can watch the logger's pid (--recorder-pid).
  bool RecorderVisible() const;
  /// Whether the logger's pid and /dev/shm are this process's (it runs on this host).
  bool LoggerVisible() const;
  /// Whether the logger counts what it handles in shared memory (SHOAL_LOGGER_PROGRESS=1).
  bool LoggerCounts() const;
  /// Whether the logger, on another host, says on its output once it has subscribed.
  bool LoggerSaysSubscribed() const;
  /// Whether the lockstep clock master reads the logger's count (a run with an uplink).
  bool ClockMasterReadsCount() const;
  /// `url`: where the process publishes (empty: the run's bus).
  std::vector<std::string> ProcessArgs(const std::string& exe,
                                       const std::vector<std::string>& more,
                                       const std::string& url = "") const;
  /// Waits (polling waitpid) up to `limit` for the children selected by `which` to exit.
  /// Returns true if all did.
  bool WaitFor(bool (*which)(const Child&), std::chrono::milliseconds limit);
  void Stop(bool logger, std::chrono::milliseconds grace);
  /// Until the logger has written every message it queued for its writer, or `limit`.
  void LoggerWritesAll(std::chrono::milliseconds limit);
  /// Once the logger was told to close the log: a problem if it ended otherwise.
  void CheckLoggerExit();
  /// Removes the name of the logger's count from /dev/shm, if it is still there.
  void RemoveLoggerCount();
  /// Until the logger has subscribed (its progress count's name exists, or on another
  /// host its output says so), or 30 s.
  void WaitForSubscription(pid_t logger_pid, const std::string& output);
  double WallSeconds(std::chrono::steady_clock::time_point wall0) const;
  /// When a fault is seen: mission time and wall time, as the report says it.
  std::string When();
  /// Records child c's fault (`what` happened to it, now) among the problems and tells
  /// cb. Returns true if it stops the run (it does unless opt_.keep_going lets a vehicle
  /// or the leader go), and then records it as the cause.
  bool Fault(Child& c, const std::string& what, const LaunchCallbacks& cb);
  /// Mission time now: real time on the clock from t0, lockstep the log's newest tick.
  double MissionSeconds();
  /// --restart on-failure: starts child c, which died (`what` happened to it), again in
  /// place (a vehicle or the leader resuming from its checkpoint). False if it may not be
  /// restarted (the logger, or past --max-restarts) or could not be.
  bool Restart(Child& c, const std::string& what, const LaunchCallbacks& cb);
  /// True if child c stopped itself before a controller reset (its checkpoint is of the
  /// tick before the next one).
  bool ResetStop(const Child& c) const;
  /// Kills child c, stopped before its controller reset, and starts it again from its
  /// checkpoint. Not counted against --max-restarts.
  bool ResetRestart(Child& c, const LaunchCallbacks& cb);
  /// Starts child c again from its checkpoint (the emulator without one), `what` being
  /// what happened to the process before it; false if it could not be started.
  bool Respawn(Child& c, const std::string& what, const LaunchCallbacks& cb);
  bool OnChildEvent(Child& c, int status, const LaunchCallbacks& cb);
  /// Samples the processes' resources into resources.csv when the mission has reached the
  /// next multiple of the interval (`end`: now, whatever the time). Lockstep reads its
  /// mission time from the log, at most every 200 ms of wall time.
  void SampleResources(bool end);

  const Scenario& s_;
  const LaunchOptions& opt_;
  LaunchResult* r_;
  std::vector<std::string> vehicle_urls_;  // per-vehicle groups; empty: one shared bus
  std::string uplink_url_;  // where the vehicles and the leader publish; empty: the run's bus
  std::string vehicle_exe_, leader_exe_, emulator_exe_;
  std::string logger_queue_shim_;  // runtime/lcm_queue_shim.c, preloaded into lcm-logger
  // The logger's count, mapped where the clock master does not read it (LoggerWritesAll).
  const ShoalLoggerProgress* logger_count_ = nullptr;
  std::vector<Child> kids_;
  LaunchPlan plan_;
  std::int64_t t0_ns_ = 0;  // real time: tick 0 on CLOCK_MONOTONIC
  /// Real time: the processes get tick 0 on the wall clock (--t0-unix-ns): asked for, or a
  /// host does not share shoal run's CLOCK_MONOTONIC (another kernel or time namespace).
  bool wall_clock_t0_ = false;
  Mode mode_ = Mode::kLockstep;  // opt_.mode, parsed by Prepare
  bool start_failed_ = false;    // a process could not be forked
  bool emulator_done_ = false;   // the channel emulator (the run's clock) ended normally
  std::unique_ptr<ProgressTracker> tracker_;  // the log as written so far
  std::chrono::steady_clock::time_point wall0_;  // when supervision started
  std::unique_ptr<ResourceLog> resources_;       // LaunchOptions::resource_interval_s
  std::chrono::steady_clock::time_point last_resource_poll_;
  std::map<std::string, HostCheck> host_checks_;  // --hosts: by host name
  int output_lock_fd_ = -1;  // the output folder, flocked for the run (PrepareOutputDir)
};

bool Launch::CheckOptions(std::string* error) {
  const std::optional<Mode> mode = ParseMode(opt_.mode);
  if (!mode) {
    *error = "--mode must be lockstep or realtime (got " + opt_.mode + ")";
    return false;
  }
  mode_ = *mode;
  if (!opt_.sched_fifo.empty() && opt_.sched_fifo != kSchedFifoAll &&
      opt_.sched_fifo != kSchedFifoEmulator) {
    *error = "--sched-fifo must be " + std::string(kSchedFifoAll) + " or " +
             kSchedFifoEmulator + " (got " + opt_.sched_fifo + ")";
    return false;
  }
  if (!opt_.sched_fifo.empty() && mode_ != Mode::kRealtime) {
    *error = "--sched-fifo is for real time; lockstep runs under SCHED_BATCH (add --mode "
             "realtime, or leave --sched-fifo out)";
    return false;
  }
  if (opt_.duration_s == 0 || (opt_.duration_s < 0 && opt_.duration_s != -1)) {
    *error = "--duration must be a positive number of seconds";
    return false;
  }
  if (opt_.duration_s > 0 && opt_.duration_s * 1e6 < static_cast<double>(s_.period_us())) {
    std::ostringstream period;
    period << s_.period_us() / 1e6;
    *error = "--duration must be at least one control period, " + period.str() + " s";
    return false;
  }
  if (const std::string ticks = s_.TickLimitRefusal(opt_.duration_s); !ticks.empty()) {
    *error = "--duration is too long: " + ticks;
    return false;
  }
  if (!opt_.allow_large) {
    *error = LargeRunRefusal(s_, opt_.duration_s,
                             mode_ == Mode::kRealtime ? RunPace::kRealtime : RunPace::kLockstep);
    if (!error->empty()) return false;
  }
  r_->mode = opt_.mode;
  r_->sched_fifo = SchedFifoAsked(mode_, opt_.sched_fifo, std::getenv("SHOAL_SCHED_FIFO"));
  r_->duration_s = opt_.duration_s > 0 ? opt_.duration_s : s_.duration_s;
  r_->log = opt_.out.empty() ? s_.name + ".lcmlog" : opt_.out;
  if (SameFile(r_->log, opt_.scenario)) {
    *error = r_->log + " is the scenario file: the log would overwrite it; give --out elsewhere";
    return false;
  }
  r_->process_output_dir = r_->log + ".d";
  vehicle_exe_ = FindExe("vehicle", "shoal_vehicle");
  leader_exe_ = FindExe("leader", "shoal_leader");
  emulator_exe_ = FindExe("channel_emulator", "shoal_channel_emulator");
  logger_queue_shim_ = FindExe("runtime", SHOAL_LCM_QUEUE_SHIM_FILE);
  if (vehicle_exe_.empty() || leader_exe_.empty() || emulator_exe_.empty()) {
    *error = "cannot find shoal_vehicle, shoal_leader or shoal_channel_emulator next to " +
             ExeDir();
    return false;
  }
  if (std::system("command -v lcm-logger >/dev/null 2>&1") != 0) {
    *error = "lcm-logger not found (Debian package liblcm-bin)";
    return false;
  }
  return true;
}

bool Launch::Prepare(bool for_print, std::string* error) {
  if (for_print && opt_.hosts) {
    *error = "--print-launch starts every process on this host: it does not take --hosts";
    return false;
  }
  // SCHED_FIFO is checked here, before anything is changed or started, rather than as each
  // process refuses at its start; with --hosts, on each host by CheckHosts' probe. A
  // printed script is run later, perhaps by another user: its processes check for
  // themselves.
  std::string why;
  if (!CheckOptions(error)) return false;
  if (!for_print && !opt_.hosts && !opt_.sched_fifo.empty() &&
      !SchedFifoPermitted(kEmulatorFifoPriority, &why)) {
    *error = "--sched-fifo: " + why;
    return false;
  }
  if (!ChooseUrls(!for_print, error)) return false;
  BuildPlan();
  if (for_print) return true;
  // Everything that can refuse the run is checked before anything is written: a refused
  // run leaves an earlier log, its key and its process output as they were. PrepareOutputDir
  // refuses before it removes anything.
  return CheckLogWritable(r_->log, error) && CheckKeyFile(opt_, r_->log + ".key", error) &&
         PrepareOutputDir(r_->process_output_dir, r_->log, &output_lock_fd_, error) &&
         PrepareKey(opt_, r_, error);
}

std::map<std::string, std::vector<std::string>> Launch::GroupsByHost(const HostsFile& hosts,
                                                                     const std::string& url) const {
  // Every host sends or joins on the shared bus's group and the uplink's; a vehicle's host
  // (the leader's too) on that vehicle's own; the emulator's, which sends to each vehicle,
  // on every vehicle's.
  std::vector<std::string> groups = {GroupOfUrl(url)};
  if (!uplink_url_.empty()) groups.push_back(GroupOfUrl(uplink_url_));
  std::map<std::string, std::vector<std::string>> by_host;
  for (const Host* h : hosts.UsedHosts(s_.followers)) by_host[h->name] = groups;
  const std::string& emulator = hosts.HostOf(HostRole::kEmulator).name;
  for (std::size_t id = 0; id < vehicle_urls_.size(); ++id) {
    const std::string g = GroupOfUrl(vehicle_urls_[id]);
    const std::string& host = hosts.HostOfVehicle(static_cast<int>(id)).name;
    by_host[host].push_back(g);
    if (host != emulator) by_host[emulator].push_back(g);
  }
  return by_host;
}

bool Launch::ChooseUrls(bool ensure_multicast, std::string* error) {
  const HostsFile* hosts = opt_.hosts ? &*opt_.hosts : nullptr;
  if (hosts && !hosts->bus_url.empty() && !opt_.lcm_url.empty()) {
    *error = "give the LCM URL either with --lcm-url or as [bus] url in " + hosts->path;
    return false;
  }
  // --lcm-url is used as given: a [bus] ttl beside it would be silently ignored.
  if (hosts && hosts->ttl_line > 0 && !opt_.lcm_url.empty()) {
    *error = hosts->path + ":" + std::to_string(hosts->ttl_line) +
             ": bus.ttl: cannot be given with --lcm-url; give the TTL in the URL (?ttl=1)";
    return false;
  }
  std::string url = hosts && !hosts->bus_url.empty() ? hosts->bus_url : opt_.lcm_url;
  int port = 0;
  // Over several hosts multicast must leave by each host's network, not loopback: each
  // host's route is checked instead (CheckHosts, after the URLs are chosen).
  if (!hosts && ensure_multicast && (url.empty() || url.rfind("udpm://", 0) == 0) &&
      !EnsureLoopbackMulticast(error)) {
    return false;
  }
  if (url.empty()) {
    port = RandomPrivatePort(s_.followers);
    url = PrivateLcmUrl(port) + "&recv_buf_size=4194304";
    if (hosts) url = UrlWithTtl(url, hosts->ttl);
  }
  r_->lcm_url = url;
  // Each vehicle receives on its own group unless asked otherwise: on one shared group
  // every vehicle's socket would receive -- and wake up for -- every message of the run.
  if (opt_.per_vehicle_urls && opt_.shared_url) {
    *error = "--per-vehicle-urls and --shared-url exclude each other";
    return false;
  }
  if (opt_.per_vehicle_urls || (port != 0 && !opt_.shared_url)) {
    if (port == 0) {
      *error = "--per-vehicle-urls needs the default private URL";
      return false;
    }
    vehicle_urls_ = PerVehicleLcmUrls(port, s_.followers);
    for (std::string& u : vehicle_urls_) u = hosts ? UrlWithTtl(u, hosts->ttl) : u;
    // The processes' messages reach the recorder through the channel emulator, a few
    // datagrams a window or period instead of one per process (ChannelEmulatorApp::
    // SetUplink). Not with restarts: what is in flight to an emulator that dies would
    // never reach the log.
    if (!logger_queue_shim_.empty() && !opt_.restart_on_failure) {
      uplink_url_ = UplinkLcmUrl(port, s_.followers);
      if (hosts) uplink_url_ = UrlWithTtl(uplink_url_, hosts->ttl);
    }
  }
  if (!hosts) return true;
  const std::map<std::string, std::vector<std::string>> groups_by_host =
      GroupsByHost(*hosts, url);
  const std::string ttl_fix = !opt_.lcm_url.empty() ? "?ttl=1 in --lcm-url"
                              : !hosts->bus_url.empty() ? "?ttl=1 in [bus] url in " + hosts->path
                                                        : "[bus] ttl = 1 in " + hosts->path;
  if (GroupOfUrl(url).empty()) {
    *error = "--hosts needs an udpm:// LCM URL (got " + url + ")";
    return false;
  }
  // Where processes are given --sched-fifo, at the highest priority each host's take (the
  // logger never is).
  std::map<std::string, int> fifo_hosts;
  if (opt_.sched_fifo == kSchedFifoAll) {
    fifo_hosts[hosts->HostOf(HostRole::kLeader).name] = kNodeFifoPriority;
    for (int id = 1; id <= s_.followers; ++id) {
      fifo_hosts[hosts->HostOfVehicle(id).name] = kNodeFifoPriority;
    }
  }
  if (!opt_.sched_fifo.empty()) {
    fifo_hosts[hosts->HostOf(HostRole::kEmulator).name] = kEmulatorFifoPriority;
  }
  if (!CheckHosts(*hosts, s_.followers, groups_by_host, TtlOfUrl(url), ttl_fix, fifo_hosts,
                  &host_checks_, error)) {
    return false;
  }
  for (const auto& [name, check] : host_checks_) wall_clock_t0_ |= !check.same_clock;
  return true;
}

void Launch::Start(const PlannedProcess& p, const std::map<std::string, std::string>& values) {
  Child c;
  c.name = p.name;
  c.id = p.id;
  c.output = r_->process_output_dir + "/" + p.tag + ".txt";
  c.argv = p.prefix;
  for (const std::string& a : p.argv) {
    const auto v = values.find(a);
    c.argv.push_back(v == values.end() ? a : v->second);
  }
  c.env = p.env;
  c.gets_key = p.gets_key;
  c.nice_inc = p.nice_inc;
  c.tag = p.tag;
  c.checkpoint = p.checkpoint;
  c.reset_ticks = p.reset_ticks;
  c.pid = SpawnChild(c, c.argv);
  c.running = c.pid > 0;
  if (c.pid < 0) {  // no process to supervise: the run cannot go on
    r_->problems.push_back("cannot start " + p.name + " (fork: " + std::strerror(errno) + ")");
    start_failed_ = true;
  }
  kids_.push_back(c);
}

bool Launch::RecorderVisible() const {
  // The emulator reads the logger's threads from /proc/<pid>: the pid must be the
  // logger's own, in the emulator's pid namespace.
  if (!opt_.hosts) return true;
  const auto logger = host_checks_.find(HostFor(kLoggerId)->name);
  const auto emulator = host_checks_.find(HostFor(kEmulatorId)->name);
  return logger != host_checks_.end() && emulator != host_checks_.end() &&
         logger->second.same_process && emulator->second.same_process;
}

bool Launch::LoggerVisible() const {
  if (!opt_.hosts) return true;
  const auto logger = host_checks_.find(HostFor(kLoggerId)->name);
  return logger != host_checks_.end() && logger->second.same_process;
}

bool Launch::ClockMasterReadsCount() const {
  return mode_ == Mode::kLockstep && !uplink_url_.empty() && RecorderVisible();
}

bool Launch::LoggerCounts() const {
  if (plan_.processes.empty()) return false;
  const std::vector<std::string>& env = plan_.processes.front().env;
  return std::find(env.begin(), env.end(), "SHOAL_LOGGER_PROGRESS=1") != env.end();
}

bool Launch::LoggerSaysSubscribed() const {
  if (plan_.processes.empty()) return false;
  const std::vector<std::string>& env = plan_.processes.front().env;
  return std::find(env.begin(), env.end(), SHOAL_LOGGER_SAY_SUBSCRIBED_ENV "=1") != env.end();
}

std::vector<int> Launch::ElsewhereIds() {
  std::vector<int> ids;
  for (const PlannedProcess& p : plan_.processes) {
    const Host* h = HostFor(p.id);
    if (p.id != kLoggerId && h != nullptr && !host_checks_[h->name].same_clock) {
      ids.push_back(p.id);
    }
  }
  return ids;
}

const Host* Launch::HostFor(int id) const {
  if (!opt_.hosts) return nullptr;
  if (id == kLoggerId) return &opt_.hosts->HostOf(HostRole::kLogger);
  if (id == kEmulatorId) return &opt_.hosts->HostOf(HostRole::kEmulator);
  return &opt_.hosts->HostOfVehicle(id);
}

void Launch::CloseStdin(Child& c) {
  if (c.stdin_fd >= 0) close(c.stdin_fd);
  c.stdin_fd = -1;
}

pid_t Launch::SpawnChild(Child& c, const std::vector<std::string>& argv) {
  const bool with_key = c.gets_key && r_->key.has_value();
  const Host* host = HostFor(c.id);
  const bool prefixed = host != nullptr && !host->prefix.empty();
  std::vector<std::string> env = ChildEnvironment(with_key && !prefixed ? &r_->key : nullptr);
  if (!prefixed) {
    for (const std::string& e : c.env) {  // replaces a variable of the same name
      const std::string name = e.substr(0, e.find('=') + 1);
      env.erase(std::remove_if(env.begin(), env.end(),
                               [&](const std::string& x) { return x.rfind(name, 0) == 0; }),
                env.end());
      env.push_back(e);
    }
  }
  std::vector<char*> envp;
  for (std::string& e : env) envp.push_back(e.data());
  envp.push_back(nullptr);
  if (!prefixed) return Spawn(argv, c.nice_inc, c.output, envp.data());
  // Through the host's prefix the key goes to the process's standard input, which stays
  // open while it runs (remote_host.h): never on a command line, which ssh and
  // ip netns exec would pass on. Its own variables go there with env(1), which execs in
  // place.
  CloseStdin(c);
  c.signals_reach = host_checks_[host->name].same_process;
  int read_fd = -1;
  std::string error;
  if (!KeyPipe(with_key ? bus_auth::ToHex(*r_->key) : "", &read_fd, &c.stdin_fd, &error)) {
    return -1;
  }
  std::vector<std::string> command;
  if (!c.env.empty()) command.push_back("/usr/bin/env");
  command.insert(command.end(), c.env.begin(), c.env.end());
  command.insert(command.end(), argv.begin(), argv.end());
  char cwd[4096];
  const std::string dir = getcwd(cwd, sizeof(cwd)) != nullptr ? cwd : ".";
  const pid_t pid =
      Spawn(HostCommand(*host, command, dir), c.nice_inc, c.output, envp.data(), read_fd);
  close(read_fd);
  return pid;
}

std::vector<std::string> Launch::ProcessArgs(const std::string& exe,
                                             const std::vector<std::string>& more,
                                             const std::string& url) const {
  std::vector<std::string> a = {exe, "--scenario", opt_.scenario,
                                "--lcm-url", url.empty() ? r_->lcm_url : url,
                                "--mode", opt_.mode,
                                wall_clock_t0_ ? "--t0-unix-ns" : "--t0-ns", kT0Arg,
                                "--duration", ExactNumber(r_->duration_s)};
  if (opt_.insecure) a.push_back("--insecure");
  // One argument each: a value is never taken for an option of its own.
  for (const std::string& set : opt_.set) a.push_back("--set=" + set);
  a.insert(a.end(), more.begin(), more.end());
  return a;
}

/// An earlier run's log at the same path is not the new logger's: it has started once the
/// file is new or truncated (lcm-logger -f opens it for writing from scratch).
class LogFileBefore {
 public:
  explicit LogFileBefore(const std::string& path)
      : path_(path), existed_(stat(path.c_str(), &st_) == 0) {}
  bool OpenedAnew() const {
    struct stat now {};
    if (stat(path_.c_str(), &now) != 0) return false;
    return !existed_ || now.st_ino != st_.st_ino || now.st_size < st_.st_size ||
           now.st_mtim.tv_sec != st_.st_mtim.tv_sec || now.st_mtim.tv_nsec != st_.st_mtim.tv_nsec;
  }

 private:
  std::string path_;
  struct stat st_ {};
  bool existed_;
};

void Launch::BuildPlan() {
  plan_ = LaunchPlan();
  plan_.mode = mode_;
  plan_.lcm_url = r_->lcm_url;
  plan_.log = r_->log;
  plan_.output_dir = r_->process_output_dir;
  plan_.insecure = opt_.insecure;
  plan_.keep_going = opt_.keep_going;
  // The logger first. lcm-logger's subscription queue holds 30 messages and drops beyond
  // that (LCM's default; lcm-logger has no option for it): the logger must not wait long
  // for the CPU while the run saturates it. As root it runs at nice -10 against the run's
  // +5 (CFS weight 9548 against 335), else at 0. It records the run's channels only: LCM
  // queues only what some subscription takes, so datagrams on other channels (another
  // program on the same port, a flood) never take a place in that queue (docs/run.md). Not SCHED_FIFO: a real-time logger
  // preempts the run at every message, and with SHOAL_CHANNEL batched it loses no fewer
  // states (docs/benchmarks.md, lockstep: 600 s runs, 36-39x against 50-56x).
  PlannedProcess logger;
  logger.name = "lcm-logger";
  logger.id = kLoggerId;
  logger.tag = "logger";
  logger.argv = {"/usr/bin/lcm-logger", "--lcm-url=" + r_->lcm_url,
                 std::string("--channel=") + channels::kAllPattern, "-f", "-q", "--", r_->log};
  logger.nice_inc = geteuid() == 0 ? -10 : 0;
  logger.gets_key = false;
  if (!logger_queue_shim_.empty()) {  // its queue: SHOAL_LOGGER_QUEUE_CAPACITY, not 30
    const char* before = std::getenv("LD_PRELOAD");
    logger.env = {"LD_PRELOAD=" + logger_queue_shim_ +
                  (before != nullptr && *before != '\0' ? std::string(":") + before : "")};
    // It counts what it has handled, for the lockstep clock master on a run with an uplink,
    // which is then the only sender on its bus (channel_emulator/recorder_gate.h:
    // RecorderProgress). On every run whose logger is on this host the count's name says
    // when the logger has subscribed, before which nothing may start (StartAll).
    if (LoggerVisible()) {
      logger.env.push_back("SHOAL_LOGGER_PROGRESS=1");
    } else {
      logger.env.push_back(SHOAL_LOGGER_SAY_SUBSCRIBED_ENV "=1");
    }
    // Lockstep: its wake-ups do not preempt the clock master finishing a window.
    if (mode_ == Mode::kLockstep) logger.env.push_back("SHOAL_LOGGER_BATCH=1");
  }
  plan_.processes.push_back(logger);
  PlanEmulator();
  PlanNodes();
}

void Launch::PlanEmulator() {
  std::vector<std::string> more = {"--max-lookahead", std::to_string(opt_.max_lookahead)};
  if (mode_ == Mode::kLockstep && RecorderVisible()) {
    more.push_back("--recorder-pid");  // back-pressure: the log stays complete
    more.push_back(kLoggerPidArg);
    more.push_back("--recorder-queue");  // what a window may send it
    more.push_back(std::to_string(logger_queue_shim_.empty() ? SHOAL_LCM_DEFAULT_QUEUE_CAPACITY
                                                             : SHOAL_LOGGER_QUEUE_CAPACITY));
  }
  if (!vehicle_urls_.empty()) {
    std::string list;
    for (std::size_t i = 0; i < vehicle_urls_.size(); ++i) {
      list += (i ? "," : "") + vehicle_urls_[i];
    }
    more.push_back("--vehicle-urls");
    more.push_back(list);
  }
  if (!uplink_url_.empty()) more.insert(more.end(), {"--uplink-url", uplink_url_});
  if (!opt_.sched_fifo.empty()) more.push_back("--sched-fifo");
  PlannedProcess e;
  e.name = "channel emulator";
  e.id = kEmulatorId;
  e.tag = "emulator";
  e.argv = ProcessArgs(emulator_exe_, more);
  // The clock master is every window's critical path (it waits for the last state, then
  // releases the next window): in lockstep it runs at nice 0, above the vehicles' +5. In
  // real time its releases are the delays the run is about: as root it runs at nice -10,
  // so that it gets a CPU before the loops that wake at the same instant.
  e.nice_inc = mode_ == Mode::kRealtime && geteuid() == 0 ? -10 : 0;
  plan_.processes.push_back(e);
}

void Launch::PlanNodes() {
  // Lockstep saturates the CPU: its processes run at a lower priority than the logger,
  // under SCHED_BATCH (they set it themselves: a woken process does not preempt the one
  // sending it a burst). Real time is paced by the clock.
  const int run_nice = mode_ == Mode::kLockstep ? 5 : 0;
  auto rx = [&](int id) {
    return vehicle_urls_.empty() ? std::vector<std::string>{}
                                 : std::vector<std::string>{"--rx-url", vehicle_urls_[id]};
  };
  for (int id = 0; id <= s_.followers; ++id) {
    PlannedProcess p;
    p.name = id == 0 ? "leader" : "vehicle " + std::to_string(id);
    p.id = id;
    p.tag = id == 0 ? "leader" : "vehicle" + std::to_string(id);
    std::vector<std::string> more;
    if (id > 0) more = {"--id", std::to_string(id)};
    const std::vector<std::string> r = rx(id);
    more.insert(more.end(), r.begin(), r.end());
    if (id > 0) p.reset_ticks = ClockedNode::ResetTicks(s_, id, s_.final_tick(r_->duration_s));
    // With restarts each writes a checkpoint after every state it publishes, to resume
    // from; so does a vehicle whose controller the scenario resets.
    if (opt_.restart_on_failure || !p.reset_ticks.empty()) {
      p.checkpoint = r_->process_output_dir + "/" + p.tag + ".ckpt";
      more.insert(more.end(), {"--checkpoint", p.checkpoint});
    }
    if (!p.reset_ticks.empty()) more.push_back("--stop-before-resets");
    // A lockstep window's states as one datagram: lcm-logger records them one by one
    // only with the shim, which unpacks such bundles (runtime/lcm_queue_shim.c).
    if (mode_ == Mode::kLockstep && !logger_queue_shim_.empty()) {
      more.push_back("--bundle-publishes");
    }
    const Micros phase_us = ClockedNode::StaggerPhaseUs(s_, id);
    if (mode_ == Mode::kRealtime && opt_.stagger && phase_us > 0) {
      more.insert(more.end(), {"--phase-us", std::to_string(phase_us)});
    }
    if (opt_.sched_fifo == kSchedFifoAll) more.push_back("--sched-fifo");
    p.argv = ProcessArgs(id == 0 ? leader_exe_ : vehicle_exe_, more, uplink_url_);
    p.nice_inc = run_nice;
    plan_.processes.push_back(p);
  }
}

/// The last `max_bytes` of a file ("" if it cannot be read): a process's exit lines.
std::string ReadTail(const std::string& path, long max_bytes) {
  std::string text;
  if (FILE* f = std::fopen(path.c_str(), "rb")) {
    if (std::fseek(f, 0, SEEK_END) == 0) {
      const long size = std::ftell(f);
      std::fseek(f, std::max(0L, size - max_bytes), SEEK_SET);
    }
    char buf[4096];
    std::size_t n = 0;
    while ((n = std::fread(buf, 1, sizeof(buf), f)) > 0) text.append(buf, n);
    std::fclose(f);
  }
  return text;
}

/// False once `pid` has exited (a zombie until shoal run reaps it, which kill(pid, 0) does
/// not tell).
bool Running(pid_t pid) {
  char path[64];
  std::snprintf(path, sizeof(path), "/proc/%ld/stat", static_cast<long>(pid));
  std::FILE* f = std::fopen(path, "r");
  if (f == nullptr) return false;
  char buf[512] = {};
  const std::size_t n = std::fread(buf, 1, sizeof(buf) - 1, f);
  std::fclose(f);
  const char* paren = std::strrchr(buf, ')');  // the name may hold spaces and parentheses
  return n > 0 && paren != nullptr && paren[1] == ' ' && paren[2] != 'Z' && paren[2] != 'X';
}

void Launch::WaitForSubscription(pid_t logger_pid, const std::string& output) {
  char name[64];
  std::snprintf(name, sizeof(name), "/dev/shm" SHOAL_LOGGER_PROGRESS_NAME,
                static_cast<long>(logger_pid));
  // On this host its count's name; on another, the line its output carries over the login.
  const bool counts = LoggerCounts();
  const auto subscribed = [&] {
    return counts ? access(name, F_OK) == 0
                  : ReadTail(output, 1 << 16).find(SHOAL_LOGGER_SUBSCRIBED_LINE) !=
                        std::string::npos;
  };
  constexpr int kLimitS = 30;
  const auto start = std::chrono::steady_clock::now();
  while (!subscribed()) {
    // A logger that exited is reported by the supervision that follows, with its status.
    if (!Running(logger_pid) || StopSignals::Requested()) return;
    if (std::chrono::steady_clock::now() - start > std::chrono::seconds(kLimitS)) {
      std::fprintf(stderr,
                   "shoal run: warning: lcm-logger had not subscribed %d s after it started: "
                   "what the run sends before it does is not in the log\n", kLimitS);
      return;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  // The clock master of a lockstep run with an uplink takes the name over and removes it;
  // on other runs shoal run reads the count at the end, and the name would outlive the run.
  if (counts && !ClockMasterReadsCount()) {
    const int fd = open(name, O_RDONLY);
    struct stat st {};
    // Its size is checked: the logger makes the name before it sizes the object, and a
    // mapping past the end of a smaller one would fault when read.
    if (fd >= 0 && fstat(fd, &st) == 0 &&
        st.st_size >= static_cast<off_t>(sizeof(ShoalLoggerProgress))) {
      void* m = mmap(nullptr, sizeof(ShoalLoggerProgress), PROT_READ, MAP_SHARED, fd, 0);
      if (m != MAP_FAILED) logger_count_ = static_cast<const ShoalLoggerProgress*>(m);
    }
    if (fd >= 0) close(fd);
    unlink(name);
  }
}

void Launch::StartAll() {
  const LogFileBefore before(r_->log);
  Start(plan_.processes.front(), {});  // lcm-logger
  const pid_t logger_pid = kids_.back().running ? kids_.back().pid : 0;
  for (int i = 0; i < 100 && !before.OpenedAnew(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  // lcm-logger creates its log before it subscribes: what the run sent it in between would
  // never reach it: in lockstep the processes' ready statuses, for which the clock master
  // would then wait; in real time the emulator's first status, the one with the scenario's
  // text. Counting, it makes its count's name once subscribed (runtime/lcm_queue_shim.c).
  if (logger_pid > 0 && (LoggerCounts() || LoggerSaysSubscribed())) {
    WaitForSubscription(logger_pid, kids_.back().output);
  }
  // Stopped while it waited: nothing else is started (nor, behind ssh, logged in to), and
  // the run, which never began, began now (its wall time is 0, not the machine's uptime).
  if (StopSignals::Requested()) {
    t0_ns_ = MonotonicNs();
    return;
  }
  // Real time: a start margin, longer by the logins the starts wait for (--hosts). On the
  // wall clock, it is converted to the monotonic clock as each process does (process.h).
  std::map<std::string, int> placed;  // processes by host
  for (std::size_t i = 1; i < plan_.processes.size(); ++i) {
    if (const Host* h = HostFor(plan_.processes[i].id)) ++placed[h->name];
  }
  double logins_s = 0;
  for (const auto& [name, n] : placed) logins_s += LoginSeconds(host_checks_[name], n);
  const std::int64_t margin_ns = 4000000000LL + static_cast<std::int64_t>(logins_s * 1e9);
  std::int64_t t0_arg = 0;
  if (wall_clock_t0_) {
    t0_arg = RealtimeNs() + margin_ns;
    t0_ns_ = MonotonicFromUnixNs(t0_arg);
  } else {
    t0_ns_ = t0_arg = MonotonicNs() + margin_ns;
  }
  // No logger (fork failed: the run stops at once): the emulator does not wait for one.
  const std::map<std::string, std::string> values = {
      {kT0Arg, std::to_string(t0_arg)}, {kLoggerPidArg, std::to_string(logger_pid)}};
  LoginPacer pacer;  // sshd refuses logins beyond its MaxStartups (remote_host.h)
  for (std::size_t i = 1; i < plan_.processes.size(); ++i) {
    const Host* h = HostFor(plan_.processes[i].id);
    const bool login = h != nullptr && !h->prefix.empty() && !host_checks_[h->name].same_process;
    if (login) pacer.WaitForRoom(h->name, [] { return StopSignals::Requested(); });
    Start(plan_.processes[i], values);
    if (login && kids_.back().running) {
      pacer.Started(h->name, kids_.back().pid, kids_.back().stdin_fd);
    }
  }
}

double Launch::WallSeconds(std::chrono::steady_clock::time_point wall0) const {
  // Real time: from the common start time t0 (the start margin before it is not the run's).
  if (mode_ == Mode::kRealtime) return (MonotonicNs() - t0_ns_) * 1e-9;
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
}

double Launch::MissionSeconds() {
  // Mission time: real time runs on the clock from t0; lockstep's is the newest tick the
  // log holds (the run waits for a process that is gone or stopped, so its log ends there).
  if (mode_ == Mode::kRealtime) return (MonotonicNs() - t0_ns_) * 1e-9;
  tracker_->Poll();
  return tracker_->sim_time_s();
}

std::string Launch::When() {
  const double mission_s = MissionSeconds();
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0_).count();
  // The wall clock too, to match the fault with other records (the system journal, the
  // processes' output).
  timespec now {};
  clock_gettime(CLOCK_REALTIME, &now);
  tm local {};
  localtime_r(&now.tv_sec, &local);
  char clock_text[32];
  std::strftime(clock_text, sizeof(clock_text), "%H:%M:%S", &local);
  char text[192];
  const int ms = static_cast<int>(now.tv_nsec / 1000000);
  if (mission_s < 0) {
    std::snprintf(text, sizeof(text),
                  "%.2f s before the mission started (%s.%03d wall clock, %.2f s into the run)",
                  -mission_s, clock_text, ms, wall_s);
  } else {
    std::snprintf(text, sizeof(text),
                  "t = %.2f s of the mission (%s.%03d wall clock, %.2f s into the run)",
                  mission_s, clock_text, ms, wall_s);
  }
  return text;
}

bool Launch::Fault(Child& c, const std::string& what, const LaunchCallbacks& cb) {
  c.reported = true;
  const bool stops = !(opt_.keep_going && c.id != kEmulatorId && c.id != kLoggerId);
  std::string text = c.name + " (pid " + std::to_string(c.pid) + ") " + what + " at " + When();
  if (stops) {
    r_->stopped_by = text;
    text += ": the run was stopped there";
  }
  r_->problems.push_back(text);
  if (cb.problem) cb.problem(text, stops);
  return stops;
}

bool Launch::Restart(Child& c, const std::string& what, const LaunchCallbacks& cb) {
  if (!opt_.restart_on_failure || c.id == kLoggerId) return false;
  if (c.restarts >= opt_.max_restarts) {
    // Fault() then stops the run, and says why there was no restart.
    r_->problems.push_back(c.name + " was restarted " + std::to_string(c.restarts) +
                           " time(s) already (--max-restarts " +
                           std::to_string(opt_.max_restarts) + "): not restarted again");
    return false;
  }
  ++c.restarts;
  return Respawn(c, what, cb);
}

bool Launch::ResetStop(const Child& c) const {
  if (c.reset_ticks.empty() || c.checkpoint.empty()) return false;
  CheckpointRecord rec;
  std::string error;
  return ReadCheckpoint(c.checkpoint, c.id, &rec, &error) &&
         rec.tick + 1 == c.reset_ticks.front();
}

bool Launch::ResetRestart(Child& c, const LaunchCallbacks& cb) {
  // It stopped itself after the tick before its controller reset: the process is killed
  // and another takes over from its checkpoint, as a real controller would restart.
  const std::int64_t tick = c.reset_ticks.front();
  c.reset_ticks.erase(c.reset_ticks.begin());
  if (kill(-c.pid, SIGKILL) != 0) kill(c.pid, SIGKILL);  // its group, as SignalGroup
  int status = 0;
  waitpid(c.pid, &status, 0);
  char what[160];
  std::snprintf(what, sizeof(what),
                "was killed for its controller reset at t = %.3f s (the scenario's "
                "controller_reset event)",
                ToSeconds(tick * s_.period_us()));
  return Respawn(c, what, cb);
}

bool Launch::Respawn(Child& c, const std::string& what, const LaunchCallbacks& cb) {
  ProcessRestart rec;
  rec.process = c.name;
  rec.pid = c.pid;
  rec.reason = what;
  rec.mission_s = MissionSeconds();
  const std::string when = When();
  std::vector<std::string> argv = c.argv;
  // The emulator has no checkpoint: the processes tell a new one where the run is.
  if (c.id != kEmulatorId) argv.insert(argv.end(), {"--resume", c.checkpoint});
  argv.insert(argv.end(), {"--restart-note", c.name + " restarted: the process before it (pid " +
                                                 std::to_string(c.pid) + ") " + what + " at " +
                                                 when});
  // Its own output file: the one of the process that died keeps that process's last words.
  c.output = r_->process_output_dir + "/" + c.tag + ".restart" +
             std::to_string(r_->restarts.size() + 1) + ".txt";
  const pid_t pid = SpawnChild(c, argv);
  if (pid < 0) {
    r_->problems.push_back("cannot restart " + c.name + " (fork: " + std::strerror(errno) + ")");
    return false;
  }
  c.pid = pid;
  c.running = true;
  c.status = 0;
  c.stopped = false;
  rec.new_pid = pid;
  r_->restarts.push_back(rec);
  if (cb.restarted) {
    cb.restarted(rec.process + " (pid " + std::to_string(rec.pid) + ") " + what + " at " + when +
                 ": restarted as pid " + std::to_string(pid));
  }
  return true;
}

bool EndsWith(const std::string& text, const std::string& tail) {
  return text.size() >= tail.size() &&
         text.compare(text.size() - tail.size(), tail.size(), tail) == 0;
}

/// Whether `line` is one that a run's process writes at its end however it ended, after
/// any reason it stopped for: the count of what failed authentication that each writes
/// last, "<name>: N message(s) failed authentication (dropped)", or "<name>: bus not
/// authenticated (--insecure)" (bus_auth::ExitNote, in runtime/clocked_node.cc and
/// channel_emulator/channel_emulator_app.cc); and the channel emulator's lockstep figures
/// ("waited for the recorder ...", "lockstep, N windows of ...").
bool IsRoutineEndLine(const std::string& line) {
  std::int64_t count = 0;
  if (EndsWith(line, " message(s) failed authentication (dropped)") &&
      bus_auth::ParseExitNote(line, &count)) {
    return true;
  }
  if (EndsWith(line, std::string(": ") + bus_auth::kInsecureNote)) return true;
  const std::string emulator = "shoal_channel_emulator: ";
  if (line.rfind(emulator + "waited for the recorder", 0) == 0) return true;
  const std::string windows = emulator + "lockstep, ";
  if (line.rfind(windows, 0) != 0) return false;
  std::size_t i = windows.size();
  while (i < line.size() && line[i] >= '0' && line[i] <= '9') ++i;
  return i > windows.size() && line.compare(i, 12, " windows of ") == 0;
}

/// A process's last words: the last line of its output file that is not a routine end
/// line (IsRoutineEndLine), which would hide why it failed ("" if none), at most 300
/// bytes.
std::string LastWordsOf(const std::string& path) {
  const std::string text = ReadTail(path, 4096);
  std::size_t end = text.size();
  while (end > 0) {
    const std::size_t nl = text.rfind('\n', end - 1);
    const std::size_t begin = nl == std::string::npos ? 0 : nl + 1;
    std::string line = text.substr(begin, end - begin);
    end = nl == std::string::npos ? 0 : nl;
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
    if (line.empty() || IsRoutineEndLine(line)) continue;
    if (line.size() > 300) line = line.substr(0, 300) + "...";
    return line;
  }
  return "";
}

/// The disk under the log: lcm-logger exits when a write fails (status 1, "No space left
/// on device" on a full disk), and its own output file may then be empty for the same
/// reason; the free space says it plainly.
std::string LoggerExitNote(const std::string& log, const std::string& logger_output) {
  std::string note;
  std::string last, line;
  if (FILE* f = std::fopen(logger_output.c_str(), "r")) {
    char buf[512];
    while (std::fgets(buf, sizeof(buf), f)) {
      line = buf;
      while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.pop_back();
      if (!line.empty()) last = line;
    }
    std::fclose(f);
  }
  if (!last.empty()) note += "; its output ends with \"" + last + "\"";
  // Full: less room than lcm-logger's write buffers need. Root may also use the blocks a
  // file system reserves for it (f_bfree), and lcm-logger runs as whoever runs shoal run.
  struct statvfs fs {};
  const std::size_t slash = log.rfind('/');
  const std::string dir = slash == std::string::npos ? "." : log.substr(0, slash + 1);
  if (statvfs(dir.c_str(), &fs) == 0) {
    const double free_b =
        static_cast<double>(geteuid() == 0 ? fs.f_bfree : fs.f_bavail) * fs.f_frsize;
    const double size_b = static_cast<double>(fs.f_blocks) * fs.f_frsize;
    if (free_b < 1024.0 * 1024.0) {
      char sizes[96];
      std::snprintf(sizes, sizeof(sizes), " is full (%.0f of %.0f kB free)", free_b / 1024,
                    size_b / 1024);
      note += "; the disk holding " + log + sizes;
    }
  }
  return note;
}

/// One waitpid report of child c: exited, killed, stopped or continued. Returns false
/// when the run must stop.
bool Launch::OnChildEvent(Child& c, int status, const LaunchCallbacks& cb) {
  if (WIFSTOPPED(status) && ResetStop(c)) return ResetRestart(c, cb);
  if (WIFSTOPPED(status)) {
    // A stopped process holds the run up (lockstep) or misses its periods (real time):
    // whatever follows, the run is not the one asked for.
    c.stopped = true;
    return !Fault(c, "was " + Describe(status), cb);
  }
  if (WIFCONTINUED(status)) {
    c.stopped = false;
    return true;
  }
  c.running = false;
  c.status = status;
  const bool clean = WIFEXITED(status) && WEXITSTATUS(status) == 0;
  if (c.id == kEmulatorId && clean) {
    emulator_done_ = true;
  } else if (c.id == kLoggerId) {
    // Nothing is recorded any more: going on would only make a run without a log. The
    // run stops now; the report says where the log ends.
    r_->logger_exited_early = Describe(status);
    r_->logger_exited_at = When();
    r_->logger_exit_note = LoggerExitNote(r_->log, r_->process_output_dir + "/logger.txt");
    // The report's problem says it as "lcm-logger exited early (...)" (run_report.cc); the
    // cause of the stop names the process as for any other.
    r_->stopped_by = Failure(c) + " at " + r_->logger_exited_at;
    c.reported = true;
    return false;
  } else if (!clean) {
    // Its last words say why it failed (an error message, or glibc's or the C++
    // runtime's reason for an abort); a process killed from outside has none.
    const int sig = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
    const bool own = WIFEXITED(status) || sig == SIGABRT || sig == SIGSEGV || sig == SIGBUS ||
                     sig == SIGFPE || sig == SIGILL;
    const std::string last = own ? LastWordsOf(c.output) : "";
    const std::string what =
        Describe(status) + (last.empty() ? "" : " (its output ends with \"" + last + "\")");
    if (Restart(c, what, cb)) return true;
    return !Fault(c, what, cb);
  }
  return true;
}

void Launch::Supervise(const LaunchCallbacks& cb) {
  // Process deaths and stops from waitpid; progress from the log as lcm-logger writes it
  // (not from the bus: a listener on the run's group would receive, and wake up for, every
  // message of the run), read only to show progress or to say when a fault happened.
  tracker_ = std::make_unique<ProgressTracker>(s_, r_->log, r_->key);
  wall0_ = std::chrono::steady_clock::now();
  auto last_show = wall0_;
  resources_ = std::make_unique<ResourceLog>(r_->process_output_dir + "/resources.csv",
                                             opt_.resource_interval_s);
  if (resources_->open()) r_->resources_file = r_->process_output_dir + "/resources.csv";
  bool go_on = !start_failed_;
  while (go_on && !emulator_done_ && !StopSignals::Requested()) {
    const long poll_ns = mode_ == Mode::kLockstep ? kLockstepPoll.count() * 1000000L : 50000000L;
    const timespec poll = {0, poll_ns};
    nanosleep(&poll, nullptr);  // returns early when a child exits or stops (SIGCHLD)
    for (Child& c : kids_) {
      int status = 0;
      if (!c.running || waitpid(c.pid, &status, WNOHANG | WUNTRACED | WCONTINUED) != c.pid) {
        continue;
      }
      if (!OnChildEvent(c, status, cb)) go_on = false;
    }
    if (go_on) SampleResources(false);
    const auto now = std::chrono::steady_clock::now();
    if (go_on && cb.progress && now - last_show > std::chrono::milliseconds(500)) {
      last_show = now;
      tracker_->Poll();
      LaunchProgress p;
      for (const Child& c : kids_) p.alive += c.running && c.id != kLoggerId;
      p.processes = s_.followers + 2;
      p.sim_time_s = tracker_->sim_time_s();
      p.duration_s = r_->duration_s;
      p.realtime_factor = p.sim_time_s / std::max(1e-9, WallSeconds(wall0_));
      p.worst_position_error_m = tracker_->worst_error();
      cb.progress(p);
    }
  }
  SampleResources(true);  // the processes still running at the end, before they stop
  r_->wall_time_s = std::max(0.0, WallSeconds(wall0_));
}

void Launch::SampleResources(bool end) {
  if (!resources_ || !resources_->open()) return;
  double sim_s = 0.0;
  if (mode_ == Mode::kRealtime) {
    sim_s = (MonotonicNs() - t0_ns_) * 1e-9;
  } else {
    const auto now = std::chrono::steady_clock::now();
    // Every supervisor poll (10 ms in lockstep): a run at 1000x real time covers 10 s of
    // mission in that time, so a 30 s --resource-interval still gets every sample it is due
    // (at 50 ms, a 5-follower run at 330x on a fast host skipped one sample in ten).
    if (!end && now - last_resource_poll_ < kLockstepPoll) return;
    last_resource_poll_ = now;
    tracker_->Poll();
    if (!tracker_->any_state()) return;
    // The log on disk lags lcm-logger's buffers; an emulator that ended normally ran the
    // final tick.
    sim_s = end && emulator_done_ ? r_->duration_s : tracker_->sim_time_s();
  }
  if (end || resources_->Due(sim_s)) resources_->Sample(sim_s, WallSeconds(wall0_), kids_);
}

bool Launch::WaitFor(bool (*which)(const Child&), std::chrono::milliseconds limit) {
  const auto t = std::chrono::steady_clock::now();
  for (;;) {
    bool any = false;
    for (Child& c : kids_) {
      if (!c.running || !which(c)) continue;
      if (waitpid(c.pid, &c.status, WNOHANG) == c.pid) {
        c.running = false;
      } else {
        any = true;
      }
    }
    if (!any) return true;
    if (std::chrono::steady_clock::now() - t > limit) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
}

bool IsLogger(const Child& c) { return c.id == kLoggerId; }
bool IsRunProcess(const Child& c) { return c.id != kLoggerId; }

/// Signals a child's process group (each child leads its own), or the child alone while
/// it has not made its group yet.
void SignalGroup(pid_t pid, int signal) {
  if (kill(-pid, signal) != 0) kill(pid, signal);
}

/// SIGTERM to the run's processes (SIGINT to the logger, which then flushes and closes
/// the log), SIGCONT after it so that a stopped one gets it too, SIGKILL to the process
/// group of whoever has not stopped after `grace`. No wait is unbounded: a process that
/// outlives SIGKILL (stuck in the kernel) is reported, not waited for.
void Launch::Stop(bool logger, std::chrono::milliseconds grace) {
  for (Child& c : kids_) {
    if (!c.running || IsLogger(c) != logger) continue;
    // On another host (through ssh) the pid is the ssh client's: the end of its standard
    // input stops the process there, which then ends as it would on SIGTERM.
    if (!c.signals_reach) {
      CloseStdin(c);
      c.stop_sent = true;
      continue;
    }
    kill(c.pid, logger ? SIGINT : SIGTERM);
    if (c.stopped) kill(c.pid, SIGCONT);
    c.stop_sent = true;
  }
  if (WaitFor(logger ? IsLogger : IsRunProcess, grace)) return;
  for (Child& c : kids_) {
    if (!c.running || IsLogger(c) != logger) continue;
    SignalGroup(c.pid, SIGKILL);
    c.reported = true;
    r_->problems.push_back(c.name + " did not stop within " +
                           std::to_string(grace.count()) + " ms and was killed");
  }
  if (WaitFor(logger ? IsLogger : IsRunProcess, std::chrono::seconds(2))) return;
  for (Child& c : kids_) {
    if (!c.running || IsLogger(c) != logger) continue;
    c.running = false;
    c.reported = true;
    r_->problems.push_back(c.name + " (pid " + std::to_string(c.pid) +
                           ") did not exit 2 s after SIGKILL");
  }
}

void Launch::Shutdown() {
  // Normal end: give the vehicles a moment to finish their last tick on their own. Stopped
  // by a fault: at once, with shorter graces, so that shoal run has exited within 2 s of
  // the fault (docs/reliability.md; they exit within about 0.1 s when they can). The
  // logger's is the longer one: killed, it would lose what it has not written yet. A stop
  // signal hurries the shutdown as well; the processes that had ended by then are reaped
  // first, so that their statuses are known.
  const bool fault = !r_->logger_exited_early.empty() || !r_->stopped_by.empty() ||
                     start_failed_;
  const bool stopped_early = fault || StopSignals::Requested();
  using std::chrono::milliseconds;
  WaitFor(IsRunProcess, stopped_early ? milliseconds(0) : milliseconds(2000));
  // The run's processes first, the logger last so that it records everything they
  // published; it drains its socket in between.
  Stop(false, milliseconds(fault ? 700 : 2000));
  std::this_thread::sleep_for(milliseconds(fault ? 100 : 200));
  // After a fault shoal run exits within 2 s of it (the logger may be the fault, stopped).
  LoggerWritesAll(milliseconds(fault ? 0 : 5000));
  Stop(true, milliseconds(fault ? 1000 : 2000));
  CheckLoggerExit();
  RemoveLoggerCount();
  // Once the channel emulator has run the last tick the run is complete: a stop signal
  // after that only hurried its shutdown, and does not make it an interrupted run.
  r_->interrupted = StopSignals::Requested() && !emulator_done_;
  // Stopped by shoal run (a fault, a stop signal, or the logger gone): the others' statuses
  // say nothing. After a hurried end, those of the processes it had to stop say nothing.
  if (fault || r_->interrupted) return;
  const bool hurried = stopped_early;
  for (const Child& c : kids_) {
    if (IsLogger(c) || c.reported || (hurried && c.stop_sent) ||
        (WIFEXITED(c.status) && WEXITSTATUS(c.status) == 0)) {
      continue;
    }
    const std::string msg = Failure(c);
    if (std::find(r_->problems.begin(), r_->problems.end(), msg) == r_->problems.end()) {
      r_->problems.push_back(msg);
    }
  }
}

void Launch::LoggerWritesAll(std::chrono::milliseconds limit) {
  // lcm-logger's writer, stopped by SIGINT, drops what it has not written: with a backlog
  // (a large swarm, a loaded machine) the end of the run. With an uplink the clock master
  // waits for it before its last status (ChannelEmulatorApp: DrainRecorder).
  if (logger_count_ == nullptr) return;
  pid_t logger = 0;
  for (const Child& c : kids_) logger = IsLogger(c) && c.running ? c.pid : logger;
  const auto load = [](const std::uint64_t& v) { return __atomic_load_n(&v, __ATOMIC_ACQUIRE); };
  const auto start = std::chrono::steady_clock::now();
  while (logger > 0 && Running(logger) &&
         load(logger_count_->magic) == SHOAL_LOGGER_PROGRESS_MAGIC &&
         load(logger_count_->written) < load(logger_count_->queued) &&
         std::chrono::steady_clock::now() - start < limit) {
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  munmap(const_cast<ShoalLoggerProgress*>(logger_count_), sizeof(ShoalLoggerProgress));
  logger_count_ = nullptr;
}

void Launch::CheckLoggerExit() {
  // lcm-logger closes the log and exits 0 on the SIGINT it was sent (or dies of it, sent
  // before it could catch it); any other end, at the end of a run too, and before it was
  // asked to stop as well (reaped while the others were waited for), may have left
  // messages it had received unwritten.
  for (Child& c : kids_) {
    if (!IsLogger(c) || c.reported || c.running || c.pid <= 0) continue;
    const bool closed = (WIFEXITED(c.status) && WEXITSTATUS(c.status) == 0) ||
                        (WIFSIGNALED(c.status) && WTERMSIG(c.status) == SIGINT);
    if (closed) continue;
    c.reported = true;
    r_->problems.push_back(Failure(c) + " when the run ended" +
                           LoggerExitNote(r_->log, c.output) +
                           ": the log may lack the run's last messages");
  }
}

void Launch::RemoveLoggerCount() {
  // The name is removed by whoever reads the count: in lockstep the clock master once it
  // has mapped it (channel_emulator/recorder_gate.cc), in real time WaitForSubscription.
  // A run stopped before the clock master did so (Ctrl-C at its start, an emulator that
  // failed at its start) would leave it in /dev/shm. Removing it again fails harmlessly.
  if (!LoggerCounts() || !LoggerVisible()) return;
  for (const Child& c : kids_) {
    if (!IsLogger(c) || c.pid <= 0) continue;
    char name[64];
    std::snprintf(name, sizeof(name), SHOAL_LOGGER_PROGRESS_NAME, static_cast<long>(c.pid));
    shm_unlink(name);
  }
}

void Launch::GatherRejections() {
  if (opt_.insecure) return;
  for (const Child& c : kids_) {
    if (IsLogger(c) || c.pid <= 0) continue;
    std::int64_t n = -1;
    if (!bus_auth::ParseExitNote(ReadTail(c.output, 1 << 16), &n)) n = -1;
    r_->unauthenticated_by_process[c.name] = n;
  }
}

/// Unless --deep-idle: the 0 us CPU latency request, in both modes, and in real time, where
/// no cpuidle driver acts on it, threads that keep every CPU polling
/// (launcher/idle_poller.h): a tick waits for a wake-up, and from a halted virtual CPU that
/// came milliseconds late. Not in lockstep, where they made Example 2 a quarter slower
/// (docs/benchmarks.md, "Idle CPUs kept polling").
void KeepCpusPolling(const LaunchOptions& opt, bool realtime,
                     std::unique_ptr<CpuLatencyRequest>* latency, IdlePoller* poller,
                     LaunchResult* result) {
  result->cpuidle_driver = CpuidleDriver();
  if (opt.deep_idle) {
    result->cpu_latency_note = "no CPU latency request, CPUs may halt when idle (--deep-idle)";
    return;
  }
  *latency = std::make_unique<CpuLatencyRequest>();
  result->cpu_latency_request = (*latency)->held();
  if (LatencyRequestPolls(result->cpuidle_driver, CpuidleState0())) {
    result->cpu_latency_note =
        result->cpu_latency_request
            ? "CPU latency request 0 us held: idle CPUs poll (cpuidle driver " +
                  result->cpuidle_driver + ")"
            : (*latency)->note();
    return;
  }
  const std::string request = result->cpu_latency_request ? "CPU latency request 0 us held"
                                                          : (*latency)->note();
  if (!realtime) {
    result->cpu_latency_note = request + "; no cpuidle driver acts on it: idle CPUs halt";
    return;
  }
  const std::string quota = CpuQuota();
  if (!quota.empty()) {
    result->cpu_latency_note = request + "; no cpuidle driver acts on it, and " + quota +
                               " limits this group's CPU time, which threads keeping the "
                               "CPUs polling would spend: idle CPUs halt";
    return;
  }
  result->idle_poll_threads = poller->Start();
  result->cpu_latency_note =
      request + "; no cpuidle driver acts on it, so " +
      (result->idle_poll_threads > 0
           ? std::to_string(result->idle_poll_threads) +
                 " threads at SCHED_IDLE keep the CPUs polling"
           : std::string("idle CPUs halt (no thread could be put at SCHED_IDLE)"));
}

}  // namespace

std::string SchedFifoAsked(Mode mode, const std::string& option, const char* env) {
  if (mode != Mode::kRealtime) return "none";
  const bool env_all = env != nullptr && std::strcmp(env, kSchedFifoEmulator) != 0;
  if (option == kSchedFifoAll || env_all) return kSchedFifoAll;
  if (option == kSchedFifoEmulator || env != nullptr) return kSchedFifoEmulator;
  return "none";
}

bool LaunchRun(const Scenario& s, const LaunchOptions& opt, const LaunchCallbacks& callbacks,
               LaunchResult* result, std::string* error) {
  *result = LaunchResult();
  Launch launch(s, opt, result);
  if (!launch.Prepare(/*for_print=*/false, error)) return false;
  const StopSignals signals({/*hangup=*/true, /*wake_on_child=*/true});
  // Held until every child has stopped.
  std::unique_ptr<CpuLatencyRequest> latency;
  IdlePoller poller;
  const bool realtime = launch.plan().mode == Mode::kRealtime;
  KeepCpusPolling(opt, realtime, &latency, &poller, result);
  launch.StartAll();
  // Real time: whether the machine itself stalled, for the timing verdict to tell it apart.
  MachineWitness witness;
  const std::string refusal = realtime ? WitnessRefusal(!opt.sched_fifo.empty()) : "";
  if (realtime) result->t0_monotonic_ns = launch.t0_ns();
  if (realtime && refusal.empty()) witness.Start(launch.t0_ns());
  launch.Supervise(callbacks);
  result->machine = witness.Stop();
  if (!refusal.empty()) result->machine.note = refusal;
  if (realtime) result->unwatched_ids = launch.ElsewhereIds();
  launch.Shutdown();
  launch.GatherRejections();
  result->idle_poll_cpu_s = poller.Stop();
  return true;
}

bool PlanLaunch(const Scenario& s, const LaunchOptions& opt, LaunchPlan* plan,
                std::string* error) {
  if (opt.restart_on_failure) {
    *error = "--print-launch: a launch script does not restart processes; print it without "
             "--restart on-failure";
    return false;
  }
  LaunchOptions wall = opt;
  wall.wall_clock_t0 = true;  // hosts can share it; one host loses nothing by it
  LaunchResult result;
  Launch launch(s, wall, &result);
  if (!launch.Prepare(/*for_print=*/true, error)) return false;
  for (const PlannedProcess& p : launch.plan().processes) {
    if (p.reset_ticks.empty()) continue;
    *error = "--print-launch: the scenario resets the controller of " + p.name +
             ", which shoal run does by restarting that process; a launch script cannot";
    return false;
  }
  *plan = launch.plan();
  return true;
}

}  // namespace shoal
