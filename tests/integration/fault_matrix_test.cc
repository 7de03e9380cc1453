// Faults of a run itself, as users meet them: `shoal run` started as a user does (the
// built binary, a private LCM URL with ttl=0), then one of its processes killed
// (SIGKILL) or stopped (SIGSTOP for 3 s, then SIGCONT) mid-run, in lockstep and in real
// time; a full disk under --out; a read-only --out folder. Each time shoal run must say
// which process and when, exit non-zero within 2 s, leave no process behind, and leave a
// log that shoal analyze reads (docs/reliability.md).
//
// The cases of one mode run in parallel (each on its own port and log): the matrix takes
// about as long as its slowest case, not as the sum of them.
#include <dirent.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/mount.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "runtime/log_reader.h"
#include "tests/integration/test_util.h"

namespace shoal {
namespace {

using shoal::testing::ParseJson;
using shoal::testing::ReadFile;
using shoal::testing::CmdLine;
using shoal::testing::ParentOf;
using shoal::testing::ProcessState;
using shoal::testing::RunShoal;
using shoal::testing::SourcePath;
using shoal::testing::StartShoal;
using shoal::testing::TmpPath;
using Clock = std::chrono::steady_clock;

const std::string kExample2 = SourcePath("scenarios/paper_example2.toml");

// The limit of the requirement: shoal run has exited within 2 s of the fault.
constexpr double kReactionLimitS = 2.0;

double Since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

std::vector<pid_t> AllPids() {
  std::vector<pid_t> pids;
  DIR* d = opendir("/proc");
  if (!d) return pids;
  while (const dirent* e = readdir(d)) {
    const int pid = std::atoi(e->d_name);
    if (pid > 0) pids.push_back(pid);
  }
  closedir(d);
  return pids;
}

// The children of shoal run `run`: their pids and command lines.
std::vector<std::pair<pid_t, std::string>> ChildrenOf(pid_t run) {
  std::vector<std::pair<pid_t, std::string>> kids;
  for (pid_t pid : AllPids()) {
    if (ParentOf(pid) == run) kids.push_back({pid, CmdLine(pid)});
  }
  return kids;
}

// Processes whose command line holds `text` (the run's unique log path or LCM port).
std::vector<pid_t> ProcessesWith(const std::string& text) {
  std::vector<pid_t> found;
  for (pid_t pid : AllPids()) {
    if (pid != getpid() && CmdLine(pid).find(text) != std::string::npos) found.push_back(pid);
  }
  return found;
}

// Processes with a file open under `dir` (each of a run's processes has its output file
// open in <log>.d/, lcm-logger the log too).
std::vector<pid_t> ProcessesUsing(const std::string& dir) {
  std::vector<pid_t> found;
  for (pid_t pid : AllPids()) {
    const std::string fds = "/proc/" + std::to_string(pid) + "/fd";
    DIR* d = opendir(fds.c_str());
    if (!d) continue;
    while (const dirent* e = readdir(d)) {
      char target[4096];
      const ssize_t n = readlink((fds + "/" + e->d_name).c_str(), target, sizeof(target) - 1);
      if (n > 0 && std::string(target, n).rfind(dir + "/", 0) == 0) {
        found.push_back(pid);
        break;
      }
    }
    closedir(d);
  }
  return found;
}

// Vehicle states in the log so far (complete events only).
int StatesInLog(const std::string& log) {
  LogTail tail(log);
  int states = 0;
  tail.Poll([&](const std::string& ch, const void*, int) {
    states += ch.rfind("SHOAL_STATE_", 0) == 0;
  });
  return states;
}

enum class Fault { kKill, kStop };

struct Case {
  std::string kind;     // "vehicle", "leader", "channel emulator", "lcm-logger"
  std::string mode;     // "lockstep" or "realtime"
  Fault fault = Fault::kKill;
  bool keep_going = false;
  // Filled in by RunCase:
  std::string name, log, out, failure;  // failure: why the case could not be run
  int status = -1;
  double reaction_s = -1;  // from the fault to shoal run's exit
  std::set<pid_t> run_pids;
  std::string port_text;  // ":<port>" of the run's URL, from lcm-logger's command line
};

// The child of the run that is `kind`, from the children's command lines.
pid_t VictimOf(const std::vector<std::pair<pid_t, std::string>>& kids, const std::string& kind) {
  const std::string exe = kind == "vehicle"            ? "shoal_vehicle"
                          : kind == "leader"           ? "shoal_leader"
                          : kind == "channel emulator" ? "shoal_channel_emulator"
                                                       : "lcm-logger";
  for (const auto& [pid, cmd] : kids) {
    if (cmd.find(exe) == std::string::npos) continue;
    if (kind == "vehicle" && cmd.find("--id 2 ") == std::string::npos) continue;
    return pid;
  }
  return -1;
}

// Waits for shoal run (pid) until `limit` after `from`; true if it exited (status set).
bool WaitUntil(pid_t pid, Clock::time_point from, double limit_s, int* status, double* at_s) {
  while (Since(from) < limit_s) {
    int raw = 0;
    if (waitpid(pid, &raw, WNOHANG) == pid) {
      *at_s = Since(from);
      *status = WIFEXITED(raw) ? WEXITSTATUS(raw) : 256 + WTERMSIG(raw);
      return true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return false;
}

// Starts the run, waits until its processes are up and the log holds half a second of
// states, applies the fault to the case's process and waits for shoal run's exit.
void RunCase(Case* c) {
  c->log = TmpPath(c->name + ".lcmlog");
  c->out = TmpPath(c->name + ".out");
  // Lockstep: long enough that only a fault ends it. Real time: 20 s, or 8 s when the
  // run must go on past a stopped vehicle.
  const std::string duration = c->mode == "lockstep" ? "100000" : c->keep_going ? "8" : "20";
  // An earlier run's log would make this one look started before it is.
  std::remove(c->log.c_str());
  const pid_t run = StartShoal("run " + kExample2 + " --mode " + c->mode + " --duration " +
                                   duration + " --out " + c->log + " --quiet" +
                                   (c->keep_going ? " --keep-going" : ""),
                               c->out);
  // Started: all 8 children have their programs (a child between fork and exec still has
  // shoal run's command line) and the log holds half a second of states.
  const auto t_start = Clock::now();
  std::vector<std::pair<pid_t, std::string>> kids;
  pid_t logger = -1, victim = -1;
  const std::string url_key = "239.255.76.67:";
  std::size_t at = std::string::npos;
  while (Since(t_start) < 30 && (kids.size() < 8 || victim <= 0 || at == std::string::npos ||
                                 StatesInLog(c->log) < 6 * 25)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    kids = ChildrenOf(run);
    logger = VictimOf(kids, "lcm-logger");
    victim = VictimOf(kids, c->kind);
    at = logger > 0 ? CmdLine(logger).find(url_key) : std::string::npos;
  }
  for (const auto& k : kids) c->run_pids.insert(k.first);
  if (at != std::string::npos) c->port_text = ":" + CmdLine(logger).substr(at + url_key.size(), 5);
  if (kids.size() < 8 || victim <= 0 || c->port_text.empty()) {
    int raw = 0;
    const bool gone = waitpid(run, &raw, WNOHANG) == run;
    c->failure = "the run did not start within 30 s: " + std::to_string(kids.size()) +
                 " processes, " + std::to_string(StatesInLog(c->log)) + " states in the log" +
                 (gone ? ", shoal run exited (raw status " + std::to_string(raw) + ")" : "");
    for (const auto& [pid, cmd] : kids) c->failure += "\n  " + std::to_string(pid) + ": " + cmd;
    if (!gone) {
      kill(run, SIGKILL);
      waitpid(run, nullptr, 0);
    }
    return;
  }
  kill(victim, c->fault == Fault::kKill ? SIGKILL : SIGSTOP);
  const auto t_fault = Clock::now();
  double at_s = -1;
  bool exited = false;
  if (c->fault == Fault::kStop) {
    exited = WaitUntil(run, t_fault, 3.0, &c->status, &at_s);
    kill(victim, SIGCONT);  // may be gone already: shoal run stopped the run
  }
  if (!exited) exited = WaitUntil(run, t_fault, 40.0, &c->status, &at_s);
  if (!exited) {
    c->failure = "shoal run did not exit within 40 s of the fault";
    kill(run, SIGKILL);
    waitpid(run, nullptr, 0);
    return;
  }
  c->reaction_s = at_s;
}

std::string CaseName(const Case& c) {
  std::string kind = c.kind;
  for (char& ch : kind) ch = ch == ' ' || ch == '-' ? '_' : ch;
  return "fault_" + std::string(c.fault == Fault::kKill ? "kill_" : "stop_") + kind + "_" +
         c.mode + (c.keep_going ? "_keep_going" : "");
}

void RunInParallel(std::vector<Case>* cases) {
  std::vector<std::thread> threads;
  for (Case& c : *cases) {
    c.name = CaseName(c);
    threads.emplace_back(RunCase, &c);
  }
  for (std::thread& t : threads) t.join();
}

// No process of the run is left: neither one of the pids seen as its children nor any
// process with its port or log in the command line.
void ExpectNothingLeft(const Case& c) {
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  for (pid_t pid : c.run_pids) {
    EXPECT_NE(access(("/proc/" + std::to_string(pid)).c_str(), F_OK), 0)
        << c.name << ": process " << pid << " of the run is left: " << CmdLine(pid);
  }
  EXPECT_TRUE(ProcessesWith(c.port_text + "?").empty()) << c.name << ": left behind";
  EXPECT_TRUE(ProcessesWith(c.log).empty()) << c.name << ": left behind";
  EXPECT_TRUE(ProcessesUsing(c.log + ".d").empty()) << c.name << ": left behind";
}

// The log up to the fault loads with shoal analyze: exit 0 (a damaged or truncated log
// is analysed up to the damage, with a warning; docs/analyze.md), and it holds states.
void ExpectAnalysable(const Case& c) {
  const auto a = RunShoal("analyze " + c.log + " --json", c.name + "_analyze");
  EXPECT_EQ(a.status, 0) << c.name << ": " << a.out << a.err;
  const auto j = ParseJson(a.out);
  EXPECT_GT(j.value("log_states", 0), 0) << c.name << ": " << a.out;
}

// The common checks: exit 1 within 2 s of the fault, the report names the process, what
// happened to it and when, nothing is left, the log is analysable.
void ExpectStoppedRun(const Case& c, const std::string& what) {
  SCOPED_TRACE(c.name);
  ASSERT_TRUE(c.failure.empty()) << c.failure << "\n" << ReadFile(c.out);
  const std::string report = ReadFile(c.out);
  std::printf("[ measured ] %-40s exit %d %.3f s after the fault\n", c.name.c_str(), c.status,
              c.reaction_s);
  EXPECT_EQ(c.status, 1) << report;
  EXPECT_LT(c.reaction_s, kReactionLimitS) << report;
  const std::string named =
      c.kind == "vehicle"      ? "vehicle 2 (pid "
      : c.kind != "lcm-logger" ? c.kind + " (pid "
      : c.fault == Fault::kKill ? "lcm-logger exited early (" + what
                                : "lcm-logger (pid ";
  const std::size_t at = report.find(named);
  ASSERT_NE(at, std::string::npos) << "the report does not name " << named << "\n" << report;
  EXPECT_NE(report.find(what, at), std::string::npos) << report;
  // When: the mission time and the wall time, on the same line.
  const std::string line = report.substr(at, report.find('\n', at) - at);
  EXPECT_NE(line.find("of the mission ("), std::string::npos) << line;
  EXPECT_NE(line.find(" wall clock, "), std::string::npos) << line;
  EXPECT_NE(line.find(" s into the run)"), std::string::npos) << line;
  ExpectNothingLeft(c);
  ExpectAnalysable(c);
}

std::vector<Case> Matrix(const std::string& mode, Fault fault) {
  std::vector<Case> cases;
  for (const std::string kind : {"vehicle", "leader", "channel emulator", "lcm-logger"}) {
    Case c;
    c.kind = kind;
    c.mode = mode;
    c.fault = fault;
    cases.push_back(c);
  }
  return cases;
}

// SIGKILL of each kind of process, in real time (all four at once) and in lockstep.
TEST(FaultMatrix, KillingAnyProcessStopsTheRunWithinTwoSeconds) {
  for (const std::string mode : {"realtime", "lockstep"}) {
    std::vector<Case> cases = Matrix(mode, Fault::kKill);
    RunInParallel(&cases);
    for (const Case& c : cases) ExpectStoppedRun(c, "killed by signal 9");
  }
}

// SIGSTOP of each kind of process for 3 s: a stopped process holds a lockstep run up
// and misses its periods in real time. shoal run sees the stop (waitpid), stops the run,
// says which process was stopped and when, and exits 1 within 2 s of the stop. With
// --keep-going a stopped vehicle does not stop the run, which fails all the same.
TEST(FaultMatrix, StoppingAnyProcessFailsTheRunAndNamesIt) {
  for (const std::string mode : {"realtime", "lockstep"}) {
    std::vector<Case> cases = Matrix(mode, Fault::kStop);
    if (mode == "realtime") {
      Case c;
      c.kind = "vehicle";
      c.mode = mode;
      c.fault = Fault::kStop;
      c.keep_going = true;
      cases.push_back(c);
    }
    RunInParallel(&cases);
    for (const Case& c : cases) {
      if (c.keep_going) continue;
      ExpectStoppedRun(c, "was stopped by signal 19");
    }
    if (mode != "realtime") continue;
    const Case& c = cases.back();
    SCOPED_TRACE(c.name);
    ASSERT_TRUE(c.failure.empty()) << c.failure;
    const std::string report = ReadFile(c.out);
    EXPECT_EQ(c.status, 1) << report;
    EXPECT_GT(c.reaction_s, 3.0) << "--keep-going: the run goes on past the stop\n" << report;
    EXPECT_NE(report.find("vehicle 2 (pid "), std::string::npos) << report;
    EXPECT_NE(report.find("was stopped by signal 19"), std::string::npos) << report;
    EXPECT_EQ(report.find("the run was stopped there"), std::string::npos) << report;
    EXPECT_NE(report.find("LATE (real time): vehicle 2: "), std::string::npos) << report;
    ExpectNothingLeft(c);
    ExpectAnalysable(c);
  }
}

// A tmpfs mounted for the test's life, unmounted however the test ends.
class TmpfsMount {
 public:
  TmpfsMount(const std::string& dir, const std::string& options) : dir_(dir) {
    mkdir(dir.c_str(), 0755);
    umount2(dir.c_str(), MNT_DETACH);  // one a failed earlier run left
    mounted_ = mount("tmpfs", dir.c_str(), "tmpfs", 0, options.c_str()) == 0;
    if (!mounted_) error_ = std::strerror(errno);
  }
  ~TmpfsMount() {
    if (mounted_) umount2(dir_.c_str(), MNT_DETACH);
  }
  bool mounted() const { return mounted_; }
  const std::string& error() const { return error_; }

 private:
  std::string dir_, error_;
  bool mounted_ = false;
};

// --out on a 2 MB tmpfs that the run fills: lcm-logger's write fails, shoal run stops the
// run at once, says the disk holding the log is full and exits 1; nothing is left, and
// what was written is analysable (up to the last complete event).
TEST(FaultMatrix, FullDiskStopsTheRunWithAClearError) {
  if (geteuid() != 0) GTEST_SKIP() << "mounting a 2 MB tmpfs needs root (CI runs as root)";
  const std::string dir = TmpPath("fault_full_disk");
  TmpfsMount tmpfs(dir, "size=2m");
  ASSERT_TRUE(tmpfs.mounted()) << "mount -t tmpfs -o size=2m tmpfs " << dir << ": "
                               << tmpfs.error();
  Case c;
  c.name = "fault_full_disk";
  c.log = dir + "/run.lcmlog";
  c.out = TmpPath("fault_full_disk.out");
  const pid_t run =
      StartShoal("run " + kExample2 + " --duration 100000 --quiet --out " + c.log, c.out);
  // The reaction: from lcm-logger's exit (it is a zombie, or gone, once it has exited) to
  // shoal run's.
  const auto t0 = Clock::now();
  pid_t logger = -1;
  while (logger <= 0 && Since(t0) < 30) {
    logger = VictimOf(ChildrenOf(run), "lcm-logger");
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_GT(logger, 0) << ReadFile(c.out);
  while (Since(t0) < 60 && ProcessState(logger) != 'Z' && ProcessState(logger) != 0) {
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  const auto t_logger_exit = Clock::now();
  double at_s = -1;
  ASSERT_TRUE(WaitUntil(run, t_logger_exit, 60.0, &c.status, &at_s))
      << "shoal run hangs on a full disk";
  const std::string report = ReadFile(c.out);
  std::printf("[ measured ] full disk: exit %d %.3f s after lcm-logger's exit, %.2f s after "
              "the start\n", c.status, at_s, Since(t0));
  EXPECT_LT(at_s, kReactionLimitS) << report;
  EXPECT_EQ(c.status, 1) << report;
  EXPECT_NE(report.find("lcm-logger exited early (exited with status 1) at t = "),
            std::string::npos)
      << report;
  EXPECT_NE(report.find("the disk holding " + c.log + " is full"), std::string::npos) << report;
  EXPECT_NE(report.find("LOG INCOMPLETE"), std::string::npos) << report;
  EXPECT_TRUE(ProcessesWith(c.log).empty()) << "left behind";
  EXPECT_TRUE(ProcessesUsing(dir).empty()) << "left behind, with files open on the full disk";
  const auto a = RunShoal("analyze " + c.log + " --json", "fault_full_disk_analyze");
  EXPECT_EQ(a.status, 0) << a.out << a.err;
  const auto j = ParseJson(a.out);
  EXPECT_GT(j.value("log_states", 0), 0) << a.out;
  // The write that failed cut the last event short (damaged: "truncated: ..."), or at
  // least the last tick lacks states; both only by chance not.
  EXPECT_TRUE(j.value("damaged", false) ||
              j.value("log_states", 0) < j.value("log_states_expected", 0))
      << a.out << a.err;
}

// --out in a read-only folder (root ignores permission bits: a read-only tmpfs): exit 2
// before anything starts, with the reason.
TEST(FaultMatrix, ReadOnlyOutFolderIsRefusedBeforeAnythingStarts) {
  if (geteuid() != 0) GTEST_SKIP() << "mounting a read-only tmpfs needs root (CI runs as root)";
  const std::string dir = TmpPath("fault_read_only");
  TmpfsMount tmpfs(dir, "ro,size=1m");
  ASSERT_TRUE(tmpfs.mounted()) << tmpfs.error();
  const auto t0 = Clock::now();
  const auto r = RunShoal("run " + kExample2 + " --out " + dir + "/run.lcmlog", "fault_ro");
  EXPECT_LT(Since(t0), 2.0);
  EXPECT_EQ(r.status, 2) << r.out << r.err;
  EXPECT_NE(r.err.find(dir + "/run.lcmlog: cannot open log for writing (Read-only file system)"),
            std::string::npos)
      << r.err;
  EXPECT_TRUE(ProcessesWith(dir).empty());
}

}  // namespace
}  // namespace shoal
