// The soak's per-window lateness: the histograms of the samples since each health report's
// predecessor (health2_t), summed over a window, give that window's quantiles to within
// one bin, however long the history before it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "analysis/run_data.h"
#include "analysis/soak_analysis.h"
#include "runtime/channels.h"
#include "runtime/clock.h"
#include "runtime/log_writer.h"
#include "runtime/messages.h"

namespace shoal {
namespace {

const double kBinRatio = std::exp2(1.0 / LatenessBins::kPerOctave);

std::string Tmp(const std::string& name) {
  const std::string dir = std::string(SHOAL_BINARY_DIR) + "/test_tmp";
  std::system(("mkdir -p " + dir).c_str());
  return dir + "/soak_window_" + name;
}

double ExactQuantile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  const auto rank = static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5);
  return v[rank];
}

TEST(LatenessBins, EdgesAreGeometricAndEveryValueHasABin) {
  EXPECT_EQ(LatenessBins::Index(0.0), 0);
  EXPECT_EQ(LatenessBins::Index(-1e-3), 0);
  EXPECT_EQ(LatenessBins::Index(std::nan("")), 0);
  EXPECT_EQ(LatenessBins::Index(0.99e-6), 0);
  EXPECT_EQ(LatenessBins::Index(1e-6), 1);
  EXPECT_EQ(LatenessBins::Index(1.5e-6), 5);  // 2^(4/8) = 1.414 <= 1.5 < 2^(5/8) = 1.542
  EXPECT_EQ(LatenessBins::Index(1.1), LatenessBins::kCount - 1);
  EXPECT_EQ(LatenessBins::Index(1e300), LatenessBins::kCount - 1);
  for (int i = 0; i + 1 < LatenessBins::kCount; ++i) {
    const double up = LatenessBins::UpperS(i);
    EXPECT_EQ(LatenessBins::Index(up * 0.999), i) << i;
    EXPECT_EQ(LatenessBins::Index(up * 1.001), i + 1) << i;
  }
  EXPECT_TRUE(std::isinf(LatenessBins::UpperS(LatenessBins::kCount - 1)));
}

TEST(LatenessBins, QuantileOfSummedWindowsIsTheExactOneWithinABin) {
  std::mt19937_64 rng(7);
  std::lognormal_distribution<double> late(std::log(300e-6), 1.2);  // 0.3 ms, long tail
  LatenessStats stats;
  std::array<std::int64_t, LatenessBins::kCount> sum{};
  std::int64_t count = 0;
  double max_s = 0.0;
  std::vector<double> all;
  for (int report = 0; report < 40; ++report) {
    for (int k = 0; k < 50 + report; ++k) {
      const double x = late(rng);
      stats.Add(x);
      all.push_back(x);
    }
    const LatenessWindow w = stats.TakeWindow();
    EXPECT_EQ(w.count(), 50 + report);
    for (int i = 0; i < LatenessBins::kCount; ++i) sum[i] += w.bins()[i];
    count += w.count();
    max_s = std::max(max_s, w.max());
  }
  EXPECT_EQ(stats.TakeWindow().count(), 0);  // taken: the next window starts empty
  ASSERT_EQ(count, static_cast<std::int64_t>(all.size()));
  for (double q : {0.0, 0.5, 0.9, 0.99, 0.999, 1.0}) {
    const double exact = ExactQuantile(all, q);
    const double got = LatenessBins::Quantile(sum.data(), count, max_s, q);
    EXPECT_GE(got, exact) << q;
    EXPECT_LE(got, exact * kBinRatio) << q;
  }
  EXPECT_EQ(LatenessBins::Quantile(sum.data(), 0, 0.0, 0.99), 0.0);
}

// One process's reports: since-start figures and the window of the second before.
struct Process {
  int id;
  LatenessStats stats;
  health2_t Report(Micros t) {
    health_t h{};
    h.utime = t;
    h.vehicle_id = id;
    h.ticks = stats.count();
    h.lateness_p50_s = stats.Quantile(0.5);
    h.lateness_p99_s = stats.Quantile(0.99);
    h.lateness_max_s = stats.max();
    return ToLcmHealth2(h, stats.TakeWindow());
  }
};

const char* kScenario = R"([run]
name = "soak_window"
duration_s = 600
control_rate_hz = 50

[swarm]
followers = 2
leader_links = [1]
edges = [[2, 1]]

[control]
k1 = 1
k2 = 1
offsets_m = [[6, 0, 0], [0, 6, 0]]
)";

