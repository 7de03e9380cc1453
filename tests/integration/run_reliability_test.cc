// shoal run at the edges of a run (docs/run.md, docs/reliability.md): an --out that is not
// a regular file, a refused run, lcm-logger dying as the run ends or in its middle, Ctrl-C
// once the run has ended or just after its start, a failing process's last words. Each
// test starts the real `shoal run` on Example 2 in a folder of its own.
#include <dirent.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <functional>
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
using shoal::testing::TmpPath;
using shoal::testing::WaitExit;
using Clock = std::chrono::steady_clock;

const std::string kExample2 = SourcePath("scenarios/paper_example2.toml");

double Since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

// An empty folder for one test's files.
std::string TestDir(const std::string& name) {
  const std::string dir = TmpPath("run_reliability_" + name);
  std::system(("rm -rf '" + dir + "' && mkdir -p '" + dir + "'").c_str());
  return dir;
}

bool Exists(const std::string& path) { return access(path.c_str(), F_OK) == 0; }

bool Ended(pid_t pid) {
  const char state = ProcessState(pid);
  return state == 0 || state == 'Z' || state == 'X';
}

// The child of shoal run `run` running the program `exe` (its path ends so) whose command
// line holds `also`, -1 if none.
pid_t ChildWith(pid_t run, const std::string& exe, const std::string& also = "") {
  DIR* d = opendir("/proc");
  if (!d) return -1;
  pid_t found = -1;
  while (const dirent* e = readdir(d)) {
    const int pid = std::atoi(e->d_name);
    if (pid <= 0 || ParentOf(pid) != run) continue;
    // The program itself, not a shell that names it (shoal run's "command -v lcm-logger").
    const std::string cmd = CmdLine(pid);
    const std::string program = cmd.substr(0, cmd.find(' '));
    const bool is_exe = program.size() >= exe.size() &&
                        program.compare(program.size() - exe.size(), exe.size(), exe) == 0;
    if (is_exe && cmd.find(also) != std::string::npos) {
      found = pid;
      break;
    }
  }
  closedir(d);
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

// Starts `shoal ARGS` in the background, its stdout (the --json report) and stderr apart.
pid_t StartShoal(const std::string& args, const std::string& out, const std::string& err) {
  const pid_t pid = fork();
  if (pid == 0) {
    const std::string cmd = "exec " + shoal::testing::ShoalBinary() + " " + args + " >'" + out +
                            "' 2>'" + err + "' </dev/null";
    execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  return pid;
}

// Kills shoal run (and with it, PR_SET_PDEATHSIG, its processes) if a test ends before
// it has waited for its exit.
struct KillIfRunning {
  pid_t pid;
  ~KillIfRunning() {
    if (pid > 0 && waitpid(pid, nullptr, WNOHANG) == 0) {
      kill(pid, SIGKILL);
      waitpid(pid, nullptr, 0);
    }
  }
};

// Polls every millisecond until `done` or `limit_s`; true if done.
bool PollUntil(double limit_s, const std::function<bool()>& done) {
  const auto t0 = Clock::now();
  while (Since(t0) < limit_s) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return done();
}

// Waits until the channel emulator of shoal run `run` has ended (the end of the run) and
// shoal run has seen it: reaped, it is gone from /proc. Its pid; -1 if it was not seen
// within 30 s or did not end within 60 s.
pid_t WaitForTheEmulatorsEnd(pid_t run) {
  pid_t emulator = -1;
  if (!PollUntil(30, [&] { return (emulator = ChildWith(run, "shoal_channel_emulator")) > 0; })) {
    return -1;
  }
  return PollUntil(60, [&] { return ProcessState(emulator) == 0; }) ? emulator : -1;
}

bool AnyHolds(const nlohmann::ordered_json& list, const std::string& text) {
  for (const auto& p : list) {
    if (p.is_string() && p.get<std::string>().find(text) != std::string::npos) return true;
  }
  return false;
}

// --out naming an existing directory, FIFO or character device: refused with 2 before
// anything is written or started, saying what it is; never waits (a FIFO once held the
// run 30 s), and nothing is put beside it (/dev/full.key, /dev/full.d/ once).
TEST(RunReliability, OutThatIsNotARegularFileIsRefusedBeforeAnythingStarts) {
  const std::string dir = TestDir("out_kinds");
  struct Case {
    std::string out, kind;
  };
  std::vector<Case> cases = {{dir + "/folder.lcmlog", "a directory"},
                             {dir + "/fifo.lcmlog", "a FIFO (named pipe)"}};
  ASSERT_EQ(mkdir(cases[0].out.c_str(), 0755), 0);
  ASSERT_EQ(mkfifo(cases[1].out.c_str(), 0644), 0);
  // The device through a link in the test's folder, so that a launcher without the check
  // writes its key and output folder here, not into /dev.
  struct stat st {};
  if (stat("/dev/full", &st) == 0 && S_ISCHR(st.st_mode)) {
    cases.push_back({dir + "/full.lcmlog", "a character device"});
    ASSERT_EQ(symlink("/dev/full", cases.back().out.c_str()), 0);
  }
  for (const Case& c : cases) {
    SCOPED_TRACE(c.out);
    const auto t0 = Clock::now();
    const auto r = RunShoal("run " + kExample2 + " --duration 2 --json --out '" + c.out + "'",
                            "run_reliability_out_kinds");
    EXPECT_EQ(r.status, 2) << r.out << r.err;
    EXPECT_LT(Since(t0), 5.0) << r.err;
    EXPECT_NE(r.err.find(c.out + ": cannot open log for writing: it is " + c.kind +
                         ", not a regular file"),
              std::string::npos)
        << r.err;
    EXPECT_FALSE(Exists(c.out + ".d")) << "the process output folder was made";
    EXPECT_FALSE(Exists(c.out + ".key")) << "a key file was written";
  }
}

// A run refused because its key file cannot be replaced (a folder in its place) removes
// nothing: the earlier run's log and each of its processes' output stay as they were.
TEST(RunReliability, ARefusedRunKeepsTheEarlierRunsLogAndProcessOutput) {
  const std::string dir = TestDir("refused_keep");
  const std::string log = dir + "/kd.lcmlog";
  const std::string args = "run " + kExample2 + " --duration 2 --json --out " + log;
  const auto first = RunShoal(args, "run_reliability_refused_first");
  ASSERT_TRUE(first.status == 0 || first.status == 1) << first.out << first.err;
  const std::vector<std::string> outputs = {"emulator.txt", "leader.txt",   "logger.txt",
                                            "vehicle1.txt", "vehicle2.txt", "vehicle3.txt",
                                            "vehicle4.txt", "vehicle5.txt"};
  for (const std::string& f : outputs) ASSERT_TRUE(Exists(log + ".d/" + f)) << f;
  const std::string log_before = ReadFile(log);
  const std::string emulator_before = ReadFile(log + ".d/emulator.txt");
  ASSERT_EQ(std::remove((log + ".key").c_str()), 0);
  ASSERT_EQ(mkdir((log + ".key").c_str(), 0755), 0);
  // With the key and with --insecure (which removes an earlier key file) alike.
  for (const std::string& more : {std::string(""), std::string(" --insecure")}) {
    SCOPED_TRACE(more);
    const auto r = RunShoal(args + more, "run_reliability_refused_again");
    EXPECT_EQ(r.status, 2) << r.out << r.err;
    const std::string why = more.empty() ? ".key: cannot replace the key file (Is a directory)"
                                         : ".key: cannot remove an earlier run's key file "
                                           "(Is a directory)";
    EXPECT_NE(r.err.find(log + why), std::string::npos) << r.err;
    for (const std::string& f : outputs) EXPECT_TRUE(Exists(log + ".d/" + f)) << f;
    EXPECT_EQ(ReadFile(log + ".d/emulator.txt"), emulator_before);
    EXPECT_EQ(ReadFile(log), log_before);
  }
}

// lcm-logger killed once the channel emulator has ended the run, before shoal run tells it
// to close the log: what it had not written is lost (the emulator's last status at
// least), so the run is not all right: a problem naming it, exit 1.
TEST(RunReliability, LoggerDyingAsTheRunEndsFailsTheRun) {
  const std::string dir = TestDir("logger_end");
  const std::string log = dir + "/run.lcmlog";
  const pid_t run = StartShoal("run " + kExample2 + " --duration 5 --json --out " + log,
                               dir + "/run.json", dir + "/run.err");
  const KillIfRunning guard{run};
  pid_t logger = -1;
  ASSERT_TRUE(PollUntil(30, [&] { return (logger = ChildWith(run, "lcm-logger")) > 0; }))
      << ReadFile(dir + "/run.err");
  const pid_t emulator = WaitForTheEmulatorsEnd(run);
  ASSERT_GT(emulator, 0) << "the channel emulator was not seen to end\n"
                         << ReadFile(dir + "/run.err");
  // shoal run waits for the other processes, then 0.2 s, before it stops the logger.
  ASSERT_FALSE(Ended(logger)) << "shoal run stopped the logger before the test could";
  ASSERT_EQ(kill(logger, SIGKILL), 0);
  const int status = WaitExit(run, 30, nullptr);
  const auto j = ParseJson(ReadFile(dir + "/run.json"));
  EXPECT_EQ(status, 1) << j.dump(1) << ReadFile(dir + "/run.err");
  EXPECT_FALSE(j.value("all_processes_ok", true)) << j.dump(1);
  EXPECT_FALSE(j.value("interrupted", true)) << j.dump(1);
  const std::string named = "lcm-logger (pid " + std::to_string(logger) + ") killed by signal 9";
  EXPECT_TRUE(AnyHolds(j["problems"], named)) << j["problems"].dump(1);
  EXPECT_TRUE(AnyHolds(j["problems"], "the log may lack the run's last messages"))
      << j["problems"].dump(1);
}

// lcm-logger killed mid-run stops the run; --json's stopped_by names it as it names any
// process whose fault stopped a run. (A lockstep run covers a few hundred seconds of
// mission a second: the duration leaves time to see the log grow, the kill ends it.)
TEST(RunReliability, LoggerKilledMidRunIsWhatStoppedTheRun) {
  const std::string dir = TestDir("logger_mid");
  const std::string log = dir + "/run.lcmlog";
  const pid_t run = StartShoal("run " + kExample2 + " --duration 3000 --json --out " + log,
                               dir + "/run.json", dir + "/run.err");
  const KillIfRunning guard{run};
  pid_t logger = -1;
  ASSERT_TRUE(PollUntil(30, [&] {
    logger = ChildWith(run, "lcm-logger");
    return logger > 0 && StatesInLog(log) >= 6 * 25;  // half a second of the mission
  })) << ReadFile(dir + "/run.err");
  ASSERT_EQ(kill(logger, SIGKILL), 0);
  EXPECT_EQ(WaitExit(run, 30, nullptr), 1) << ReadFile(dir + "/run.err");
  const auto j = ParseJson(ReadFile(dir + "/run.json"));
  const std::string stopped_by = j.value("stopped_by", "");
  const std::string named =
      "lcm-logger (pid " + std::to_string(logger) + ") killed by signal 9 (Killed) at t = ";
  EXPECT_EQ(stopped_by.rfind(named, 0), 0u) << stopped_by;
  EXPECT_NE(stopped_by.find(" s into the run)"), std::string::npos) << stopped_by;
  EXPECT_TRUE(AnyHolds(j["problems"], "lcm-logger exited early (killed by signal 9"))
      << j["problems"].dump(1);
}

// Ctrl-C (SIGINT to shoal run) once the channel emulator has ended the run only hurries
// the shutdown: the run is not interrupted (not 130), and no process failed.
TEST(RunReliability, CtrlCOnceTheRunHasEndedDoesNotInterruptIt) {
  const std::string dir = TestDir("ctrl_c_end");
  const std::string log = dir + "/run.lcmlog";
  const pid_t run = StartShoal("run " + kExample2 + " --duration 5 --json --out " + log,
                               dir + "/run.json", dir + "/run.err");
  const KillIfRunning guard{run};
  ASSERT_GT(WaitForTheEmulatorsEnd(run), 0) << "the channel emulator was not seen to end\n"
                                            << ReadFile(dir + "/run.err");
  int raw = 0;
  ASSERT_EQ(waitpid(run, &raw, WNOHANG), 0) << "shoal run ended before the test's Ctrl-C";
  ASSERT_EQ(kill(run, SIGINT), 0);
  const int status = WaitExit(run, 30, nullptr);
  const auto j = ParseJson(ReadFile(dir + "/run.json"));
  // 0, or 1 for what a 5 s run does not reach (convergence): never 130.
  EXPECT_TRUE(status == 0 || status == 1) << status << "\n" << j.dump(1);
  EXPECT_FALSE(j.value("interrupted", true)) << j.dump(1);
  EXPECT_TRUE(j.value("all_processes_ok", false)) << j.dump(1);
  EXPECT_TRUE(j["problems"].empty()) << j["problems"].dump(1);
  EXPECT_EQ(j.value("stopped_by", "?"), "") << j.dump(1);
}

// Ctrl-C just after the start of a lockstep run, before the clock master has taken over
// the logger's count (and removed its name): shoal run removes it, nothing is left in
// /dev/shm.
TEST(RunReliability, CtrlCAtTheStartLeavesNothingInDevShm) {
  const std::string dir = TestDir("ctrl_c_start");
  const std::string log = dir + "/run.lcmlog";
  const pid_t run = StartShoal("run " + kExample2 + " --duration 600 --json --out " + log,
                               dir + "/run.json", dir + "/run.err");
  const KillIfRunning guard{run};
  pid_t logger = -1;
  ASSERT_TRUE(PollUntil(30, [&] { return (logger = ChildWith(run, "lcm-logger")) > 0; }))
      << ReadFile(dir + "/run.err");
  const std::string environ = ReadFile("/proc/" + std::to_string(logger) + "/environ");
  if (environ.find(std::string("SHOAL_LOGGER_PROGRESS=1") + '\0') == std::string::npos) {
    kill(run, SIGINT);
    WaitExit(run, 30, nullptr);
    GTEST_SKIP() << "this build's logger keeps no count (no runtime/lcm_queue_shim.c library)";
  }
  // The name is made once the logger has subscribed; the clock master maps it (and removes
  // it) only once every process is ready.
  const std::string name = "/dev/shm/shoal-logger-" + std::to_string(logger);
  ASSERT_TRUE(PollUntil(30, [&] { return Exists(name); })) << ReadFile(dir + "/run.err");
  ASSERT_EQ(kill(run, SIGINT), 0);
  EXPECT_EQ(WaitExit(run, 30, nullptr), 130) << ReadFile(dir + "/run.err");
  EXPECT_FALSE(Exists(name)) << name << " is left";
  unlink(name.c_str());  // not left for the next run, whatever the result
}

// A process that fails says why before the lines every process writes at its end (its
// authentication count; the emulator's lockstep figures): shoal run quotes the reason.
// Vehicle 2 killed with --keep-going: the channel emulator waits 5 s for it, declares it
// lost, runs to the end (a second or two) and exits 4.
TEST(RunReliability, AFailingProcessIsQuotedByItsReasonNotItsEndOfRunLines) {
  const std::string dir = TestDir("last_words");
  const std::string log = dir + "/run.lcmlog";
  const pid_t run =
      StartShoal("run " + kExample2 + " --duration 1200 --keep-going --json --out " + log,
                 dir + "/run.json", dir + "/run.err");
  const KillIfRunning guard{run};
  pid_t vehicle = -1;
  ASSERT_TRUE(PollUntil(30, [&] {
    vehicle = ChildWith(run, "shoal_vehicle", "--id 2 ");
    return vehicle > 0 && StatesInLog(log) >= 6 * 25;
  })) << ReadFile(dir + "/run.err");
  ASSERT_EQ(kill(vehicle, SIGKILL), 0);
  EXPECT_EQ(WaitExit(run, 60, nullptr), 1) << ReadFile(dir + "/run.err");
  const auto j = ParseJson(ReadFile(dir + "/run.json"));
  const std::string stopped_by = j.value("stopped_by", "");
  EXPECT_NE(stopped_by.find("channel emulator (pid "), std::string::npos) << j.dump(1);
  EXPECT_TRUE(AnyHolds(j["problems"],
                       "exited with status 4 (its output ends with \"shoal_channel_emulator: "
                       "vehicle 2 stopped answering at t = "))
      << j["problems"].dump(1) << "\n"
      << ReadFile(log + ".d/emulator.txt");
  EXPECT_FALSE(AnyHolds(j["problems"], "failed authentication")) << j["problems"].dump(1);
}

}  // namespace
}  // namespace shoal
