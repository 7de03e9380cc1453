// shoal soak in real time, as a user runs it: a short soak of two followers whose phases step
// the delay must pass with every real-time part of its verdict filled in (per-minute rows
// with every state, per-phase loop lateness and release error p99 from the health
// reports' window histograms, resources sampled); with vehicle 2's loop held for a second
// in the last phase, the verdict must fail naming that phase's lateness and only it.
#include <signal.h>
#include <sys/ptrace.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "lcmtypes/wire.h"
#include "runtime/log_reader.h"
#include "tests/integration/test_util.h"

namespace shoal::testing {
namespace {

using ojson = nlohmann::ordered_json;

// Two followers (1 hears the leader, 2 hears 1) at 20 Hz: the lightest run with a chain of
// neighbours, so that five processes (leader, two vehicles, emulator, logger) share the
// machine with whatever else runs on it.
const char* kScenario = R"([run]
name = "soak_realtime"
duration_s = 600
control_rate_hz = 20

[swarm]
followers = 2
leader_links = [1]
edges = [[2, 1]]

[control]
k1 = 1
k2 = 1
offsets_m = [[6, 0, 0], [0, 6, 0]]

[channel.delay]
model = "constant"
base_s = 0.1
)";
constexpr int kVehicles = 3;  // leader and two followers
constexpr int kRateHz = 20;

// Three phases of `phase_s`. The lateness and delay targets are 20 ms (shoal run's own
// real-time limit), not the product's 2 ms and 1 ms, and a phase may overrun 5 ticks:
// this machine runs the suite beside other builds on two cores, often as a VM among
// others, where a loop a few ms late now and then, and a stall of the whole machine for
// more than a period now and then (2 overruns in one phase, once in many runs), are the
// machine's, not the code's; a held loop (below) is late by hundreds of ms and overruns
// about 20 ticks. The position tolerance is
// wide because the run is short: the formation takes longer than a phase to converge from
// its initial conditions, and re-convergence is the lockstep soaks' test.
std::string WriteCampaign(const std::string& name, int phase_s, int settle_s) {
  const std::string dir = TmpPath("soak_rt_" + name);
  std::system(("rm -rf " + dir + " && mkdir -p " + dir).c_str());
  std::ofstream(dir + "/scenario.toml") << kScenario;
  std::ofstream(dir + "/c.toml")
      << "[campaign]\nscenario = \"scenario.toml\"\nengine = \"realtime\"\n"
         "set = ['metrics.position_tol_m=1000']\n"
         "[[axis]]\nkey = \"channel.delay.base_s\"\nvalues = [0.1, 0.2, 0.1]\n"
         "[soak]\nphase_s = " << phase_s << "\nsettle_s = " << settle_s << "\n"
         "lateness_p99_max_s = 0.02\ndelay_error_p99_max_s = 0.02\noverruns_max = 5\n"
         "memory_growth_max = 0.5\n";
  return dir;
}

bool Mentions(const ojson& why, const std::string& text) {
  for (const auto& w : why) {
    if (w.get<std::string>().find(text) != std::string::npos) return true;
  }
  return false;
}

// Passes, unless the verdict says it failed only on timing the machine's own stalls
// account for (timing_machine_limited, docs/campaigns.md): a shared VM holds a virtual CPU
// for up to 100 ms now and then, whatever the loops do.
TEST(SoakRealtime, AShortSoakPassesWithEveryRealTimePartOfItsVerdict) {
  const std::string dir = WriteCampaign("pass", 10, 3);
  const RunResult r = RunShoal("soak " + dir + "/c.toml --out " + dir + "/out", "soak_rt_pass");
  const ojson soak = ParseJson(ReadFile(dir + "/out/soak.json"));
  ASSERT_TRUE(soak.contains("verdict") && soak.contains("phases")) << r.out << r.err;
  const bool machine = soak.at("timing_machine_limited").get<bool>();
  EXPECT_EQ(r.status, machine ? 1 : 0) << r.out << r.err;
  EXPECT_NE(r.out.find(machine ? "verdict FAIL" : "verdict PASS"), std::string::npos) << r.out;
  EXPECT_EQ(soak.at("verdict"), machine ? "fail" : "pass") << soak.at("reasons").dump();
  if (machine) {
    std::printf("timing missed only where the machine stalled: %s\n",
                soak.at("reasons").dump().c_str());
    EXPECT_NE(r.out.find("where the machine itself stalled"), std::string::npos) << r.out;
  }
  // One minute row: 30 s of ticks and the final one, every vehicle; the soak's 30 s, not
  // the scenario's 600 s.
  ASSERT_EQ(soak.at("minutes").size(), 1u);
  const ojson& m = soak.at("minutes").at(0);
  EXPECT_EQ(m.at("states_expected").get<long long>(), kVehicles * (30 * kRateHz + 1));
  EXPECT_EQ(m.at("states").get<long long>(), m.at("states_expected").get<long long>());
  EXPECT_GT(m.at("lateness_p99_s").get<double>(), 0.0);
  EXPECT_GT(m.at("release_error_p99_s").get<double>(), 0.0);
  EXPECT_EQ(m.at("processes").size(), 5u);  // 2 vehicles, leader, emulator, logger
  ASSERT_EQ(soak.at("phases").size(), 3u);
  long long states = 0;
  for (const auto& p : soak.at("phases")) {
    const ojson& pm = p.at("metrics");
    // Where the run's witness watched the machine (as root), every phase says what it saw.
    EXPECT_EQ(p.at("machine").is_null(), !soak.at("run").at("machine").at("watched").get<bool>())
        << p.dump();
    const bool stalled = p.at("timing_machine_limited").get<bool>();
    EXPECT_EQ(p.at("pass").get<bool>(), !stalled) << p.dump();
    EXPECT_GT(pm.at("lateness_p99_s").get<double>(), 0.0) << p.dump();
    EXPECT_GT(pm.at("release_error_p99_s").get<double>(), 0.0) << p.dump();
    if (!stalled) {
      EXPECT_LE(pm.at("release_error_p99_s").get<double>(), 0.02) << p.dump();
      EXPECT_LE(pm.at("lateness_p99_s").get<double>(), 0.02) << p.dump();
      EXPECT_LE(pm.at("overruns").get<long long>(), 5) << p.dump();
    }
    EXPECT_EQ(pm.at("states").get<long long>(), pm.at("states_expected").get<long long>());
    states += pm.at("states").get<long long>();
  }
  EXPECT_EQ(states, kVehicles * (30 * kRateHz + 1));
  EXPECT_EQ(soak.at("run").at("mode"), "realtime");
  EXPECT_EQ(soak.at("processes").size(), 5u);  // every process's memory judged
}

/// The pid of `process` ("vehicle 2") in a run's resources.csv, or -1.
pid_t PidOf(const std::string& resources_csv, const std::string& process) {
  std::stringstream ss(ReadFile(resources_csv));
  std::string line;
  const std::string key = "," + process + ",";
  while (std::getline(ss, line)) {
    const std::size_t at = line.find(key);
    if (at != std::string::npos) return std::atoi(line.c_str() + at + key.size());
  }
  return -1;
}

/// Follows the log until a vehicle state at or after mission time `t_us`: false after
/// `timeout_s` of wall time.
bool WaitForMissionTime(const std::string& log, std::int64_t t_us, double timeout_s) {
  LogTail tail(log);
  std::int64_t newest = -1;
  const auto t0 = std::chrono::steady_clock::now();
  while (newest < t_us) {
    if (std::chrono::steady_clock::now() - t0 > std::chrono::duration<double>(timeout_s)) {
      return false;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    tail.Poll([&](const std::string& ch, const void* data, int size) {
      if (ch.rfind("SHOAL_STATE_", 0) != 0 || size < 16) return;
      newest = std::max(newest, wire::I64(static_cast<const std::uint8_t*>(data) + 8));
    });
  }
  return true;
}

/// Holds the main thread of `pid` (its control loop) for `hold_s`. A ptrace stop, not
/// SIGSTOP: shoal run stops the whole run at once when a process is stopped by a signal
/// (its parent sees that), while a tracer's stop is seen by the tracer only, so the run
/// goes on and the loop is simply late, as under a long preemption.
bool HoldThread(pid_t pid, double hold_s, std::string* error) {
  if (ptrace(PTRACE_SEIZE, pid, nullptr, nullptr) != 0) {
    *error = "PTRACE_SEIZE: " + std::string(std::strerror(errno));
    return false;
  }
  int status = 0;
  if (ptrace(PTRACE_INTERRUPT, pid, nullptr, nullptr) != 0 ||
      waitpid(pid, &status, __WALL) != pid) {
    *error = "PTRACE_INTERRUPT: " + std::string(std::strerror(errno));
    ptrace(PTRACE_DETACH, pid, nullptr, nullptr);
    return false;
  }
  std::this_thread::sleep_for(std::chrono::duration<double>(hold_s));
  ptrace(PTRACE_DETACH, pid, nullptr, nullptr);
  return true;
}

TEST(SoakRealtime, ALoopHeldInTheLastPhaseFailsThatPhaseOnly) {
  const std::string dir = WriteCampaign("late", 7, 2);
  const std::string out = dir + "/soak.out";
  const pid_t soak = StartShoal("soak " + dir + "/c.toml --out " + dir + "/out", out);
  const std::string log = dir + "/out/soak.lcmlog";
  // Phase 3 is 14-21 s; hold vehicle 2 from 16 s.
  ASSERT_TRUE(WaitForMissionTime(log, 16000000, 60)) << ReadFile(out);
  const pid_t victim = PidOf(log + ".d/resources.csv", "vehicle 2");
  ASSERT_GT(victim, 0) << ReadFile(log + ".d/resources.csv");
  std::string error;
  EXPECT_TRUE(HoldThread(victim, 1.0, &error)) << error;
  EXPECT_EQ(WaitExit(soak, 60, nullptr), 1) << ReadFile(out);
  const ojson s = ParseJson(ReadFile(dir + "/out/soak.json"));
  ASSERT_TRUE(s.contains("verdict") && s.contains("phases")) << ReadFile(out);
  EXPECT_EQ(s.at("verdict"), "fail");
  ASSERT_EQ(s.at("phases").size(), 3u);
  for (int k : {0, 1}) {
    const ojson& p = s.at("phases").at(k);
    if (p.at("timing_machine_limited").get<bool>()) continue;  // the machine stalled there
    EXPECT_FALSE(Mentions(p.at("why"), "loop lateness")) << p.dump();
    EXPECT_LE(p.at("metrics").at("lateness_p99_s").get<double>(), 0.02) << p.dump();
  }
  // 20 ticks of vehicle 2 run late by up to a second: more than 1 % of the phase's
  // 7 s x 20 Hz x 3 loops (420), so its p99 is one of them. No stall of the machine
  // accounts for that, and the verdict says so.
  const ojson& late = s.at("phases").at(2);
  EXPECT_FALSE(late.at("pass").get<bool>());
  EXPECT_FALSE(late.at("timing_machine_limited").get<bool>()) << late.dump();
  EXPECT_FALSE(s.at("timing_machine_limited").get<bool>());
  EXPECT_TRUE(Mentions(late.at("why"), "loop lateness p99")) << late.dump();
  EXPECT_TRUE(Mentions(late.at("why"), "control ticks overran their period (at most 5)"))
      << late.dump();
  EXPECT_GT(late.at("metrics").at("lateness_p99_s").get<double>(), 0.1) << late.dump();
  bool named = false;
  for (const auto& reason : s.at("reasons")) {
    const std::string text = reason.get<std::string>();
    named = named || (text.rfind("phase 3 (channel.delay.base_s = 0.1, 14-21 s)", 0) == 0 &&
                      text.find("loop lateness p99") != std::string::npos);
  }
  EXPECT_TRUE(named) << s.at("reasons").dump();
}

}  // namespace
}  // namespace shoal::testing