// Ten minutes of quiet loops (0.2 ms late, release error 0.1 ms) at 50 Hz; in the second
// phase (540-600 s) vehicle 1 is 30 ms late for 100 ticks of 570-572 s: 1.1 % of that
// phase's samples but 0.33 % of vehicle 1's since start.
std::string WriteLateSpikeLog() {
  const std::string path = Tmp("late_spike.lcmlog");
  LogWriter log(path);
  run_status_t st;
  st.utime = 0;
  st.vehicle_id = kLauncherId;
  st.state = "running";
  st.scenario_name = "soak_window";
  st.scenario_toml = kScenario;
  st.followers = 2;
  log.Write(channels::Status(), 0, st);
  std::vector<Process> procs = {{0, {}}, {1, {}}, {2, {}}, {kEmulatorId, {}}};
  for (int s = 1; s <= 600; ++s) {
    for (Process& p : procs) {
      for (int k = 0; k < 50; ++k) {
        const bool spike = p.id == 1 && (s == 571 || s == 572);
        p.stats.Add(spike ? 0.030 : (p.id == kEmulatorId ? 100e-6 : 200e-6));
      }
      log.Write(channels::Health(p.id), s * 1000000LL, p.Report(s * 1000000LL));
    }
  }
  return path;
}

TEST(SoakWindow, ALateSpikeAfterALongQuietHistoryFailsItsPhase) {
  SoakInput in;
  in.log = WriteLateSpikeLog();
  in.phases = {{0.0, 540.0, "quiet"}, {540.0, 600.0, "late"}};
  in.settle_s = 10.0;
  in.engine = "realtime";
  in.report = nlohmann::json::object();  // no run report: only the windows are judged here
  SoakResult r;
  std::string error;
  ASSERT_TRUE(AnalyseSoak(in, &r, &error)) << error;
  ASSERT_EQ(r.phases.size(), 2u);
  const double quiet = r.phases[0].metrics["lateness_p99_s"].get<double>();
  const double late = r.phases[1].metrics["lateness_p99_s"].get<double>();
  EXPECT_GE(quiet, 200e-6);
  EXPECT_LE(quiet, 200e-6 * kBinRatio);
  // 100 of the phase's 9000 loop samples are 30 ms: its p99 rank (8909) is among them.
  EXPECT_EQ(late, 0.030);
  for (const SoakPhaseResult& p : r.phases) {
    const double release = p.metrics["release_error_p99_s"].get<double>();
    EXPECT_GE(release, 100e-6);
    EXPECT_LE(release, 100e-6 * kBinRatio);
  }
  auto names_lateness = [](const SoakPhaseResult& p) {
    return std::any_of(p.why.begin(), p.why.end(), [](const std::string& w) {
      return w.find("loop lateness p99 30 ms > target 2 ms") != std::string::npos;
    });
  };
  EXPECT_FALSE(names_lateness(r.phases[0]));
  EXPECT_TRUE(names_lateness(r.phases[1]));
  EXPECT_TRUE(std::any_of(r.reasons.begin(), r.reasons.end(), [](const std::string& s) {
    return s.rfind("phase 2 (late, 540-600 s): loop lateness p99", 0) == 0;
  })) << ::testing::PrintToString(r.reasons);
  // The since-start p99s reported within that phase never pass 2 ms: a window judged by
  // their maximum (as before the histograms) would have passed it.
  RunData run;
  ASSERT_TRUE(LoadRunLog(in.log, LoadOptions(), &run, &error)) << error;
  double since_start_max = 0.0;
  for (const HealthRecord& h : run.health) {
    if (h.utime >= 540000000) since_start_max = std::max(since_start_max, h.lateness_p99_s);
  }
  EXPECT_LT(since_start_max, 0.001);
  // The minute holding the spike says so too; the minute before does not.
  ASSERT_EQ(r.minutes.size(), 10u);
  EXPECT_EQ(r.minutes[9].lateness_p99_s, 0.030);
  EXPECT_LE(r.minutes[8].lateness_p99_s, 200e-6 * kBinRatio);
}

