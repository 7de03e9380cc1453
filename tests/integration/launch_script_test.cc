// The start time of a real-time run (--t0-ns, --t0-unix-ns) and shoal run --print-launch:
// the real executables, and the printed script run by bash.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "launcher/launch_script.h"
#include "runtime/clock.h"
#include "runtime/lcm_bus.h"
#include "runtime/process.h"
#include "tests/integration/test_util.h"

namespace shoal {
namespace {

using shoal::testing::ParseJson;
using shoal::testing::ReadFile;
using shoal::testing::RunShoal;
using shoal::testing::SourcePath;
using shoal::testing::TmpPath;

const std::string kExample2 = SourcePath("scenarios/paper_example2.toml");

std::string Url(int port) { return "udpm://239.255.76.67:" + std::to_string(port) + "?ttl=0"; }

std::string Exe(const std::string& which) {
  if (which == "vehicle") return std::string(SHOAL_BINARY_DIR) + "/vehicle/shoal_vehicle --id 1";
  if (which == "leader") return std::string(SHOAL_BINARY_DIR) + "/leader/shoal_leader";
  return std::string(SHOAL_BINARY_DIR) + "/channel_emulator/shoal_channel_emulator";
}

struct Outcome {
  int status = -1;
  std::string output;
  int messages = 0;  // what a listener on the process's bus heard meanwhile
};

/// Runs `command` (a real process of a run, on bus `port`, --insecure) while listening on
/// that bus: what it said, its exit status, and how many messages it published.
/// After `limit_s` it is killed (status 256 + 9).
Outcome RunListening(const std::string& command, int port, const std::string& tag,
                     double limit_s = 30.0) {
  LcmBus listener(Url(port));
  std::atomic<int> heard{0};
  listener.Subscribe("SHOAL_.*", [&heard](const std::string&, const void*, int) { ++heard; });
  const std::string out = TmpPath(tag + ".out");
  const pid_t pid = fork();
  if (pid == 0) {
    const std::string cmd = "exec " + command + " >" + out + " 2>&1 </dev/null";
    execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  Outcome o;
  int raw = 0;
  const auto t0 = std::chrono::steady_clock::now();
  while (waitpid(pid, &raw, WNOHANG) != pid) {
    listener.Handle(20);
    if (std::chrono::steady_clock::now() - t0 > std::chrono::duration<double>(limit_s)) {
      kill(pid, SIGKILL);
      waitpid(pid, &raw, 0);
      break;
    }
  }
  for (int i = 0; i < 10; ++i) listener.Handle(20);  // what is still on its way
  o.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : 256 + WTERMSIG(raw);
  o.output = ReadFile(out);
  o.messages = heard;
  return o;
}

/// The loop lateness p50 a real-time process says on exit ("lateness p50 X ms"); a start
/// time converted wrongly makes it seconds, a loaded machine a few milliseconds at most.
double LatenessP50Ms(const std::string& output) {
  const std::size_t p = output.find("lateness p50 ");
  if (p == std::string::npos) return 1e300;
  return std::stod(output.substr(p + 13));
}

std::string Common(int port, const std::string& mode) {
  return " --insecure --scenario " + kExample2 + " --lcm-url '" + Url(port) + "' --mode " + mode +
         " --duration 0.3";
}

TEST(StartTime, RealtimeProcessWithoutAStartTimeRefusesToStart) {
  for (const std::string which : {"vehicle", "leader", "emulator"}) {
    const Outcome o = RunListening(Exe(which) + Common(31711, "realtime"), 31711, "t0_none");
    EXPECT_EQ(o.status, 2) << which << ": " << o.output;
    EXPECT_NE(o.output.find("real time needs the run's start time"), std::string::npos)
        << which << ": " << o.output;
    EXPECT_NE(o.output.find("--t0-unix-ns"), std::string::npos) << which << ": " << o.output;
    EXPECT_NE(o.output.find("--t0-ns"), std::string::npos) << which << ": " << o.output;
    EXPECT_EQ(o.messages, 0) << which << ": it published";
  }
}

TEST(StartTime, AVehicleGivenAStartTimeRunsAndPublishes) {
  // The listener of the test above hears a process that does publish.
  const std::string t0 = std::to_string(RealtimeNs() + 200000000LL);
  const Outcome o = RunListening(Exe("vehicle") + Common(31712, "realtime") +
                                     " --t0-unix-ns " + t0, 31712, "t0_unix");
  EXPECT_EQ(o.status, 0) << o.output;
  EXPECT_GE(o.messages, 16) << o.output;  // 0.3 s at 50 Hz: 16 states, statuses, health
  // On time: the wall-clock start was converted to the monotonic clock correctly.
  EXPECT_LT(LatenessP50Ms(o.output), 50.0) << o.output;
}

TEST(StartTime, ADurationThatCountsNoTickIsRefused) {
  for (const std::string which : {"vehicle", "leader", "emulator"}) {
    for (const std::string d : {"inf", "nan", "1e30", "0", "-5", "5s"}) {
      const Outcome o = RunListening(Exe(which) + " --insecure --scenario " + kExample2 +
                                         " --lcm-url '" + Url(31716) +
                                         "' --mode lockstep --duration " + d,
                                     31716, "dur_bad");
      EXPECT_EQ(o.status, 2) << which << " --duration " << d << ": " << o.output;
      EXPECT_NE(o.output.find("at most 1e9"), std::string::npos) << which << ": " << o.output;
      EXPECT_EQ(o.messages, 0) << which << ": it published";
    }
  }
}

TEST(StartTime, BothStartTimesOrOneMoreThanADayAheadOrBeforeTheClockAreRefused) {
  const std::int64_t day = 86400LL * 1000000000LL;
  const std::string mono_now = std::to_string(MonotonicNs());
  const std::string unix_now = std::to_string(RealtimeNs());
  const std::vector<std::pair<std::string, std::string>> bad = {
      {" --t0-ns " + mono_now + " --t0-unix-ns " + unix_now, "not both"},
      {" --t0-unix-ns " + std::to_string(RealtimeNs() + day + 60000000000LL), "more than a day"},
      {" --t0-unix-ns " + mono_now, "before the year 2000"},  // the monotonic clock for it
      {" --t0-ns " + unix_now, "more than a day"},            // and the other way round
      {" --t0-ns -5", "before boot"},
  };
  for (const auto& [args, says] : bad) {
    for (const std::string which : {"vehicle", "emulator"}) {
      const Outcome o = RunListening(Exe(which) + Common(31713, "realtime") + args, 31713,
                                     "t0_bad");
      EXPECT_EQ(o.status, 2) << which << args << ": " << o.output;
      EXPECT_NE(o.output.find(says), std::string::npos) << which << args << ": " << o.output;
      EXPECT_EQ(o.messages, 0) << which << args;
    }
  }
}

TEST(StartTime, AStartTimeInThePastIsAllowed) {
  // A restarted process goes on with the run's original t0.
  const std::string t0 = std::to_string(RealtimeNs() - 3600LL * 1000000000LL);
  const Outcome o = RunListening(Exe("vehicle") + Common(31714, "realtime") +
                                     " --t0-unix-ns " + t0, 31714, "t0_past");
  EXPECT_EQ(o.status, 0) << o.output;
  EXPECT_GT(o.messages, 0) << o.output;
}

TEST(StartTime, WallClockConvertsToTheMonotonicClock) {
  const std::int64_t unix_now = RealtimeNs();
  const std::int64_t mono = MonotonicFromUnixNs(unix_now);
  EXPECT_LT(std::llabs(mono - MonotonicNs()), 5000000LL);  // 5 ms, on a loaded machine
  // A second later on one clock is a second later on the other.
  EXPECT_LT(std::llabs(MonotonicFromUnixNs(unix_now + 1000000000LL) - mono - 1000000000LL),
            5000000LL);
}

TEST(StartTime, LockstepNeedsNoStartTime) {
  // Lockstep reads no clock: started without one, a vehicle announces itself and waits
  // for the clock master as usual (here none comes: it is stopped after 1.5 s).
  const Outcome o =
      RunListening(Exe("vehicle") + Common(31715, "lockstep"), 31715, "t0_ls", 1.5);
  EXPECT_EQ(o.status, 256 + SIGKILL) << o.output;
  EXPECT_EQ(o.output.find("start time"), std::string::npos) << o.output;
  EXPECT_GT(o.messages, 0) << o.output;  // its "ready" statuses
}

struct Script {
  std::string path;
  std::string text;
};

/// shoal run --print-launch ARGS, into a file.
Script Print(const std::string& args, const std::string& tag) {
  const auto r = RunShoal("run --print-launch " + args, tag);
  EXPECT_EQ(r.status, 0) << r.err;
  Script s{TmpPath(tag + ".sh"), r.out};
  std::FILE* f = std::fopen(s.path.c_str(), "w");
  std::fputs(r.out.c_str(), f);
  std::fclose(f);
  return s;
}

/// bash SCRIPT: exit status and stderr.
std::pair<int, std::string> RunBash(const std::string& script, const std::string& tag) {
  const std::string err = TmpPath(tag + ".bash.err");
  const int raw = std::system(("bash " + script + " >/dev/null 2>" + err + " </dev/null").c_str());
  return {WIFEXITED(raw) ? WEXITSTATUS(raw) : 256 + WTERMSIG(raw), ReadFile(err)};
}

TEST(LaunchScript, ShellWordsKeepEveryArgumentAsItIs) {
  EXPECT_EQ(ShellWord("--duration"), "--duration");
  EXPECT_EQ(ShellWord("udpm://239.255.76.67:1?ttl=0&x=1"), "'udpm://239.255.76.67:1?ttl=0&x=1'");
  EXPECT_EQ(ShellWord("--set=name=it's $HOME"), "'--set=name=it'\\''s $HOME'");
  EXPECT_EQ(ShellWord(""), "''");
  EXPECT_EQ(ShellWord(kT0Arg), "\"$t0\"");
  EXPECT_EQ(ShellWord(kLoggerPidArg), "\"$logger_pid\"");
  // bash gives back each word as it was.
  const std::string odd = "a b'c\"d$e`f\\g\nh*";
  const std::string out = TmpPath("ls_words.out");
  std::system(("printf '%s' " + ShellWord(odd) + " >" + out).c_str());
  EXPECT_EQ(ReadFile(out), odd);
}

TEST(LaunchScript, HoldsShoalRunsCommands) {
  const std::string log = TmpPath("ls_text.lcmlog");
  const Script s = Print(kExample2 + " --mode realtime --duration 5 --out " + log +
                             " --set vehicle.integrator_step_s=0.01 --max-lookahead 7", "ls_text");
  EXPECT_EQ(s.text.rfind("#!/usr/bin/env bash\n", 0), 0u) << s.text;
  EXPECT_NE(s.text.find("set -euo pipefail"), std::string::npos);
  EXPECT_NE(s.text.find("export SHOAL_BUS_KEY"), std::string::npos);
  EXPECT_NE(s.text.find("t0=$(( $(date +%s%N) + 4000000000 ))"), std::string::npos);
  EXPECT_NE(s.text.find("trap shut_down EXIT"), std::string::npos);
  // Every run process gets the start time on the wall clock, the --set and the options.
  const std::regex start(R"(start '?([a-z ]+[0-9]*)'? )");
  int processes = 0;
  for (auto it = std::sregex_iterator(s.text.begin(), s.text.end(), start);
       it != std::sregex_iterator(); ++it) {
    ++processes;
  }
  EXPECT_EQ(processes, 1 + 1 + 1 + 5) << s.text;  // logger, emulator, leader, 5 followers
  std::string commands;  // the script less its comments
  std::istringstream lines(s.text);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("#", 0) != 0) commands += line + "\n";
  }
  auto count = [&](const std::string& what) {
    int n = 0;
    for (std::size_t p = commands.find(what); p != std::string::npos;
         p = commands.find(what, p + 1)) {
      ++n;
    }
    return n;
  };
  EXPECT_EQ(count("--t0-unix-ns \"$t0\""), 7) << s.text;
  EXPECT_EQ(count("--set=vehicle.integrator_step_s=0.01"), 7) << s.text;
  EXPECT_EQ(count("--t0-ns"), 0) << s.text;
  EXPECT_EQ(count("--max-lookahead 7"), 1) << s.text;
  EXPECT_EQ(count("--rx-url"), 6) << s.text;
  EXPECT_EQ(count(" " + std::string(SHOAL_BINARY_DIR) + "/tools/../vehicle/shoal_vehicle \\\n"), 5)
      << s.text;  // by absolute path, as shoal run finds it
  EXPECT_EQ(count("/usr/bin/lcm-logger"), 1) << s.text;
  // The log is named on the `log=` and `out_dir=` lines only; the logger records to $log.
  EXPECT_EQ(count(log), 2) << s.text;
  EXPECT_EQ(count("log=" + log + "\n"), 1) << s.text;
  EXPECT_EQ(count("\n    -- \"$log\"\n"), 1) << s.text;
  // What a script cannot do is refused.
  const auto restart = RunShoal("run --print-launch " + kExample2 + " --restart on-failure",
                                "ls_restart");
  EXPECT_EQ(restart.status, 2) << restart.err;
  EXPECT_NE(restart.err.find("does not restart"), std::string::npos) << restart.err;
}

TEST(LaunchScript, LockstepScriptLogsWhatShoalRunLogs) {
  const std::string script_log = TmpPath("ls_script.lcmlog"), run_log = TmpPath("ls_run.lcmlog");
  const std::string printed_log = TmpPath("ls_printed.lcmlog");
  Script s = Print(kExample2 + " --duration 10 --out " + printed_log, "ls_lockstep");
  // A user who edits the one `log=` line moves the log, its key and the processes' output.
  const std::string printed_line = "\nlog=" + printed_log + "\n";
  const std::size_t at = s.text.find(printed_line);
  ASSERT_NE(at, std::string::npos) << s.text;
  s.text.replace(at, printed_line.size(), "\nlog=" + script_log + "\n");
  const std::string out_line = "\nout_dir=" + printed_log + ".d ";
  const std::size_t out_at = s.text.find(out_line);
  ASSERT_NE(out_at, std::string::npos) << s.text;
  s.text.replace(out_at, out_line.size(), "\nout_dir=" + script_log + ".d ");
  {
    std::ofstream f(s.path);
    f << s.text;
  }
  std::remove(printed_log.c_str());
  const auto [status, err] = RunBash(s.path, "ls_lockstep");
  ASSERT_EQ(status, 0) << err << s.text;
  EXPECT_FALSE(std::ifstream(printed_log).good()) << "the log went to the printed path";
  EXPECT_TRUE(std::ifstream(script_log + ".key").good());
  EXPECT_TRUE(std::ifstream(script_log + ".d/vehicle1.txt").good());
  const auto run = RunShoal("run " + kExample2 + " --duration 10 --json --out " + run_log,
                            "ls_lockstep_run");
  ASSERT_TRUE(ParseJson(run.out)["all_processes_ok"].get<bool>()) << run.out << run.err;
  // Each log verified with its own run's key (<log>.key): the script wrote its own.
  const auto cmp = RunShoal("compare " + script_log + " " + run_log + " --json", "ls_lockstep_cmp");
  const auto cj = ParseJson(cmp.out);
  EXPECT_EQ(cmp.status, 0) << cmp.out << cmp.err;
  EXPECT_EQ(cj["max_position_diff_m"].get<double>(), 0.0) << cmp.out;
  EXPECT_EQ(cj["max_velocity_diff_mps"].get<double>(), 0.0) << cmp.out;
  EXPECT_EQ(cj["only_in_a"].get<int>(), 0) << cmp.out;
  EXPECT_EQ(cj["only_in_b"].get<int>(), 0) << cmp.out;
  EXPECT_EQ(cj["samples"].get<int>(), 6 * 501) << cmp.out;  // 6 vehicles, ticks 0..500
  EXPECT_EQ(cmp.err.find("authenticat"), std::string::npos) << cmp.err;
}

TEST(LaunchScript, RealtimeScriptRunsToTheEnd) {
  const std::string log = TmpPath("ls_rt.lcmlog");
  const Script s = Print(kExample2 + " --mode realtime --duration 3 --out " + log, "ls_rt");
  const auto t0 = std::chrono::steady_clock::now();
  const auto [status, err] = RunBash(s.path, "ls_rt");
  const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_EQ(status, 0) << err;
  EXPECT_LT(took, 15.0);  // 4 s margin, 3 s of mission, the end of the last delays
  const auto ana = RunShoal("analyze --json " + log, "ls_rt_analyze");
  const auto aj = ParseJson(ana.out);
  EXPECT_EQ(aj["log_states"].get<int>(), 6 * 151) << ana.out;  // ticks 0..150
  // The emulator's last status, sent as it exits, is in the log: it tells where the run
  // ended, so the states expected are those of 3 s, not of the scenario's 600 s.
  EXPECT_EQ(aj["log_states_expected"].get<int>(), 6 * 151) << ana.out;
  // Every process ran on time from the wall-clock start.
  for (const std::string tag : {"leader", "vehicle1", "vehicle5"}) {
    const std::string out = ReadFile(log + ".d/" + tag + ".txt");
    EXPECT_LT(LatenessP50Ms(out), 50.0) << tag << ": " << out;
  }
}

/// Starts `bash SCRIPT` (stderr to `err`), as a terminal starts a job when `own_group`: in
/// a process group of its own.
pid_t StartBash(const std::string& script, const std::string& err, bool own_group) {
  const pid_t bash = fork();
  if (bash == 0) {
    if (own_group) setpgid(0, 0);
    signal(SIGINT, SIG_DFL);  // an ignored SIGINT would stay ignored: bash could not trap it
    const std::string cmd = "exec bash " + script + " >/dev/null 2>" + err + " </dev/null";
    execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  return bash;
}

/// Stops a process group when the test leaves, whatever failed: nothing of a run outlives
/// the test to load the next ones.
struct GroupStopper {
  pid_t group;
  ~GroupStopper() { kill(-group, SIGTERM); }
};

/// The pids of the processes the script says it started, once there are `n` (or 10 s).
std::vector<int> StartedPids(const std::string& err, std::size_t n) {
  std::vector<int> pids;
  const std::regex started(R"(started .* \(pid ([0-9]+)\))");
  for (int i = 0; i < 200 && pids.size() < n; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    pids.clear();
    const std::string text = ReadFile(err);
    for (auto it = std::sregex_iterator(text.begin(), text.end(), started);
         it != std::sregex_iterator(); ++it) {
      pids.push_back(std::stoi((*it)[1]));
    }
  }
  return pids;
}

TEST(LaunchScript, StoppingTheScriptStopsEveryProcess) {
  const std::string log = TmpPath("ls_stop.lcmlog");
  const Script s = Print(kExample2 + " --mode realtime --duration 60 --out " + log, "ls_stop");
  const std::string err = TmpPath("ls_stop.bash.err");
  const pid_t bash = StartBash(s.path, err, false);
  const std::vector<int> pids = StartedPids(err, 8);
  ASSERT_EQ(pids.size(), 8u) << ReadFile(err);
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  kill(bash, SIGTERM);
  double took = 0;
  EXPECT_EQ(shoal::testing::WaitExit(bash, 10.0, &took), 143) << ReadFile(err);
  EXPECT_LT(took, 6.0);
  for (const int pid : pids) EXPECT_NE(kill(pid, 0), 0) << "pid " << pid << " still runs";
  EXPECT_GT(ReadFile(log).size(), 0u);  // the logger closed its log
}

// While a run writes a log, a second run on the same log -- the same script again, or
// shoal run with that --out -- is refused before it removes anything: both lock <log>.d/.
// The script also removes an earlier run's resources.csv, which would describe other
// processes.
TEST(LaunchScript, ASecondRunOnTheSameLogIsRefusedWhileTheFirstWrites) {
  const std::string log = TmpPath("ls_twice.lcmlog");
  const Script s = Print(kExample2 + " --mode realtime --duration 60 --out " + log, "ls_twice");
  ::mkdir((log + ".d").c_str(), 0755);
  { std::ofstream(log + ".d/resources.csv") << "an earlier run's\n"; }
  const std::string err = TmpPath("ls_twice.bash.err");
  const pid_t bash = StartBash(s.path, err, true);
  const GroupStopper stop_all{bash};
  ASSERT_EQ(StartedPids(err, 8).size(), 8u) << ReadFile(err);
  EXPECT_FALSE(std::ifstream(log + ".d/resources.csv").good());
  const auto [status, second] = RunBash(s.path, "ls_twice_again");
  EXPECT_EQ(status, 2) << second;
  EXPECT_NE(second.find("another run is writing " + log), std::string::npos) << second;
  const auto run = RunShoal("run " + kExample2 + " --duration 1 --out " + log, "ls_twice_run");
  EXPECT_EQ(run.status, 2) << run.err;
  EXPECT_NE(run.err.find("another run is writing " + log), std::string::npos) << run.err;
  std::this_thread::sleep_for(std::chrono::seconds(5));  // tick 0 is 4 s after the logger
  kill(-bash, SIGINT);
  EXPECT_EQ(shoal::testing::WaitExit(bash, 10.0, nullptr), 130) << ReadFile(err);
  const auto ana = RunShoal("analyze --json " + log, "ls_twice_analyze");
  EXPECT_GT(ParseJson(ana.out)["log_states"].get<int>(), 6 * 10) << ana.out << ana.err;
}

TEST(LaunchScript, CtrlCAtTheTerminalStopsTheLoggerLast) {
  // A terminal's Ctrl-C is SIGINT to the job's whole process group. The script's processes
  // run in process groups of their own, so the logger is stopped by the script, after the
  // others, and records the status the emulator sends as it stops ("interrupted"; the
  // others' go to the emulator's uplink, which has stopped by then).
  const std::string log = TmpPath("ls_ctrlc.lcmlog");
  const Script s = Print(kExample2 + " --mode realtime --duration 60 --out " + log, "ls_ctrlc");
  const std::string err = TmpPath("ls_ctrlc.bash.err");
  const pid_t bash = StartBash(s.path, err, true);
  const GroupStopper stop_all{bash};
  const std::vector<int> pids = StartedPids(err, 8);
  ASSERT_EQ(pids.size(), 8u) << ReadFile(err);
  std::this_thread::sleep_for(std::chrono::seconds(6));  // tick 0 is 4 s after the logger
  kill(-bash, SIGINT);
  double took = 0;
  EXPECT_EQ(shoal::testing::WaitExit(bash, 10.0, &took), 130) << ReadFile(err);
  for (const int pid : pids) EXPECT_NE(kill(pid, 0), 0) << "pid " << pid << " still runs";
  const auto ana = RunShoal("analyze --json " + log, "ls_ctrlc_analyze");
  const auto aj = ParseJson(ana.out);
  EXPECT_GT(aj["log_states"].get<int>(), 6 * 50) << ana.out;  // more than a second of ticks
  EXPECT_TRUE(aj["interrupted"].get<bool>()) << ana.out;     // the processes' last statuses
}

// Stopped just as the channel emulator starts, before the clock master of a lockstep run
// with an uplink has taken over the logger's count (and removed its name): the script
// removes it, as shoal run does; nothing is left in /dev/shm.
TEST(LaunchScript, StoppedAtItsStartLeavesNothingInDevShm) {
  const std::string log = TmpPath("ls_shm.lcmlog");
  const Script s = Print(kExample2 + " --mode lockstep --duration 60 --out " + log, "ls_shm");
  ASSERT_NE(s.text.find("/dev/shm/shoal-logger-"), std::string::npos) << s.text;
  const std::string err = TmpPath("ls_shm.bash.err");
  const pid_t bash = StartBash(s.path, err, false);
  const std::regex started(R"(started .* \(pid ([0-9]+)\))");
  std::vector<int> pids;
  for (int i = 0; i < 2000 && pids.size() < 2; ++i) {  // the logger and the emulator
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    pids.clear();
    const std::string text = ReadFile(err);
    for (auto it = std::sregex_iterator(text.begin(), text.end(), started);
         it != std::sregex_iterator(); ++it) {
      pids.push_back(std::stoi((*it)[1]));
    }
  }
  kill(bash, SIGTERM);
  ASSERT_GE(pids.size(), 2u) << ReadFile(err);
  EXPECT_EQ(shoal::testing::WaitExit(bash, 10.0, nullptr), 143) << ReadFile(err);
  const std::string name = "/dev/shm/shoal-logger-" + std::to_string(pids[0]);
  EXPECT_NE(access(name.c_str(), F_OK), 0) << name << " is left";
  unlink(name.c_str());  // not left for the next run, whatever the result
}

// A logger that exits before it subscribes (here killed while a preloaded library holds
// its subscription back) never will: the script says so and starts nothing else.
TEST(LaunchScript, ALoggerGoneBeforeItSubscribesStopsTheScriptBeforeTheRun) {
  const std::string lib = std::string(SHOAL_BINARY_DIR) + "/tests/libslow_logger_subscribe.so";
  ASSERT_EQ(access(lib.c_str(), R_OK), 0) << lib;
  const std::string log = TmpPath("ls_gone.lcmlog");
  // Printed with it preloaded: the script's logger gets the queue library and it.
  setenv("LD_PRELOAD", lib.c_str(), 1);
  const Script s = Print(kExample2 + " --mode lockstep --duration 20 --out " + log, "ls_gone");
  ASSERT_NE(s.text.find(lib), std::string::npos) << s.text;
  const std::string err = TmpPath("ls_gone.bash.err");
  setenv("SHOAL_TEST_SUBSCRIBE_DELAY_MS", "60000", 1);
  const pid_t bash = StartBash(s.path, err, false);
  unsetenv("LD_PRELOAD");
  unsetenv("SHOAL_TEST_SUBSCRIBE_DELAY_MS");
  const std::vector<int> pids = StartedPids(err, 1);
  ASSERT_EQ(pids.size(), 1u) << ReadFile(err);
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  kill(pids[0], SIGKILL);
  double took = 0;
  EXPECT_EQ(shoal::testing::WaitExit(bash, 10.0, &took), 1) << ReadFile(err);
  EXPECT_LT(took, 5.0);
  const std::string said = ReadFile(err);
  EXPECT_NE(said.find("lcm-logger exited before it subscribed"), std::string::npos) << said;
  EXPECT_EQ(said.find("started channel emulator"), std::string::npos) << said;
}

// lcm-logger's writer, stopped by SIGINT, drops what it has not written yet. A writer far
// behind at the end (100 us more per event, preloaded) still writes the whole run of a
// script on one bus for all: the script waits for it, by its count, as shoal run does.
TEST(LaunchScript, ALoggerBehindAtTheEndWritesTheWholeRun) {
  const std::string lib = std::string(SHOAL_BINARY_DIR) + "/tests/libslow_logger_subscribe.so";
  ASSERT_EQ(access(lib.c_str(), R_OK), 0) << lib;
  const std::string log = TmpPath("ls_slow_writer.lcmlog");
  setenv("LD_PRELOAD", lib.c_str(), 1);
  const Script s = Print(kExample2 + " --mode lockstep --duration 20 --shared-url --out " + log,
                         "ls_slow_writer");
  setenv("SHOAL_TEST_WRITE_DELAY_US", "100", 1);
  const auto [status, err] = RunBash(s.path, "ls_slow_writer");
  unsetenv("LD_PRELOAD");
  unsetenv("SHOAL_TEST_WRITE_DELAY_US");
  EXPECT_EQ(status, 0) << err;
  const auto ana = RunShoal("analyze --json " + log, "ls_slow_writer_analyze");
  const auto aj = ParseJson(ana.out);
  EXPECT_EQ(aj["log_states"].get<int>(), 6 * 1001) << ana.out << ana.err;
  EXPECT_EQ(aj["scenario_source"], "log") << ana.err;
  const std::regex name("shoal-logger-[0-9]+");
  for (const auto& e : std::filesystem::directory_iterator("/dev/shm")) {
    const std::string n = e.path().filename().string();
    // Only this test's logger could have left one: the script's tests run one at a time.
    EXPECT_FALSE(std::regex_match(n, name) && err.find("(pid " + n.substr(13) + ")") !=
                                                  std::string::npos)
        << n << " is left";
  }
}

TEST(ShoalRun, WallClockStartTimeRunsOnTime) {
  const std::string log = TmpPath("ls_wall.lcmlog");
  const auto r = RunShoal("run " + kExample2 + " --mode realtime --t0-clock wall --duration 3 "
                          "--json --out " + log, "ls_wall");
  const auto j = ParseJson(r.out);
  EXPECT_TRUE(j["all_processes_ok"].get<bool>()) << r.out << r.err;
  EXPECT_TRUE(j["log_complete"].get<bool>()) << r.out;
  // On time (timing_ok is not asked for: the shared machine may be loaded).
  EXPECT_LT(LatenessP50Ms(ReadFile(log + ".d/vehicle1.txt")), 50.0);
  // Each process was given the wall-clock time, and says what it made of it.
  for (const std::string tag : {"emulator", "leader", "vehicle1"}) {
    const std::string out = ReadFile(log + ".d/" + tag + ".txt");
    EXPECT_NE(out.find("tick 0 at --t0-unix-ns "), std::string::npos) << tag << ": " << out;
  }
}

}  // namespace
}  // namespace shoal