// Two quiet phases of 60 s at 50 Hz; vehicle 1 overruns 3 ticks at 90 s, in the second.
std::string WriteOverrunLog() {
  const std::string path = Tmp("overruns.lcmlog");
  LogWriter log(path);
  run_status_t st;
  st.utime = 0;
  st.vehicle_id = kLauncherId;
  st.state = "running";
  st.scenario_name = "soak_window";
  st.scenario_toml = kScenario;
  st.followers = 2;
  log.Write(channels::Status(), 0, st);
  std::vector<Process> procs = {{0, {}}, {1, {}}, {2, {}}, {kEmulatorId, {}}};
  for (int s = 1; s <= 120; ++s) {
    for (Process& p : procs) {
      for (int k = 0; k < 50; ++k) p.stats.Add(200e-6);
      health2_t h = p.Report(s * 1000000LL);
      h.overruns = (p.id == 1 && s >= 90) ? 3 : 0;  // since the process started
      log.Write(channels::Health(p.id), s * 1000000LL, h);
    }
  }
  return path;
}

TEST(SoakWindow, APhaseFailsOnMoreOverrunsThanItsTargetAllows) {
  SoakInput in;
  in.log = WriteOverrunLog();
  in.phases = {{0.0, 60.0, "first"}, {60.0, 120.0, "second"}};
  in.settle_s = 10.0;
  in.engine = "realtime";
  in.report = nlohmann::json::object();
  auto judge = [&](long long overruns_max) {
    in.targets.overruns_max = overruns_max;
    SoakResult r;
    std::string error;
    EXPECT_TRUE(AnalyseSoak(in, &r, &error)) << error;
    return r;
  };
  // The log holds no vehicle state, so a phase fails on re-convergence too: only the
  // overrun reasons are judged here.
  auto overran = [](const std::vector<std::string>& why) {
    std::vector<std::string> out;
    for (const std::string& w : why) {
      if (w.find("overran") != std::string::npos) out.push_back(w);
    }
    return out;
  };
  for (long long allowed : {0LL, 2LL, 3LL}) {
    const SoakResult r = judge(allowed);
    ASSERT_EQ(r.phases.size(), 2u);
    EXPECT_EQ(r.phases[0].metrics["overruns"].get<long long>(), 0);
    EXPECT_EQ(r.phases[1].metrics["overruns"].get<long long>(), 3);
    EXPECT_TRUE(overran(r.phases[0].why).empty()) << allowed;
    const std::vector<std::string> second = overran(r.phases[1].why);
    const std::string expected =
        allowed == 0 ? "3 control ticks overran their period"
                     : "3 control ticks overran their period (at most 2)";
    if (allowed < 3) {
      ASSERT_EQ(second.size(), 1u) << allowed;
      EXPECT_EQ(second[0], expected);
      EXPECT_TRUE(std::any_of(r.reasons.begin(), r.reasons.end(), [&](const std::string& s) {
        return s == "phase 2 (second, 60-120 s): " + expected;
      })) << ::testing::PrintToString(r.reasons);
    } else {
      EXPECT_TRUE(second.empty()) << ::testing::PrintToString(second);
    }
  }
}

// Two phases of 10 s at 50 Hz (leader and two vehicles: three loops). In the second, each
// report at a time in `held` (the report at 15 s covers 14-15 s) holds `late` ticks of each
// loop 100 ms late, 4 more overruns of each, and 8 of the emulator's releases 50 ms late.
// The phase has 1650 loop samples (reports at 10-20 s; its p99 is beyond the 1633 earliest)
// and 550 release samples (p99 beyond the 544 earliest). With `states`, every vehicle's
// state at every tick, the formation exact.
std::string WriteStalledLog(const std::string& name, const std::vector<int>& held, int late,
                            bool states = false) {
  const std::string path = Tmp(name + ".lcmlog");
  LogWriter log(path);
  run_status_t st;
  st.utime = 0;
  st.vehicle_id = kLauncherId;
  st.state = "running";
  st.scenario_name = "soak_window";
  st.scenario_toml = kScenario;
  st.followers = 2;
  log.Write(channels::Status(), 0, st);
  std::vector<Process> procs = {{0, {}}, {1, {}}, {2, {}}, {kEmulatorId, {}}};
  for (Micros t = 0; states && t <= 20000000; t += 20000) {
    const Vec5 still = Vec5::Zero();
    const Vec3 at[] = {Vec3::Zero(), Vec3(6, 0, 0), Vec3(0, 6, 0)};
    for (int id = 0; id < 3; ++id) {
      StateMsg m;
      m.vehicle_id = id;
      m.seq = static_cast<std::int32_t>(t / 20000);
      m.utime = t;
      m.eta = still;
      m.eta.head<3>() = at[id];
      m.eta_dot = still;
      m.nu = still;
      m.flags = id == 0 ? StateMsg::kFlagLeader : 0;
      log.Write(channels::State(id), t, ToLcm(m));
    }
  }
  int overruns = 0;
  for (int s = 1; s <= 20; ++s) {
    const bool stalled = std::find(held.begin(), held.end(), s) != held.end();
    overruns += stalled ? 4 : 0;
    for (Process& p : procs) {
      const bool emulator = p.id == kEmulatorId;
      for (int k = 0; k < 50; ++k) {
        const bool slow = stalled && k < (emulator ? 8 : late);
        p.stats.Add(slow ? (emulator ? 0.050 : 0.100) : 200e-6);
      }
      health2_t h = p.Report(s * 1000000LL);
      h.overruns = emulator ? 0 : overruns;
      log.Write(channels::Health(p.id), s * 1000000LL, h);
    }
  }
  return path;
}

struct StallCase {
  SoakInput in;
  explicit StallCase(const std::string& log) {
    in.log = log;
    in.phases = {{0.0, 10.0, "first"}, {10.0, 20.0, "second"}};
    in.settle_s = 1.0;
    in.engine = "realtime";
    in.report = nlohmann::json::object();
    in.targets.lateness_p99_max_s = 0.002;
    in.targets.delay_error_p99_max_s = 0.001;
    in.targets.overruns_max = 0;
  }
  SoakResult Judge(bool watched, std::vector<SoakStall> stalls) {
    in.machine_watched = watched;
    in.machine_stalls = std::move(stalls);
    SoakResult r;
    std::string error;
    EXPECT_TRUE(AnalyseSoak(in, &r, &error)) << error;
    return r;
  }
};

std::vector<std::string> TimingWhy(const SoakPhaseResult& p) {
  std::vector<std::string> out;
  for (const std::string& w : p.why) {
    if (w.find("overran") != std::string::npos || w.find("p99") != std::string::npos) {
      out.push_back(w);
    }
  }
  return out;
}

// A phase late where the machine stalled says that the stall accounts for it only when the
// stall overlaps the reports holding those ticks and could have delayed that many of them
// that late: 99 ms at a 20 ms period, 6 ticks of each loop, up to 198 ms late; at the
// reports' 50 releases a second, 6 releases. A 30 ms stall accounts for 3 overruns of each
// loop (not 4) and for no tick 100 ms late; a 45 ms one for every overrun but not for the
// lateness. A stall the witness saw on both CPUs is one. A stall in another report's time,
// or an unwatched machine, accounts for nothing. The phase fails either way.
TEST(SoakWindow, TheMachinesOwnStallAccountsForTheLateTicksItCouldHaveDelayed) {
  StallCase c(WriteStalledLog("stalled", {15}, 6));
  const SoakResult held = c.Judge(true, {{14.5, 0.099}, {14.501, 0.098}});  // both CPUs
  ASSERT_EQ(held.phases.size(), 2u);
  const SoakPhaseResult& second = held.phases[1];
  EXPECT_EQ(second.metrics["overruns"].get<long long>(), 12);
  EXPECT_EQ(second.metrics["lateness_p99_s"].get<double>(), 0.100);
  EXPECT_EQ(second.metrics["release_error_p99_s"].get<double>(), 0.050);
  EXPECT_FALSE(second.pass);
  EXPECT_TRUE(second.timing_machine_limited) << ::testing::PrintToString(second.why);
  EXPECT_EQ(second.machine["complete"], true);
  EXPECT_EQ(second.machine["stall_count"], 1);
  EXPECT_EQ(second.machine["worst_stall_s"], 0.099);
  EXPECT_EQ(second.machine["worst_stall_at_s"], 14.5);
  EXPECT_EQ(second.machine["late_ticks_accounted"], 18);
  EXPECT_EQ(second.machine["overruns_accounted"], 12);
  EXPECT_EQ(second.machine["late_releases_accounted"], 6);
  EXPECT_EQ(second.machine["delay_errors_accounted"], 0);
  const std::vector<std::string> why = TimingWhy(second);
  ASSERT_EQ(why.size(), 3u) << ::testing::PrintToString(second.why);
  for (const std::string& w : why) {
    EXPECT_NE(w.find("; the machine itself stalled 1 time(s) within the phase's reach (worst "
                     "99 ms, at t = 14.5 s), which accounts for it"),
              std::string::npos) << w;
  }
  // Its re-convergence failed too (the log holds no vehicle state): not the machine's.
  EXPECT_GT(second.why.size(), why.size());
  EXPECT_FALSE(held.phases[0].timing_machine_limited);
  EXPECT_EQ(held.phases[0].machine["stall_count"], 0);
  EXPECT_FALSE(held.pass);
  EXPECT_FALSE(held.timing_machine_limited);

  const SoakResult shorter = c.Judge(true, {{14.5, 0.030}, {14.51, 0.025}});
  EXPECT_FALSE(shorter.phases[1].timing_machine_limited);
  EXPECT_EQ(shorter.phases[1].machine["late_ticks_accounted"], 0);
  EXPECT_EQ(shorter.phases[1].machine["overruns_accounted"], 9);
  for (const std::string& w : TimingWhy(shorter.phases[1])) {
    EXPECT_EQ(w.find("machine"), std::string::npos) << w;
  }
  // Two 30 ms stalls on two CPUs, overlapping: one stall of 30 ms, not of their 50 ms union.
  EXPECT_EQ(c.Judge(true, {{14.5, 0.030}, {14.52, 0.030}}).phases[1].machine["overruns_accounted"],
            9);
  const SoakResult overruns_only = c.Judge(true, {{14.5, 0.045}});
  EXPECT_EQ(overruns_only.phases[1].machine["overruns_accounted"], 12);
  EXPECT_EQ(overruns_only.phases[1].machine["late_ticks_accounted"], 0);
  EXPECT_FALSE(overruns_only.phases[1].timing_machine_limited);
  // 48 ms: ticks up to 96 ms late, and the 100 ms ones are in a bin that reaches beyond.
  EXPECT_EQ(c.Judge(true, {{14.5, 0.048}}).phases[1].machine["late_ticks_accounted"], 0);
  // 97 ms: (97 + 2) ms of releases at 50 a second, 5 of them.
  EXPECT_EQ(c.Judge(true, {{14.5, 0.097}}).phases[1].machine["late_releases_accounted"], 5);
  // Within the phase's reach (the report at 10 s covers 9-10 s) but not in the time of the
  // report that holds the late ticks.
  const SoakResult elsewhere = c.Judge(true, {{9.2, 0.099}});
  EXPECT_EQ(elsewhere.phases[1].machine["stall_count"], 1);
  EXPECT_EQ(elsewhere.phases[1].machine["late_ticks_accounted"], 0);
  EXPECT_FALSE(elsewhere.phases[1].timing_machine_limited);
  EXPECT_EQ(c.Judge(true, {{8.5, 0.099}}).phases[1].machine["stall_count"], 0);
  const SoakResult unwatched = c.Judge(false, {{14.5, 0.099}});
  EXPECT_FALSE(unwatched.phases[1].timing_machine_limited);
  EXPECT_TRUE(unwatched.phases[1].machine.is_null());
  // Stalls the witness dropped for want of room after 12 s: the second phase says so.
  c.in.machine_complete_until_s = 12.0;
  EXPECT_EQ(c.Judge(true, {{14.5, 0.099}}).phases[1].machine["complete"], false);
}

// A stall gives each loop its ticks once: across the two reports it overlaps (6 of the 12
// late ticks of each loop, 6 of its 8 overruns), also when they are in two phases, and
// not lent to ticks later than short stalls could make them (ten 3 ms stalls beside a
// 99 ms one account for no tick 100 ms late).
TEST(SoakWindow, AStallAccountsForItsTicksOnce) {
  StallCase across(WriteStalledLog("stalled_across", {15, 16}, 6));
  const SoakResult a = across.Judge(true, {{14.95, 0.099}});
  EXPECT_EQ(a.phases[1].machine["late_ticks_accounted"], 18);
  EXPECT_EQ(a.phases[1].machine["overruns_accounted"], 18);
  EXPECT_FALSE(a.phases[1].timing_machine_limited);

  StallCase phases(WriteStalledLog("stalled_phases", {9, 10}, 6));
  const SoakResult two = phases.Judge(true, {{8.98, 0.099}});
  EXPECT_EQ(two.phases[0].machine["late_ticks_accounted"], 18);
  EXPECT_EQ(two.phases[0].machine["overruns_accounted"], 12);
  EXPECT_EQ(two.phases[0].machine["late_releases_accounted"], 6);
  EXPECT_EQ(two.phases[1].machine["stall_count"], 1);
  EXPECT_EQ(two.phases[1].machine["late_ticks_accounted"], 0);
  EXPECT_EQ(two.phases[1].machine["overruns_accounted"], 6);
  EXPECT_EQ(two.phases[1].machine["late_releases_accounted"], 0);

  StallCase pooled(WriteStalledLog("stalled_pooled", {15}, 12));
  std::vector<SoakStall> stalls = {{14.1, 0.099}};
  for (int k = 0; k < 10; ++k) stalls.push_back({14.3 + 0.05 * k, 0.003});
  const SoakResult p = pooled.Judge(true, stalls);
  EXPECT_EQ(p.phases[1].machine["stall_count"], 11);
  EXPECT_EQ(p.phases[1].machine["late_ticks_accounted"], 18);
  EXPECT_FALSE(p.phases[1].timing_machine_limited);
}

// With nothing else wrong (every process ran, every state logged, the formation held, no
// memory growth), a soak that missed only timing the machine's stalls account for says so
// as a whole; one stall too short to account for it, and the verdict is a plain failure.
TEST(SoakWindow, AVerdictFailedOnlyWhereTheMachineStalledSaysSo) {
  StallCase c(WriteStalledLog("stalled_clean", {15}, 6, true));
  c.in.report = {{"all_processes_ok", true}, {"log_complete", true}};
  c.in.resources_csv = Tmp("stalled_clean_resources.csv");
  std::ofstream(c.in.resources_csv)
      << "sim_time_s,wall_time_s,process,pid,rss_kib,cpu_s\n"
         "0,0,vehicle 1,100,5000,0\n12,12,vehicle 1,100,5000,0.1\n20,20,vehicle 1,100,5000,0.2\n";
  const SoakResult stalled = c.Judge(true, {{14.5, 0.099}});
  EXPECT_FALSE(stalled.pass);
  EXPECT_TRUE(stalled.timing_machine_limited) << ::testing::PrintToString(stalled.reasons);
  EXPECT_EQ(stalled.reasons.size(), 3u) << ::testing::PrintToString(stalled.reasons);
  EXPECT_TRUE(stalled.phases[0].pass) << ::testing::PrintToString(stalled.phases[0].why);
  EXPECT_TRUE(stalled.phases[1].metrics["reconverged"].get<bool>());
  const nlohmann::ordered_json j = SoakJson(stalled);
  EXPECT_EQ(j["verdict"], "fail");
  EXPECT_EQ(j["timing_machine_limited"], true);
  EXPECT_EQ(j["phases"][1]["timing_machine_limited"], true);
  const SoakResult plain = c.Judge(true, {{14.5, 0.030}});
  EXPECT_FALSE(plain.pass);
  EXPECT_FALSE(plain.timing_machine_limited);
  const SoakResult quiet = c.Judge(true, {});
  EXPECT_FALSE(quiet.timing_machine_limited);
}

TEST(SoakWindow, ReportsKeepTheirWindowAndADamagedHistogramIsRejected) {
  const std::string path = Tmp("damaged.lcmlog");
  {
    LogWriter log(path);
    Process p{1, {}};
    for (int k = 0; k < 10; ++k) p.stats.Add(k * 1e-4);
    health2_t good = p.Report(1000000);
    log.Write(channels::Health(1), 1000000, good);
    health2_t negative = good;
    negative.utime = 2000000;
    negative.lateness_window_bins[3] = -1;
    negative.lateness_window_count -= 1;
    log.Write(channels::Health(1), 2000000, negative);
    health2_t wrong_sum = good;
    wrong_sum.utime = 3000000;
    wrong_sum.lateness_window_count += 1;
    log.Write(channels::Health(1), 3000000, wrong_sum);
    health_t older{};  // an older build's report: no window
    older.utime = 4000000;
    older.vehicle_id = 1;
    older.lateness_p99_s = 0.5;
    log.Write(channels::Health(1), 4000000, older);
  }
  RunData run;
  std::string error;
  ASSERT_TRUE(LoadRunLog(path, LoadOptions(), &run, &error)) << error;
  ASSERT_EQ(run.health.size(), 2u);
  EXPECT_EQ(run.rejected, 2);
  const HealthRecord& h = run.health[0];
  EXPECT_EQ(h.lateness_window_count, 10);
  EXPECT_DOUBLE_EQ(h.lateness_window_max_s, 9e-4);
  std::int64_t sum = 0;
  for (const LatenessBinCount& b : h.lateness_window) sum += b.count;
  EXPECT_EQ(sum, 10);
  EXPECT_EQ(h.lateness_window.front().bin, 0);  // the sample of 0 s
  EXPECT_EQ(run.health[1].lateness_window_count, -1);
  EXPECT_EQ(run.health[1].lateness_p99_s, 0.5);
}

}  // namespace
}  // namespace shoal
