// shoal_analysis on synthetic logs written with the real log writer: known answers for
// the formation, channel and health metrics; damaged, truncated, empty and non-LCM files.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include <shoal/clock_tick_t.hpp>
#include <shoal/clock_window_t.hpp>

#include "analysis/analysis.h"
#include "analysis/analysis_text.h"
#include "analysis/csv.h"
#include "analysis/run_data.h"
#include "runtime/channels.h"
#include "runtime/lcm_bus.h"
#include "runtime/log_reader.h"
#include "runtime/log_writer.h"
#include "runtime/messages.h"

namespace shoal {
namespace {

constexpr Micros kPeriod = 20000;  // 50 Hz
constexpr double kPi = 3.14159265358979323846;

std::string Tmp(const std::string& name) {
  const std::string dir = std::string(SHOAL_BINARY_DIR) + "/test_tmp";
  std::system(("mkdir -p " + dir).c_str());
  // Per test: ctest runs each test as its own process, in parallel, and several tests
  // write logs with the same helper.
  const ::testing::TestInfo* t = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::string test = t != nullptr ? std::string(t->name()) + "_" : std::string();
  return dir + "/analysis_" + test + name;
}

std::string ReadBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}
void WriteBytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << bytes;
}

// Two followers: 1 hears the leader (constant 0.1 s), 2 hears 1 (constant 0.03 s, a link
// override). Offsets d_1 = (6, 0, 0), d_2 = (0, 6, 0).
const char* kScenario = R"([run]
name = "known_answers"
duration_s = 10
control_rate_hz = 50

[swarm]
followers = 2
leader_links = [1]
edges = [[2, 1]]
neighbour_timeout_s = 1.0

[control]
k1 = 1
k2 = 1
offsets_m = [[6, 0, 0], [0, 6, 0]]

[channel.delay]
model = "constant"
base_s = 0.1

[[channel.link]]
from = 1
to = 2
delay = { model = "constant", base_s = 0.03 }
)";

run_status_t Status(Micros t, int id, const std::string& state, const std::string& toml,
                    int followers = 2) {
  run_status_t st;
  st.utime = t;
  st.vehicle_id = id;
  st.seq = 0;
  st.state = state;
  st.scenario_name = "known_answers";
  st.scenario_toml = toml;
  st.seed = 1;
  st.followers = followers;
  st.message = "";
  return st;
}

StateMsg State(int id, Micros t, const Vec5& eta, const Vec5& eta_dot, int flags = 0) {
  StateMsg m;
  m.vehicle_id = id;
  m.seq = static_cast<std::int32_t>(t / kPeriod);
  m.utime = t;
  m.eta = eta;
  m.eta_dot = eta_dot;
  m.nu = eta_dot;
  m.flags = flags;
  return m;
}

ChannelDecision Decision(int from, int to, Micros send, double delay_s, Micros deliver,
                         std::int8_t status) {
  ChannelDecision d;
  d.sender = from;
  d.receiver = to;
  d.msg_seq = static_cast<std::int32_t>(send / kPeriod);
  d.send_utime = send;
  d.delay_s = delay_s;
  d.deliver_utime = deliver;
  d.status = static_cast<ChannelDecision::Status>(status);
  return d;
}

channel_event_t Event(int from, int to, Micros send, double delay_s, Micros deliver,
                      std::int8_t status, std::int32_t seq) {
  return ToLcm(Decision(from, to, send, delay_s, deliver, status), seq);
}

health_t Health(Micros t, int id, double p99, std::int64_t overruns) {
  health_t h{};
  h.utime = t;
  h.vehicle_id = id;
  h.ticks = t / kPeriod + 1;
  h.lateness_p50_s = p99 / 2;
  h.lateness_p99_s = p99;
  h.lateness_max_s = 2 * p99;
  h.overruns = overruns;
  return h;
}

RunData Load(const std::string& path, std::string* err = nullptr) {
  RunData run;
  std::string e;
  EXPECT_TRUE(LoadRunLog(path, LoadOptions(), &run, &e)) << e;
  if (err) *err = e;
  return run;
}

// The leader moves north at 1 m/s. Follower 1 is off its slot by (3, 4, 0) m with a 0.2 m/s
// sway velocity error, 0.1 rad pitch error and a heading across +-pi (0.1 rad after
// wrapping) until t = 4 s; from then on off by (0.06, 0.08, 0) m and 0.01 m/s.
// Follower 2 sits exactly in its slot. The leader's state at t = 6 s is missing.
std::string WriteFormationLog(int ticks) {
  const std::string path = Tmp("formation.lcmlog");
  LogWriter log(path);
  log.Write(channels::Status(), 0, Status(0, kLauncherId, "running", kScenario));
  for (int k = 0; k < ticks; ++k) {
    const Micros t = k * kPeriod;
    const double ts = ToSeconds(t);
    const bool early = t < 4000000;
    const Vec5 eta0 = (Vec5() << ts, 0, 0, 0, -kPi + 0.05).finished();
    const Vec5 v0 = (Vec5() << 1, 0, 0, 0, 0).finished();
    const Vec3 e = early ? Vec3(3, 4, 0) : Vec3(0.06, 0.08, 0);
    Vec5 eta1 = eta0;
    eta1.head<3>() += Vec3(6, 0, 0) + e;
    eta1(3) = 0.1;
    eta1(4) = kPi - 0.05;
    const Vec5 v1 = (Vec5() << 1, early ? 0.2 : 0.01, 0, 0, 0).finished();
    Vec5 eta2 = eta0;
    eta2.head<3>() += Vec3(0, 6, 0);
    if (t != 6000000) log.Write(channels::State(0), t, ToLcm(State(0, t, eta0, v0, StateMsg::kFlagLeader)));
    log.Write(channels::State(1), t, ToLcm(State(1, t, eta1, v1)));
    log.Write(channels::State(2), t, ToLcm(State(2, t, eta2, v0)));
  }
  return path;
}

TEST(Analysis, FollowerAtKnownErrorGivesKnownErrorsAndConvergence) {
  const int ticks = 500;  // 0 .. 9.98 s
  const RunData run = Load(WriteFormationLog(ticks));
  ASSERT_TRUE(run.has_scenario);
  EXPECT_EQ(run.scenario_origin, "log");
  EXPECT_EQ(run.scenario_name, "known_answers");
  EXPECT_EQ(run.followers, 2);
  ASSERT_EQ(run.vehicles.size(), 3u);
  EXPECT_EQ(run.vehicles[0].samples.size(), static_cast<std::size_t>(ticks - 1));
  const RunAnalysis a = AnalyseRun(run);
  ASSERT_TRUE(a.has_formation);
  EXPECT_EQ(a.mode, "unknown");  // neither clock ticks nor an emulator
  // Swarm level: converged when follower 1 came within tolerance.
  EXPECT_TRUE(a.summary.converged);
  EXPECT_DOUBLE_EQ(a.summary.convergence_time_s, 4.0);
  EXPECT_NEAR(a.summary.final_worst.position_m, 0.1, 1e-9);
  EXPECT_NEAR(a.summary.final_worst.velocity_mps, 0.01, 1e-12);
  EXPECT_NEAR(a.summary.final_worst.attitude_rad, std::sqrt(0.02), 1e-9);
  EXPECT_NEAR(a.summary.max_position_error_m, 5.0, 1e-9);
  EXPECT_EQ(a.complete_samples, ticks - 1);  // the leader's missing sample
  EXPECT_DOUBLE_EQ(a.summary.sim_time_s, ToSeconds((ticks - 1) * kPeriod));
  // Per follower, aligned with the samples.
  ASSERT_EQ(a.followers.size(), 2u);
  const FollowerAnalysis& f1 = a.followers[0];
  ASSERT_EQ(f1.errors.size(), static_cast<std::size_t>(ticks));
  EXPECT_NEAR(f1.errors[50].position_m, 5.0, 1e-9);
  EXPECT_NEAR(f1.errors[50].velocity_mps, 0.2, 1e-12);
  EXPECT_NEAR(f1.errors[50].attitude_rad, std::sqrt(0.02), 1e-9);  // heading wrapped
  EXPECT_TRUE(std::isnan(f1.errors[300].position_m));              // t = 6 s: no leader
  EXPECT_NEAR(f1.errors[301].position_m, 0.1, 1e-9);
  EXPECT_EQ(f1.compared, ticks - 1);
  EXPECT_DOUBLE_EQ(f1.convergence_time_s, 4.0);
  EXPECT_DOUBLE_EQ(a.followers[1].convergence_time_s, 0.0);
  EXPECT_NEAR(a.followers[1].final_errors.position_m, 0.0, 1e-12);
  ASSERT_EQ(a.final_errors.size(), 2u);
  EXPECT_NEAR(a.final_errors[0].position_m, 0.1, 1e-9);
  // The leader's path: 1 m/s north for (ticks - 1) periods, minus nothing (the missing
  // sample is on the straight line).
  EXPECT_NEAR(a.leader_path_length_m, ToSeconds((ticks - 1) * kPeriod), 1e-9);
}

TEST(Analysis, NotConvergedWhenTheLastSampleViolates) {
  const std::string path = Tmp("late_violation.lcmlog");
  {
    LogWriter log(path);
    log.Write(channels::Status(), 0, Status(0, kLauncherId, "running", kScenario));
    for (int k = 0; k < 100; ++k) {
      const Micros t = k * kPeriod;
      const Vec5 z = Vec5::Zero();
      Vec5 e1 = z, e2 = z;
      e1.head<3>() = Vec3(6, 0, 0);
      e2.head<3>() = Vec3(0, 6, k == 99 ? 7 : 0);  // 7 m off at the very end
      log.Write(channels::State(0), t, ToLcm(State(0, t, z, z)));
      log.Write(channels::State(1), t, ToLcm(State(1, t, e1, z)));
      log.Write(channels::State(2), t, ToLcm(State(2, t, e2, z)));
    }
  }
  const RunAnalysis a = AnalyseRun(Load(path));
  EXPECT_FALSE(a.summary.converged);
  EXPECT_EQ(a.summary.convergence_time_s, -1.0);
  EXPECT_NEAR(a.summary.final_worst.position_m, 7.0, 1e-12);
  EXPECT_TRUE(a.followers[0].converged);
  EXPECT_FALSE(a.followers[1].converged);
}

// Leader -> 1: tau = 0.1 s, every 4th message lost, message 9 dropped by a full queue.
// 1 -> 2: tau = 0.03 s, delivered at the next tick boundary, 0.04 s (tick quantisation).
// Written as the lockstep emulator writes it: one clock message and one SHOAL_CHANNEL batch
// per window of 3 ticks; `legacy`: as logs before batching, one clock message per tick
// and one channel_event_t per decision.
std::string WriteChannelLog(int ticks, bool with_states = true, bool legacy = false,
                            std::int8_t status_at_9 = 2) {
  const std::string path = Tmp(legacy ? "channel_legacy.lcmlog" : "channel.lcmlog");
  LogWriter log(path);
  log.Write(channels::Status(), 0, Status(0, kLauncherId, "running", kScenario));
  const int window = legacy ? 1 : 3;
  std::int32_t seq = 0;
  ChannelEventBatch batch;
  for (int k = 0; k < ticks; ++k) {
    const Micros t = k * kPeriod;
    if (legacy) {  // the clock type of those logs: one tick per message, no n_ticks
      clock_tick_t c{};
      c.utime = t;
      c.vehicle_id = kEmulatorId;
      c.tick = k;
      c.period_us = kPeriod;
      c.final_tick = k == ticks - 1 ? 1 : 0;
      log.Write(channels::Clock(), t, c);
    } else if (k % window == 0) {
      clock_window_t c{};
      c.utime = t;
      c.vehicle_id = kEmulatorId;
      c.tick = k;
      c.n_ticks = std::min(window, ticks - k);
      c.period_us = kPeriod;
      c.final_tick = k + c.n_ticks == ticks ? 1 : 0;
      log.Write(channels::Clock(), t, c);
    }
    if (with_states) {
      for (int id = 0; id <= 2; ++id) {
        log.Write(channels::State(id), t, ToLcm(State(id, t, Vec5::Zero(), Vec5::Zero())));
      }
    }
    const std::int8_t s01 = k == 9 ? status_at_9 : (k % 4 == 3 ? 1 : 0);
    const ChannelDecision d01 = Decision(0, 1, t, 0.1, s01 == 0 ? t + 100000 : 0, s01);
    const ChannelDecision d12 = Decision(1, 2, t, 0.03, t + 40000, 0);
    if (legacy) {
      log.Write(channels::ChannelEvents(), t, ToLcm(d01, seq++));
      log.Write(channels::ChannelEvents(), t, ToLcm(d12, seq++));
    } else {
      batch.Add(d01);
      batch.Add(d12);
      if (k % window == window - 1 || k == ticks - 1) {
        batch.Flush([&](const channel_events_t& b) { log.Write(channels::ChannelEvents(), t, b); });
      }
    }
  }
  return path;
}

// Window clocks give one record per tick; batches one record per decision; a log written
// before batching (single events, a clock message per tick) reads the same.
TEST(RunData, WindowClocksAndEventBatchesReadLikeSingleOnes) {
  const int ticks = 400;
  const RunData batched = Load(WriteChannelLog(ticks));
  const RunData legacy = Load(WriteChannelLog(ticks, true, true));
  // Each window as its ticks: (tick, time, whether it is the run's last).
  const auto per_tick = [](const RunData& run) {
    std::vector<std::tuple<std::int64_t, Micros, bool>> t;
    for (const ClockRecord& c : run.clock) {
      for (std::int32_t k = 0; k < c.n_ticks; ++k) {
        t.emplace_back(c.tick + k, c.utime + k * c.period_us,
                       c.final_tick && k == c.n_ticks - 1);
      }
    }
    return t;
  };
  const auto b = per_tick(batched), l = per_tick(legacy);
  EXPECT_EQ(ClockTicks(batched), ticks);
  EXPECT_EQ(ClockTicks(legacy), ticks);
  ASSERT_EQ(b.size(), static_cast<std::size_t>(ticks));
  ASSERT_EQ(l.size(), b.size());
  for (int k = 0; k < ticks; ++k) {
    EXPECT_EQ(std::get<0>(b[k]), k);
    EXPECT_EQ(std::get<1>(b[k]), k * kPeriod);
    EXPECT_EQ(std::get<2>(b[k]), k == ticks - 1) << k;
    EXPECT_EQ(l[k], b[k]) << k;
  }
  ASSERT_EQ(batched.channel_events.size(), 2u * ticks);
  ASSERT_EQ(legacy.channel_events.size(), batched.channel_events.size());
  for (std::size_t k = 0; k < batched.channel_events.size(); ++k) {
    const ChannelEventRecord& a = batched.channel_events[k];
    const ChannelEventRecord& b = legacy.channel_events[k];
    EXPECT_EQ(a.send_utime, b.send_utime);
    EXPECT_EQ(a.deliver_utime, b.deliver_utime);
    EXPECT_EQ(a.delay_s, b.delay_s);
    EXPECT_EQ(a.sender, b.sender);
    EXPECT_EQ(a.receiver, b.receiver);
    EXPECT_EQ(a.status, b.status);
    EXPECT_EQ(a.msg_seq, b.msg_seq);
  }
  EXPECT_EQ(batched.undecodable + batched.rejected, 0);
  EXPECT_EQ(legacy.undecodable + legacy.rejected, 0);
  EXPECT_EQ(AnalyseRun(batched).ticks, ticks);
  EXPECT_EQ(AnalyseRun(legacy).ticks, ticks);
}

// A damaged batch is refused whole and counted once; a window clock covering no tick, or
// ticks whose times overflow, too.
TEST(RunData, DamagedBatchOrEmptyWindowIsCountedNotKept) {
  const std::string path = Tmp("damaged_batch.lcmlog");
  {
    LogWriter log(path);
    log.Write(channels::Status(), 0, Status(0, kLauncherId, "running", kScenario));
    ChannelEventBatch batch;
    batch.Add(Decision(0, 1, 0, 0.1, 100000, 0));
    batch.Add(Decision(1, 2, 0, 0.03, 40000, 0));
    std::vector<unsigned char> bytes;
    batch.Flush([&](const channel_events_t& b) {
      bytes.resize(static_cast<std::size_t>(b.getEncodedSize()));
      b.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
    });
    // The second event's reason length made too large: the batch no longer adds up.
    std::vector<unsigned char> bad = bytes;
    bad[bad.size() - 2] = 0x7f;
    log.WriteRaw(channels::ChannelEvents(), 0, bad.data(), static_cast<int>(bad.size()));
    // Truncated by one byte.
    log.WriteRaw(channels::ChannelEvents(), 0, bytes.data(), static_cast<int>(bytes.size()) - 1);
    // A single (pre-batching) event's fingerprint and nothing else.
    const channel_event_t single = Event(0, 1, 0, 0.1, 100000, 0, 0);
    std::vector<unsigned char> one(static_cast<std::size_t>(single.getEncodedSize()));
    single.encode(one.data(), 0, static_cast<int>(one.size()));
    log.WriteRaw(channels::ChannelEvents(), 0, one.data(), 8);
    // Intact.
    log.WriteRaw(channels::ChannelEvents(), 0, bytes.data(), static_cast<int>(bytes.size()));
    clock_window_t c{};
    c.vehicle_id = kEmulatorId;
    c.period_us = kPeriod;
    c.n_ticks = 0;
    log.Write(channels::Clock(), 0, c);
    // The largest tick and period each check allows: their product does not fit in 64
    // bits, so it must be refused before it is computed (UBSan builds catch the overflow).
    c.n_ticks = 1;
    c.tick = std::int64_t{1} << 40;
    c.period_us = 1000000000;
    c.utime = 0;
    log.Write(channels::Clock(), 0, c);
  }
  const RunData run = Load(path);
  EXPECT_EQ(run.channel_events.size(), 2u);
  EXPECT_EQ(run.undecodable, 3);
  EXPECT_EQ(run.rejected, 2);
  EXPECT_TRUE(run.clock.empty());
  // Each count is said, so a user learns why data is missing.
  const auto said = [&](const std::string& what) {
    for (const std::string& w : run.warnings) {
      if (w.find(what) != std::string::npos) return true;
    }
    return false;
  };
  EXPECT_TRUE(said("3 messages on Shoal channels did not decode"));
  EXPECT_TRUE(said("2 messages were inconsistent"));
}

// A channel batch or a health report whose bytes came before (a log recorded twice, a
// signed message replayed onto the bus) is counted once; a restarted publisher's message
// with the same sequence number or time but other contents is its own and is kept.
TEST(RunData, ACopiedBatchOrReportCountsOnceARestartedPublishersDoesNot) {
  const std::string path = Tmp("copied_batch.lcmlog");
  {
    LogWriter log(path);
    log.Write(channels::Status(), 0, Status(0, kLauncherId, "running", kScenario));
    std::vector<channel_events_t> sent;
    ChannelEventBatch first;
    for (int k = 0; k < 2; ++k) {
      first.Add(Decision(0, 1, k * kPeriod, 0.1, k * kPeriod + 100000, 0));
      first.Add(Decision(1, 2, k * kPeriod, 0.03, k * kPeriod + 40000, 0));
      first.Flush([&](const channel_events_t& b) { sent.push_back(b); });
    }
    for (const channel_events_t& b : sent) log.Write(channels::ChannelEvents(), b.utime, b);
    log.Write(channels::Health(1), 1000000, Health(1000000, 1, 0.002, 3));
    // The first batch and the report again, byte for byte.
    log.Write(channels::ChannelEvents(), 1100000, sent[0]);
    log.Write(channels::Health(1), 1100000, Health(1000000, 1, 0.002, 3));
    // A restarted emulator numbers its batches from 0 again; a restarted vehicle may report
    // at a time it reported before, with other figures.
    ChannelEventBatch restarted;
    restarted.Add(Decision(0, 1, 5 * kPeriod, 0.1, 5 * kPeriod + 100000, 0));
    restarted.Add(Decision(1, 2, 5 * kPeriod, 0.03, 5 * kPeriod + 40000, 0));
    restarted.Flush([&](const channel_events_t& b) {
      ASSERT_EQ(b.seq, sent[0].seq);
      log.Write(channels::ChannelEvents(), 1200000, b);
    });
    log.Write(channels::Health(1), 1200000, Health(1000000, 1, 0.004, 5));
  }
  const RunData run = Load(path);
  ASSERT_EQ(run.channel_events.size(), 6u);
  EXPECT_EQ(run.channel_events[4].send_utime, 5 * kPeriod);
  ASSERT_EQ(run.health.size(), 2u);
  EXPECT_EQ(run.health[1].overruns, 5);
  EXPECT_EQ(run.undecodable + run.rejected, 0);
  ASSERT_EQ(run.warnings.size(), 1u);
  EXPECT_NE(run.warnings[0].find("2 channel decisions and 1 health reports appear more than once"),
            std::string::npos)
      << run.warnings[0];
}

TEST(Analysis, ChannelWithKnownDelayAndDropPattern) {
  const int ticks = 400;
  const RunData run = Load(WriteChannelLog(ticks));
  const RunAnalysis a = AnalyseRun(run);
  const ChannelAnalysis& c = a.channel;
  int lost = 0;
  for (int k = 0; k < ticks; ++k) lost += k % 4 == 3;
  EXPECT_EQ(c.sent, 2 * ticks);
  EXPECT_EQ(c.dropped_loss, lost);
  EXPECT_EQ(c.dropped_queue, 1);
  EXPECT_EQ(c.dropped_invalid, 0);
  EXPECT_EQ(c.dropped, lost + 1);
  EXPECT_EQ(c.delivered, 2 * ticks - lost - 1);
  EXPECT_EQ(a.summary.delivered, c.delivered);
  EXPECT_EQ(a.summary.dropped, c.dropped);
  EXPECT_EQ(c.model_mismatches, 0);
  EXPECT_EQ(c.unknown_links, 0);
  ASSERT_EQ(c.links.size(), 2u);
  const LinkAnalysis& l01 = c.links[0];
  const LinkAnalysis& l12 = c.links[1];
  ASSERT_EQ(l01.from, 0);
  ASSERT_EQ(l01.to, 1);
  ASSERT_EQ(l12.from, 1);
  ASSERT_EQ(l12.to, 2);
  EXPECT_TRUE(l01.in_scenario && l12.in_scenario);
  EXPECT_EQ(l01.delivered, ticks - lost - 1);
  EXPECT_EQ(l12.delivered, ticks);
  // Realised delay exactly tau on 0 -> 1; one tick boundary later than tau on 1 -> 2.
  EXPECT_NEAR(l01.realised_delay_s.p50, 0.1, 1e-12);
  EXPECT_NEAR(l01.delay_error_s.max, 0.0, 1e-12);
  EXPECT_NEAR(l01.delay_error_s.min, 0.0, 1e-12);
  EXPECT_NEAR(l12.realised_delay_s.max, 0.04, 1e-12);
  EXPECT_NEAR(l12.delay_error_s.p50, 0.01, 1e-12);
  EXPECT_NEAR(l12.delay_error_s.min, 0.01, 1e-12);
  EXPECT_NEAR(c.delay_error_s.max, 0.01, 1e-12);
  EXPECT_EQ(c.delay_error_s.count, c.delivered);
  // Configured tau per event, aligned with the events.
  ASSERT_EQ(c.configured_delay_s.size(), run.channel_events.size());
  for (std::size_t k = 0; k < run.channel_events.size(); ++k) {
    EXPECT_DOUBLE_EQ(c.configured_delay_s[k], run.channel_events[k].sender == 0 ? 0.1 : 0.03);
  }
  // Age at use on 0 -> 1: 0.1 s, or 0.12 s when the newest message was lost; the first
  // delivery is usable at tick 5.
  EXPECT_EQ(l01.ticks_before_first, 5);
  EXPECT_EQ(l01.ticks_stale, 0);
  EXPECT_EQ(l01.age_at_use_s.count, ticks - 5);
  EXPECT_NEAR(l01.age_at_use_s.p50, 0.1, 1e-12);
  EXPECT_NEAR(l01.age_at_use_s.p99, 0.12, 1e-12);
  EXPECT_NEAR(l01.age_at_use_s.max, 0.12, 1e-12);
  // Ticks at which the newest message is one period older than usual: one per lost
  // message (its delivery tick), and one for the queue drop (k = 9, delivery tick 14).
  int older = 0;
  for (int j = 5; j < ticks; ++j) older += ((j - 5) % 4 == 3) || (j - 5 == 9);
  EXPECT_NEAR(l01.age_at_use_s.mean, (0.1 * (ticks - 5 - older) + 0.12 * older) / (ticks - 5),
              1e-12);
  // 1 -> 2: always 0.04 s after the first delivery (tick 2).
  EXPECT_EQ(l12.ticks_before_first, 2);
  EXPECT_NEAR(l12.age_at_use_s.min, 0.04, 1e-12);
  EXPECT_NEAR(l12.age_at_use_s.max, 0.04, 1e-12);
  // With a clock and no emulator this is a shoal sim log.
  EXPECT_EQ(a.mode, "sim");
  EXPECT_EQ(a.ticks, ticks);
}

// A status newer than this reader (a later writer's kind of drop) is counted as
// dropped_invalid, as lcmtypes/README.md promises older readers do, not rejected.
TEST(Analysis, UnknownChannelStatusIsDroppedInvalidNotRejected) {
  const RunData run = Load(WriteChannelLog(40, true, false, 9));
  EXPECT_EQ(run.rejected, 0);
  const ChannelAnalysis& c = AnalyseRun(run).channel;
  EXPECT_EQ(c.dropped_queue, 0);
  EXPECT_EQ(c.dropped_invalid, 1);
  EXPECT_EQ(c.sent, 80);
  const RunData negative = Load(WriteChannelLog(40, true, false, -1));
  EXPECT_EQ(negative.rejected, 1);
}

TEST(Analysis, AgeAtUseCountsStaleTicksBeyondTheTimeout) {
  // Leader -> 1 delivers only messages sent before 1 s; the timeout is 1 s.
  const std::string path = Tmp("stale.lcmlog");
  {
    LogWriter log(path);
    log.Write(channels::Status(), 0, Status(0, kLauncherId, "running", kScenario));
    for (int k = 0; k < 200; ++k) {  // 0 .. 3.98 s
      const Micros t = k * kPeriod;
      for (int id = 0; id <= 2; ++id) {
        log.Write(channels::State(id), t, ToLcm(State(id, t, Vec5::Zero(), Vec5::Zero())));
      }
      const bool ok = t < 1000000;
      log.Write(channels::ChannelEvents(), t, Event(0, 1, t, 0.1, ok ? t + 100000 : 0, ok ? 0 : 1, k));
    }
  }
  const RunAnalysis a = AnalyseRun(Load(path));
  const LinkAnalysis& l = a.channel.links[0];
  // The newest message was sent at 0.98 s; usable while now - 0.98 <= 1.0, i.e. up to 1.98 s.
  EXPECT_EQ(l.ticks_before_first, 5);
  EXPECT_EQ(l.age_at_use_s.count, 100 - 5);   // ticks 5 .. 99
  EXPECT_EQ(l.ticks_stale, 200 - 100);        // ticks 100 .. 199
  EXPECT_NEAR(l.age_at_use_s.max, 1.0, 1e-12);
}

TEST(Analysis, DrawnDelayOtherThanTheScenarioModelIsAMismatch) {
  const std::string path = Tmp("mismatch.lcmlog");
  {
    LogWriter log(path);
    log.Write(channels::Status(), 0, Status(0, kLauncherId, "running", kScenario));
    log.Write(channels::ChannelEvents(), 0, Event(0, 1, 0, 0.1, 100000, 0, 0));
    log.Write(channels::ChannelEvents(), 20000, Event(0, 1, 20000, 0.25, 280000, 0, 1));
    log.Write(channels::ChannelEvents(), 40000, Event(2, 1, 40000, 0.1, 140000, 0, 2));
  }
  const RunAnalysis a = AnalyseRun(Load(path));
  EXPECT_EQ(a.channel.model_mismatches, 1);
  EXPECT_EQ(a.channel.unknown_links, 1);  // 2 -> 1 is not in the topology
  EXPECT_DOUBLE_EQ(a.channel.configured_delay_s[1], 0.1);
  EXPECT_DOUBLE_EQ(a.channel.configured_delay_s[2], 0.1);  // unknown link: the drawn delay
  EXPECT_NEAR(a.channel.delay_error_s.max, 0.16, 1e-12);   // 0.26 realised - 0.1
}

// Acoustic: a drawn delay outside [processing_s, max_range / c + processing_s + jitter_s]
// is a mismatch; "modem busy" decisions are counted apart and not as sent, "out of
// range" ones as dropped (their delay, beyond the bound by definition, is no mismatch).
TEST(Analysis, AcousticBoundsBusyAndRangeStatuses) {
  std::string toml = kScenario;
  const std::string from = "model = \"constant\"\nbase_s = 0.1\n";
  toml.replace(toml.find(from), from.size(),
               "model = \"acoustic\"\nmax_range_m = 1500\nprocessing_s = 0.1\n");
  const std::string path = Tmp("acoustic.lcmlog");
  {
    LogWriter log(path);
    log.Write(channels::Status(), 0, Status(0, kLauncherId, "running", toml));
    log.Write(channels::ChannelEvents(), 0, Event(0, 1, 0, 0.5, 500000, 0, 0));     // in bounds
    log.Write(channels::ChannelEvents(), 20000, Event(0, 1, 20000, 1.2, 1220000, 0, 1));  // > 1.1
    log.Write(channels::ChannelEvents(), 40000, Event(0, 1, 40000, 0.0, 0, 4, 2));  // busy
    // Out of range: its delay is the range's (beyond max_range_m), not a draw to check.
    log.Write(channels::ChannelEvents(), 60000, Event(0, 1, 60000, 2.1, 0, 5, 3));
  }
  const RunAnalysis a = AnalyseRun(Load(path));
  EXPECT_EQ(a.channel.model_mismatches, 1);
  EXPECT_EQ(a.channel.skipped_busy, 1);
  EXPECT_EQ(a.channel.dropped_range, 1);
  EXPECT_EQ(a.channel.sent, 3);
  EXPECT_EQ(a.channel.delivered, 2);
  EXPECT_EQ(a.channel.dropped, 1);
  EXPECT_EQ(a.channel.dropped_invalid, 0);
}

TEST(Analysis, SinusoidConfiguredDelayIsTauAtSendTime) {
  std::string toml = kScenario;
  const std::string from = "model = \"constant\"\nbase_s = 0.1\n";
  toml.replace(toml.find(from), from.size(),
               "model = \"sinusoid\"\nbase_s = 0.1\namplitude_s = 0.05\nomega_rad_s = 1.0\n");
  const std::string path = Tmp("sinusoid.lcmlog");
  {
    LogWriter log(path);
    log.Write(channels::Status(), 0, Status(0, kLauncherId, "running", toml));
    for (int k = 0; k < 300; ++k) {
      const Micros t = k * kPeriod;
      const double tau = 0.1 + 0.05 * std::cos(ToSeconds(t));
      log.Write(channels::ChannelEvents(), t,
                Event(0, 1, t, tau, DeliveryTime(t, tau, kPeriod), 0, k));
    }
  }
  const RunData run = Load(path);
  const RunAnalysis a = AnalyseRun(run);
  EXPECT_EQ(a.channel.model_mismatches, 0);
  for (std::size_t k = 0; k < run.channel_events.size(); ++k) {
    EXPECT_DOUBLE_EQ(a.channel.configured_delay_s[k],
                     0.1 + 0.05 * std::cos(ToSeconds(run.channel_events[k].send_utime)));
  }
  // Tick quantisation: delivered at the first tick at or after send + tau, so the error
  // lies in [0, one period).
  EXPECT_GE(a.channel.delay_error_s.min, -0.5e-6);
  EXPECT_LT(a.channel.delay_error_s.max, ToSeconds(kPeriod));
  EXPECT_GT(a.channel.delay_error_s.max, 0.0);
}

TEST(Analysis, HealthUsesTheLastReportPerProcessAndFlagsGiveStaleEvents) {
  const std::string path = Tmp("health.lcmlog");
  {
    LogWriter log(path);
    log.Write(channels::Status(), 0, Status(0, kEmulatorId, "running", ""));
    for (int k = 0; k < 100; ++k) {
      const Micros t = k * kPeriod;
      int flags = 0;
      if ((k >= 10 && k < 20) || (k >= 30 && k < 35)) flags |= StateMsg::kFlagStaleNeighbour;
      if (k % 20 == 0) flags |= StateMsg::kFlagSaturated;
      log.Write(channels::State(0), t, ToLcm(State(0, t, Vec5::Zero(), Vec5::Zero())));
      log.Write(channels::State(1), t, ToLcm(State(1, t, Vec5::Zero(), Vec5::Zero(), flags)));
      log.Write(channels::State(2), t, ToLcm(State(2, t, Vec5::Zero(), Vec5::Zero())));
    }
    // Earlier reports with larger figures must not count: the last report holds the
    // figures since the start.
    log.Write(channels::Health(1), 1000000, Health(1000000, 1, 0.9, 99));
    log.Write(channels::Health(1), 2000000, Health(2000000, 1, 0.002, 3));
    log.Write(channels::Health(2), 2000000, Health(2000000, 2, 0.005, 4));
    log.Write(channels::Health(0), 2000000, Health(2000000, 0, 0.001, 0));
    log.Write(channels::Health(kEmulatorId), 2000000, Health(2000000, kEmulatorId, 0.0007, 8));
    // The first report replayed later in the log (validly signed, as anyone on the bus can
    // resend one): the newest in mission time still counts.
    log.Write(channels::Health(1), 2100000, Health(1000000, 1, 0.9, 99));
  }
  const RunData run = Load(path);
  EXPECT_FALSE(run.has_scenario);
  EXPECT_EQ(run.followers, 2);  // from the status
  const RunAnalysis a = AnalyseRun(run);
  EXPECT_FALSE(a.has_formation);
  EXPECT_EQ(a.mode, "realtime");  // an emulator and no clock
  EXPECT_DOUBLE_EQ(a.summary.lateness_p99_s, 0.005);
  EXPECT_EQ(a.summary.overruns, 7);  // vehicles only; the emulator's 8 are not loop overruns
  EXPECT_DOUBLE_EQ(a.summary.release_error_p99_s, 0.0007);
  EXPECT_DOUBLE_EQ(a.channel.release_error_p99_s, 0.0007);
  ASSERT_EQ(a.processes.size(), 4u);
  EXPECT_EQ(a.processes[0].id, -1);
  EXPECT_EQ(a.processes[2].id, 1);
  EXPECT_EQ(a.processes[2].reports, 2);  // the replayed copy is the first report, once
  EXPECT_DOUBLE_EQ(a.processes[2].last.lateness_max_s, 0.004);
  const FollowerAnalysis& f1 = a.followers[0];
  EXPECT_EQ(f1.stale_ticks, 15);
  EXPECT_EQ(f1.stale_events, 2);
  EXPECT_EQ(f1.saturated_ticks, 5);
  EXPECT_DOUBLE_EQ(f1.saturation_fraction, 0.05);
  EXPECT_EQ(a.followers[1].stale_events, 0);
}

// A run stopped early (Ctrl-C, a fault) is expected up to the tick its run-level
// "interrupted" status names, not over the scenario's whole length: a complete log of
// what ran is complete.
TEST(Analysis, AnInterruptedRunIsExpectedUpToWhereItStopped) {
  const std::string path = Tmp("interrupted.lcmlog");
  {
    LogWriter log(path);
    log.Write(channels::Status(), 0, Status(0, kEmulatorId, "running", kScenario));
    for (int k = 0; k <= 100; ++k) {
      const Micros t = k * kPeriod;
      for (int id = 0; id <= 2; ++id) {
        log.Write(channels::State(id), t, ToLcm(State(id, t, Vec5::Zero(), Vec5::Zero())));
      }
    }
    log.Write(channels::Status(), 100 * kPeriod,
              Status(100 * kPeriod, kEmulatorId, "interrupted", ""));
  }
  const RunAnalysis a = AnalyseRun(Load(path));
  EXPECT_TRUE(a.interrupted);
  EXPECT_EQ(a.states_expected, 101 * 3);  // ticks 0..100 of the leader and 2 followers
}

// A recording's span is the run's, from tick 0: the statuses of the processes' start-up,
// stamped seconds before it (4 s in real time), are not counted.
TEST(Analysis, WallTimeRunsFromTheFirstStateNotTheStartUp) {
  const std::string path = Tmp("wall_time.lcmlog");
  const std::int64_t wall0 = 1700000000000000LL;  // lcm-logger's stamps: the wall clock
  {
    LogWriter log(path);
    log.Write(channels::Status(), wall0, Status(0, kEmulatorId, "running", kScenario));
    for (int k = 0; k <= 250; ++k) {
      const Micros t = k * kPeriod;
      for (int id = 0; id <= 2; ++id) {
        log.Write(channels::State(id), wall0 + 4000000 + t,
                  ToLcm(State(id, t, Vec5::Zero(), Vec5::Zero())));
      }
    }
  }
  const RunAnalysis a = AnalyseRun(Load(path));
  EXPECT_NEAR(a.wall_time_s, 5.0, 1e-9);
}

TEST(Analysis, ModeAndProblemsFromStatuses) {
  const std::string path = Tmp("lockstep.lcmlog");
  {
    LogWriter log(path);
    clock_window_t c{};
    c.n_ticks = 1;
    c.period_us = kPeriod;
    c.vehicle_id = kEmulatorId;
    log.Write(channels::Clock(), 0, c);
    log.Write(channels::Health(kEmulatorId), 0, Health(0, kEmulatorId, 0, 0));
    run_status_t lost = Status(0, kEmulatorId, "vehicle_lost", "");
    lost.message = "vehicle 2 stopped answering at t = 0 s";
    log.Write(channels::Status(), 0, lost);
    log.Write(channels::Status(), 0, Status(0, kEmulatorId, "finished", ""));
  }
  const RunAnalysis a = AnalyseRun(Load(path));
  EXPECT_EQ(a.mode, "lockstep");
  ASSERT_EQ(a.problems.size(), 1u);
  EXPECT_NE(a.problems[0].find("vehicle 2 stopped answering"), std::string::npos);
  EXPECT_FALSE(a.interrupted);
}

// A clock window whose times do not fit in 64 bits (tick 2^39 at a period of 2^24 us, or
// a window running past the largest time) is rejected, without computing the overflowing
// product (signed overflow: undefined; the ASan+UBSan build stops on it). Found by
// fuzz_log_reader (tests/fuzz/regressions/fuzz_log_reader/clock_window_tick_times_period_overflows).
TEST(RunData, ClockWindowWhoseTimesOverflowIsRejected) {
  const std::string path = Tmp("clock_overflow.lcmlog");
  {
    LogWriter log(path);
    clock_window_t c{};
    c.vehicle_id = kEmulatorId;
    c.n_ticks = 1;
    c.period_us = std::int64_t{1} << 24;
    c.tick = std::int64_t{1} << 39;
    c.utime = 0;  // what a wrapped product would not match either
    log.Write(channels::Clock(), 0, c);
    c.tick = (std::int64_t{1} << 39) - 1;  // fits: (2^39 - 1) * 2^24 < 2^63
    c.utime = c.tick * c.period_us;
    c.n_ticks = 100000;  // but its last tick does not
    log.Write(channels::Clock(), 0, c);
    c.tick = 3;
    c.n_ticks = 2;
    c.period_us = kPeriod;
    c.utime = 3 * kPeriod;
    log.Write(channels::Clock(), 0, c);
  }
  const RunData run = Load(path);
  EXPECT_EQ(run.rejected, 2);
  ASSERT_EQ(run.clock.size(), 1u);
  EXPECT_EQ(run.clock[0].last_utime(), 4 * kPeriod);
  EXPECT_EQ(ClockTicks(run), 2);
}

// Clock messages are kept as windows: a log of a few kB whose messages each declare the
// largest window (10^5 ticks) once filled 1.1 GB with a record per tick. Windows repeated
// or overlapping count their ticks once.
TEST(RunData, ClockWindowsAreKeptAsWindowsAndTheirTicksCountedOnce) {
  const std::string path = Tmp("huge_windows.lcmlog");
  {
    LogWriter log(path);
    clock_window_t c{};
    c.vehicle_id = kEmulatorId;
    c.n_ticks = 100000;
    c.period_us = kPeriod;
    for (int k = 0; k < 2000; ++k) {
      c.tick = (k % 1000) * 50000;  // each overlaps the next by half, and all come twice
      c.utime = c.tick * kPeriod;
      log.Write(channels::Clock(), 0, c);
    }
  }
  const RunData run = Load(path);
  EXPECT_EQ(run.rejected, 0);
  EXPECT_EQ(run.clock.size(), 2000u);
  EXPECT_EQ(ClockTicks(run), 999 * 50000 + 100000);
}

TEST(RunData, KeepsEveryStateFieldSortsAndDeduplicates) {
  const std::string path = Tmp("fields.lcmlog");
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1e3, 1e3);
  std::vector<StateMsg> written;
  {
    LogWriter log(path);
    log.Write("OTHER_CHANNEL", 0, ToLcm(State(0, 0, Vec5::Zero(), Vec5::Zero())));
    for (int k : {0, 2, 1, 3, 3}) {  // out of order, and utime 3 twice
      StateMsg m;
      m.vehicle_id = 1;
      m.seq = k * 10 + static_cast<int>(written.size());
      m.utime = k * kPeriod;
      for (Vec5* v : {&m.eta, &m.nu, &m.eta_dot, &m.accel_cmd, &m.tau}) {
        for (int c = 0; c < 5; ++c) (*v)(c) = u(rng);
      }
      m.flags = k;
      written.push_back(m);
      log.Write(channels::State(1), m.utime, ToLcm(m));
    }
    StateMsg bad = written[0];
    bad.vehicle_id = 2;  // on SHOAL_STATE_1: inconsistent
    log.Write(channels::State(1), 0, ToLcm(bad));
    StateMsg nan = written[0];
    nan.utime = 10 * kPeriod;
    nan.eta(0) = std::nan("");
    log.Write(channels::State(1), nan.utime, ToLcm(nan));
  }
  RunData run = Load(path);
  EXPECT_EQ(run.other_events, 1);
  EXPECT_EQ(run.rejected, 1);
  EXPECT_FALSE(run.has_scenario);
  const VehicleTrack& v = run.vehicles[1];
  EXPECT_EQ(v.received, 6);
  EXPECT_EQ(v.repeated, 1);
  EXPECT_EQ(v.nonfinite, 1);
  EXPECT_EQ(v.first_nonfinite_utime, 10 * kPeriod);
  ASSERT_EQ(v.samples.size(), 5u);  // 0, 1, 2, 3 (the later one), 10 (NaN, kept)
  const int expect_index[] = {0, 2, 1, 4};
  for (int k = 0; k < 4; ++k) {
    const StateMsg& a = v.samples[k];
    const StateMsg& b = written[expect_index[k]];
    EXPECT_EQ(a.utime, b.utime);
    EXPECT_EQ(a.seq, b.seq);
    EXPECT_EQ(a.flags, b.flags);
    EXPECT_EQ(a.eta, b.eta);
    EXPECT_EQ(a.nu, b.nu);
    EXPECT_EQ(a.eta_dot, b.eta_dot);
    EXPECT_EQ(a.accel_cmd, b.accel_cmd);
    EXPECT_EQ(a.tau, b.tau);
  }
  EXPECT_TRUE(std::isnan(v.samples[4].eta(0)));
  // A NaN state is a divergence, as in shoal sim.
  EXPECT_EQ(AnalyseRun(run).diverged_follower, 1);
}

// ---- Damaged, empty and foreign files --------------------------------------------------

TEST(LogDamage, EmptyFileIsAnError) {
  const std::string path = Tmp("empty.lcmlog");
  WriteBytes(path, "");
  RunData run;
  std::string err;
  EXPECT_FALSE(LoadRunLog(path, LoadOptions(), &run, &err));
  EXPECT_NE(err.find("empty"), std::string::npos) << err;
}

TEST(LogDamage, NonLcmFileIsAnError) {
  const std::string path = Tmp("text.lcmlog");
  WriteBytes(path, std::string(kScenario) + std::string(5000, 'x'));
  RunData run;
  std::string err;
  EXPECT_FALSE(LoadRunLog(path, LoadOptions(), &run, &err));
  EXPECT_NE(err.find("not an LCM log"), std::string::npos) << err;
  WriteBytes(path, "abc");
  EXPECT_FALSE(LoadRunLog(path, LoadOptions(), &run, &err));
  EXPECT_NE(err.find("too short"), std::string::npos) << err;
  EXPECT_FALSE(LoadRunLog(Tmp("does_not_exist.lcmlog"), LoadOptions(), &run, &err));
  EXPECT_NE(err.find("cannot read"), std::string::npos) << err;
}

TEST(LogDamage, LcmLogWithoutShoalMessagesIsAnError) {
  const std::string path = Tmp("foreign.lcmlog");
  {
    LogWriter log(path);
    log.Write("POSE", 0, ToLcm(State(0, 0, Vec5::Zero(), Vec5::Zero())));
  }
  RunData run;
  std::string err;
  EXPECT_FALSE(LoadRunLog(path, LoadOptions(), &run, &err));
  EXPECT_NE(err.find("no Shoal message"), std::string::npos) << err;
}

struct EventSpan {
  std::int64_t offset, size;
};
// Event boundaries of a well-formed log.
std::vector<EventSpan> Spans(const std::string& bytes) {
  std::vector<EventSpan> v;
  std::size_t p = 0;
  auto u32 = [&](std::size_t at) {
    return (std::uint32_t(std::uint8_t(bytes[at])) << 24) | (std::uint32_t(std::uint8_t(bytes[at + 1])) << 16) |
           (std::uint32_t(std::uint8_t(bytes[at + 2])) << 8) | std::uint32_t(std::uint8_t(bytes[at + 3]));
  };
  while (p + 28 <= bytes.size()) {
    const std::size_t n = 28 + u32(p + 20) + u32(p + 24);
    v.push_back({static_cast<std::int64_t>(p), static_cast<std::int64_t>(n)});
    p += n;
  }
  return v;
}

TEST(LogDamage, TruncatedLastEventIsReportedAndTheRestAnalysed) {
  const std::string full = ReadBytes(WriteChannelLog(50));
  const auto spans = Spans(full);
  ASSERT_GT(spans.size(), 100u);
  const EventSpan last = spans.back();
  const std::string path = Tmp("truncated.lcmlog");
  WriteBytes(path, full.substr(0, last.offset + last.size / 2));
  RunData run;
  std::string err;
  ASSERT_TRUE(LoadRunLog(path, LoadOptions(), &run, &err)) << err;
  EXPECT_TRUE(run.damaged);
  EXPECT_EQ(run.events, static_cast<std::int64_t>(spans.size()) - 1);
  ASSERT_FALSE(run.warnings.empty());
  EXPECT_NE(run.warnings[0].find("truncated"), std::string::npos) << run.warnings[0];
  EXPECT_NE(run.warnings[0].find("byte " + std::to_string(last.offset)), std::string::npos)
      << run.warnings[0];
}

TEST(LogDamage, BadSyncInTheMiddleResynchronisesAndLosesOneEvent) {
  const std::string full = ReadBytes(WriteChannelLog(50));
  const auto spans = Spans(full);
  const EventSpan hit = spans[spans.size() / 2];
  std::string bytes = full;
  bytes[hit.offset + 1] ^= 0x5A;
  const std::string path = Tmp("badsync.lcmlog");
  WriteBytes(path, bytes);
  RunData run;
  std::string err;
  ASSERT_TRUE(LoadRunLog(path, LoadOptions(), &run, &err)) << err;
  EXPECT_EQ(run.events, static_cast<std::int64_t>(spans.size()) - 1);
  ASSERT_EQ(run.warnings.size(), 1u);
  EXPECT_NE(run.warnings[0].find("byte " + std::to_string(hit.offset)), std::string::npos);
  EXPECT_NE(run.warnings[0].find("resynchronised"), std::string::npos) << run.warnings[0];
}

TEST(LogDamage, WrongDataLengthLosesOnlyThatEvent) {
  const std::string full = ReadBytes(WriteChannelLog(50));
  const auto spans = Spans(full);
  const EventSpan hit = spans[spans.size() / 3];
  std::string bytes = full;
  bytes[hit.offset + 26] = static_cast<char>(bytes[hit.offset + 26] + 1);  // data length + 256
  const std::string path = Tmp("badlen.lcmlog");
  WriteBytes(path, bytes);
  RunData run;
  std::string err;
  ASSERT_TRUE(LoadRunLog(path, LoadOptions(), &run, &err)) << err;
  EXPECT_EQ(run.events, static_cast<std::int64_t>(spans.size()) - 1);
  EXPECT_TRUE(run.damaged);
  // A length far beyond the end of the file (200 MB) is damage too, not a truncation.
  bytes = full;
  bytes[hit.offset + 24] = 0x0C;
  WriteBytes(path, bytes);
  ASSERT_TRUE(LoadRunLog(path, LoadOptions(), &run, &err)) << err;
  EXPECT_EQ(run.events, static_cast<std::int64_t>(spans.size()) - 1);
  ASSERT_FALSE(run.warnings.empty());
  EXPECT_NE(run.warnings[0].find("resynchronised"), std::string::npos) << run.warnings[0];
}

TEST(LogDamage, DamagedStartIsSkippedNotFatal) {
  const std::string full = ReadBytes(WriteChannelLog(20));
  const std::string path = Tmp("badstart.lcmlog");
  WriteBytes(path, std::string(100, '\x07') + full);
  RunData run;
  std::string err;
  ASSERT_TRUE(LoadRunLog(path, LoadOptions(), &run, &err)) << err;
  EXPECT_EQ(run.events, static_cast<std::int64_t>(Spans(full).size()));
  EXPECT_NE(run.warnings[0].find("skipped 100 bytes"), std::string::npos) << run.warnings[0];
  // An event within the first megabyte is found; one beyond it is not, however much of the
  // file one read brings in: the file is then no LCM log.
  WriteBytes(path, std::string((1 << 20) - 1, '\x07') + full);
  ASSERT_TRUE(LoadRunLog(path, LoadOptions(), &run, &err)) << err;
  EXPECT_EQ(run.events, static_cast<std::int64_t>(Spans(full).size()));
  for (const std::size_t junk : {std::size_t{1} << 20, std::size_t{2} << 20}) {
    WriteBytes(path, std::string(junk, '\x07') + full);
    EXPECT_FALSE(LoadRunLog(path, LoadOptions(), &run, &err)) << junk;
    EXPECT_NE(err.find("not an LCM log"), std::string::npos) << err;
  }
}

// Property: at any truncation point the loader returns (never crashes), reads exactly the
// complete events before the cut, and warns unless the cut falls on an event boundary.
TEST(LogDamage, RandomTruncations) {
  const std::string full = ReadBytes(WriteChannelLog(40));
  const auto spans = Spans(full);
  std::mt19937 rng(42);
  std::uniform_int_distribution<std::size_t> cut(1, full.size() - 1);
  const std::string path = Tmp("fuzz_trunc.lcmlog");
  for (int trial = 0; trial < 150; ++trial) {
    const std::size_t n = cut(rng);
    WriteBytes(path, full.substr(0, n));
    std::int64_t complete = 0;
    bool boundary = false;
    for (const EventSpan& s : spans) {
      if (s.offset + s.size <= static_cast<std::int64_t>(n)) ++complete;
      boundary = boundary || s.offset + s.size == static_cast<std::int64_t>(n);
    }
    RunData run;
    std::string err;
    const bool ok = LoadRunLog(path, LoadOptions(), &run, &err);
    if (complete == 0) {
      EXPECT_FALSE(ok);
      EXPECT_FALSE(err.empty());
      continue;
    }
    ASSERT_TRUE(ok) << "cut at " << n << ": " << err;
    EXPECT_EQ(run.events, complete) << "cut at " << n;
    EXPECT_EQ(run.damaged, !boundary) << "cut at " << n;
    AnalyseRun(run);  // must not crash either
  }
}

// Property: random byte flips never crash the loader or the analysis; whatever loads has
// no more events than the original and every kept state is one that was written.
TEST(LogDamage, RandomByteFlips) {
  const std::string full = ReadBytes(WriteChannelLog(40));
  const std::int64_t n_events = static_cast<std::int64_t>(Spans(full).size());
  std::mt19937 rng(4242);
  std::uniform_int_distribution<std::size_t> pos(0, full.size() - 1);
  std::uniform_int_distribution<int> flips(1, 12), byte(1, 255);
  const std::string path = Tmp("fuzz_flip.lcmlog");
  int loaded = 0;
  for (int trial = 0; trial < 300; ++trial) {
    std::string bytes = full;
    const int k = flips(rng);
    for (int i = 0; i < k; ++i) bytes[pos(rng)] ^= static_cast<char>(byte(rng));
    WriteBytes(path, bytes);
    RunData run;
    std::string err;
    if (!LoadRunLog(path, LoadOptions(), &run, &err)) {
      EXPECT_FALSE(err.empty());
      continue;
    }
    ++loaded;
    // LCM has no checksum, so a flipped data byte may survive as a wrong value; what the
    // loader guarantees is structure: ids in range, tracks sorted with unique times.
    EXPECT_LE(run.events, n_events);
    ASSERT_LE(run.vehicles.size(), 3u);
    for (const VehicleTrack& v : run.vehicles) {
      for (std::size_t i = 1; i < v.samples.size(); ++i) {
        EXPECT_LT(v.samples[i - 1].utime, v.samples[i].utime);
      }
    }
    const RunAnalysis a = AnalyseRun(run);
    if (trial % 10 == 0) {
      std::vector<std::string> files;
      std::string cerr;
      EXPECT_TRUE(WriteRunCsv(run, a, Tmp("fuzz_csv"), &files, &cerr)) << cerr;
    }
  }
  EXPECT_GT(loaded, 250);  // a few flips damage a few events, not the whole log
}

// LCM 1.3.1's generated decoders trust array counts (an int product that overflows, a
// vector resized before the bytes are checked): a clock message or an event batch with a
// forged count must be refused by Decode, not read out of bounds or allocate gigabytes.
TEST(LogDamage, ForgedArrayCountsAreRefusedNotTrusted) {
  clock_window_t c{};
  c.vehicle_id = kEmulatorId;
  c.n_ticks = 1;
  c.period_us = kPeriod;
  c.n_deliveries = 1;
  c.delivery_tick = {0};
  c.delivery_receiver = {1};
  c.delivery_sender = {0};
  c.delivery_seq = {0};
  c.delivery_digest = {0};
  std::vector<std::uint8_t> b(c.getEncodedSize());
  ASSERT_EQ(c.encode(b.data(), 0, static_cast<int>(b.size())), static_cast<int>(b.size()));
  clock_window_t out;
  ASSERT_TRUE(Decode(b.data(), static_cast<int>(b.size()), &out));
  const int at = 8 + 8 + 4 + 4 + 8 + 4 + 8 + 1;  // n_deliveries
  for (std::uint32_t n : {0x7fffffffu, 0x20000000u, 0x10000001u, 0x80000000u, 2u, 0u}) {
    for (int k = 0; k < 4; ++k) b[at + k] = static_cast<std::uint8_t>(n >> (24 - 8 * k));
    EXPECT_FALSE(Decode(b.data(), static_cast<int>(b.size()), &out)) << n;
  }
  ChannelEventBatch batch;
  batch.Add(Decision(0, 1, 0, 0.1, 100000, 0));
  std::vector<std::uint8_t> e;
  batch.Flush([&](const channel_events_t& m) {
    e.resize(static_cast<std::size_t>(m.getEncodedSize()));
    m.encode(e.data(), 0, static_cast<int>(e.size()));
  });
  channel_events_t events;
  ASSERT_TRUE(Decode(e.data(), static_cast<int>(e.size()), &events));
  for (std::uint32_t n : {0x7fffffffu, 0x04000000u, 0x80000000u, 2u}) {
    for (int k = 0; k < 4; ++k) e[24 + k] = static_cast<std::uint8_t>(n >> (24 - 8 * k));
    EXPECT_FALSE(Decode(e.data(), static_cast<int>(e.size()), &events)) << n;
  }
}

// A string length of 0 or less makes LCM's generated decoder throw std::length_error, and
// INT_MIN overflows its length - 1 (a 2 GB read past the message); runtime's Decode()
// (used in the processes' LCM handlers) must refuse them instead.
TEST(LogDamage, DamagedStringLengthIsRefusedNotThrown) {
  const auto put = [](std::vector<std::uint8_t>* b, int at, std::int32_t v) {
    for (int k = 0; k < 4; ++k) (*b)[at + k] = static_cast<std::uint8_t>(static_cast<std::uint32_t>(v) >> (24 - 8 * k));
  };
  const std::int32_t kBad[] = {0, -1, -100000, std::numeric_limits<std::int32_t>::min()};
  run_status_t st = Status(0, 1, "ready", "");
  std::vector<std::uint8_t> b(st.getEncodedSize());
  ASSERT_EQ(st.encode(b.data(), 0, static_cast<int>(b.size())), static_cast<int>(b.size()));
  for (std::int32_t len : kBad) {
    put(&b, 24, len);
    run_status_t out;
    EXPECT_FALSE(Decode(b.data(), static_cast<int>(b.size()), &out)) << len;
  }
  ChannelEventBatch batch;
  batch.Add(Decision(0, 1, 0, 0.1, 100000, 0));
  std::vector<std::uint8_t> e;
  batch.Flush([&](const channel_events_t& m) {
    e.resize(static_cast<std::size_t>(m.getEncodedSize()));
    m.encode(e.data(), 0, static_cast<int>(e.size()));
  });
  const int reason_at = 8 + 8 + 4 + 4 + 4 + 8 + 4 * 5 + 8 * 3 + 1;  // first event's reason
  for (std::int32_t len : kBad) {
    put(&e, reason_at, len);
    channel_events_t out;
    EXPECT_FALSE(Decode(e.data(), static_cast<int>(e.size()), &out)) << len;
  }
}

// ---- Reader details --------------------------------------------------------------------

TEST(LogReader, ReadsEveryEventOfALargeLogAcrossBufferRefills) {
  const std::string path = Tmp("large.lcmlog");
  const int n = 60000;  // ~16 MB: several 8 MB reads
  {
    LogWriter log(path);
    for (int k = 0; k < n; ++k) {
      log.Write(channels::State(0), k, ToLcm(State(0, k * kPeriod, Vec5::Constant(k), Vec5::Zero())));
    }
  }
  LcmLogReader r;
  std::string err;
  ASSERT_TRUE(r.Open(path, &err)) << err;
  LogEventView ev;
  std::int64_t k = 0;
  while (r.Next(&ev)) {
    EXPECT_EQ(ev.eventnum, k);
    EXPECT_EQ(ev.timestamp, k);
    EXPECT_EQ(ev.channel, "SHOAL_STATE_0");
    ++k;
  }
  EXPECT_EQ(k, n);
  EXPECT_TRUE(r.warnings().empty());
  RunData run = Load(path);
  ASSERT_EQ(run.vehicles[0].samples.size(), static_cast<std::size_t>(n));
  EXPECT_EQ(run.vehicles[0].samples.back().eta(0), n - 1);
}

// shoal run follows the log lcm-logger is writing: every complete event once, in order;
// an event cut short waits for its rest; damage stops the reading for good.
TEST(LogReader, FollowsALogThatIsStillBeingWritten) {
  const std::string source = Tmp("follow_source.lcmlog");
  const int n = 50;
  {
    LogWriter log(source);
    for (int k = 0; k < n; ++k) {
      log.Write(channels::State(1), k, ToLcm(State(1, k * kPeriod, Vec5::Constant(k), Vec5::Zero())));
    }
  }
  std::ifstream in(source, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string path = Tmp("follow.lcmlog");
  std::remove(path.c_str());
  LogTail tail(path);
  std::vector<double> seen;
  const LogTail::Handler on = [&](const std::string& ch, const void* d, int size) {
    EXPECT_EQ(ch, channels::State(1));
    vehicle_state_t m;
    ASSERT_TRUE(Decode(d, size, &m));
    seen.push_back(m.eta[0]);
  };
  EXPECT_EQ(tail.Poll(on), 0);  // not created yet
  std::ofstream out(path, std::ios::binary);
  for (std::size_t at = 0; at < bytes.size(); at += 37) {  // events cut anywhere
    out.write(bytes.data() + at, static_cast<std::streamsize>(std::min<std::size_t>(37, bytes.size() - at)));
    out.flush();
    ASSERT_GE(tail.Poll(on), 0) << at;
  }
  ASSERT_EQ(seen.size(), static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) EXPECT_EQ(seen[k], k);
  EXPECT_EQ(tail.events(), n);
  out << "not an LCM event header, not at all";
  out.flush();
  EXPECT_EQ(tail.Poll(on), -1);
  EXPECT_TRUE(tail.damaged());
  EXPECT_EQ(tail.Poll(on), -1);
  EXPECT_EQ(seen.size(), static_cast<std::size_t>(n));
}

// A header whose data length is damaged (or not written yet) and says 128 MB: following
// waits for the rest without making its buffer that big (it used to zero-fill a buffer of
// the declared size on every log like that); the event, once complete, is handed over.
TEST(LogReader, FollowingAnEventDeclaredHugeDoesNotAllocateIt) {
  const std::string path = Tmp("follow_huge.lcmlog");
  const auto big_endian = [](std::uint64_t v, int bytes) {
    std::string s;
    for (int k = bytes - 1; k >= 0; --k) s.push_back(static_cast<char>((v >> (8 * k)) & 0xFF));
    return s;
  };
  const std::string channel = "SHOAL_OTHER";
  const std::uint32_t declared = 128u << 20;
  WriteBytes(path, big_endian(LcmLogReader::kSync, 4) + big_endian(0, 8) + big_endian(0, 8) +
                       big_endian(channel.size(), 4) + big_endian(declared, 4) + channel +
                       std::string(1000, 'x'));
  const auto resident_mb = [] {
    std::ifstream statm("/proc/self/statm");
    long pages = 0, resident = 0;
    statm >> pages >> resident;
    return resident * 4096.0 / (1 << 20);
  };
  const double before = resident_mb();
  LogTail tail(path);
  int handled = 0;
  const LogTail::Handler on = [&](const std::string&, const void*, int size) {
    EXPECT_EQ(size, static_cast<int>(declared));
    ++handled;
  };
  for (int k = 0; k < 3; ++k) EXPECT_EQ(tail.Poll(on), 0);
  EXPECT_LT(resident_mb() - before, 48.0);
  EXPECT_FALSE(tail.damaged());
  std::ofstream(path, std::ios::binary | std::ios::app) << std::string(declared - 1000, 'y');
  EXPECT_EQ(tail.Poll(on), 1);
  EXPECT_EQ(handled, 1);
  std::remove(path.c_str());
}

// ---- Summary shared with shoal run -------------------------------------------------------

TEST(RunSummaryTest, MatchesTheAnalysisAndToleratesMissingOrEmptyLogs) {
  const std::string path = WriteFormationLog(400);
  RunData run = Load(path);
  RunSummary s;
  ASSERT_TRUE(SummariseRunLog(path, run.scenario, &s));
  const RunSummary& a = AnalyseRun(run).summary;
  EXPECT_EQ(s.converged, a.converged);
  EXPECT_EQ(s.convergence_time_s, a.convergence_time_s);
  EXPECT_EQ(s.final_worst.position_m, a.final_worst.position_m);
  EXPECT_EQ(s.states, 3 * 400 - 1);
  EXPECT_FALSE(SummariseRunLog(Tmp("missing.lcmlog"), run.scenario, &s));
  const std::string empty = Tmp("empty_summary.lcmlog");
  WriteBytes(empty, "");
  ASSERT_TRUE(SummariseRunLog(empty, run.scenario, &s));
  EXPECT_EQ(s.states, 0);
  EXPECT_FALSE(s.converged);
}

// ---- States at impossible times ----------------------------------------------------------

// The leader and both followers in their slots for `ticks` ticks (of the 10 s scenario:
// 501 ticks), then `extra` states, as a damaged or forged log would hold them. Without
// `toml` the log declares no scenario.
std::string WriteLogWithExtraStates(const std::string& name, int ticks,
                                    const std::vector<StateMsg>& extra,
                                    const char* toml = kScenario) {
  const std::string path = Tmp(name);
  LogWriter log(path);
  log.Write(channels::Status(), 0, Status(0, kLauncherId, "running", toml));
  const Vec5 z = Vec5::Zero();
  const Vec3 slot[3] = {Vec3::Zero(), Vec3(6, 0, 0), Vec3(0, 6, 0)};
  for (int k = 0; k < ticks; ++k) {
    const Micros t = k * kPeriod;
    for (int id = 0; id <= 2; ++id) {
      Vec5 eta = z;
      eta.head<3>() = slot[id] + Vec3(ToSeconds(t), 0, 0);
      log.Write(channels::State(id), t, ToLcm(State(id, t, eta, z)));
    }
  }
  for (const StateMsg& m : extra) log.Write(channels::State(m.vehicle_id), 0, ToLcm(m));
  return path;
}

StateMsg FarOff(int id, Micros t) {
  return State(id, t, Vec5::Constant(1e6), Vec5::Constant(1e3));  // far from any slot
}

// Taken as the run's end, one state at utime = INT64_MAX would make the expectation
// 2.8e15 states and stretch every time axis to 9e12 s: the run's declared duration and
// period give the expectation, the state is counted as damaged and left out of every metric.
TEST(ImpossibleTimes, Int64MaxUtimeIsDamagedNotTheRunsEnd) {
  constexpr Micros kMax = std::numeric_limits<Micros>::max();
  const RunData run = Load(WriteLogWithExtraStates("int64max.lcmlog", 501, {FarOff(1, kMax)}));
  ASSERT_TRUE(run.has_scenario);
  const RunAnalysis a = AnalyseRun(run);
  EXPECT_EQ(a.states_expected, 501 * 3);  // 10 s at 50 Hz: ticks 0..500, three vehicles
  EXPECT_EQ(a.states_damaged, 1);
  EXPECT_EQ(a.states_after_end, 1);
  EXPECT_EQ(a.states_negative_time, 0);
  EXPECT_DOUBLE_EQ(a.end_s, 10.0);
  EXPECT_EQ(a.summary.states, 501 * 3);
  EXPECT_DOUBLE_EQ(a.summary.sim_time_s, 10.0);
  EXPECT_NEAR(a.summary.max_position_error_m, 0.0, 1e-12);  // the far-off state is not used
  EXPECT_TRUE(a.summary.converged);
  EXPECT_EQ(a.followers[0].samples, 501);
  // Still aligned with the whole track, NaN at the damaged state.
  ASSERT_EQ(a.followers[0].errors.size(), 502u);
  EXPECT_TRUE(std::isnan(a.followers[0].errors[501].position_m));
  EXPECT_NEAR(a.followers[0].errors[500].position_m, 0.0, 1e-12);
  EXPECT_EQ(a.diverged_follower, 0);
}

TEST(ImpossibleTimes, NegativeAndFarAfterTheEndAreDamaged) {
  constexpr Micros kMin = std::numeric_limits<Micros>::min();
  const RunData run = Load(WriteLogWithExtraStates(
      "negative.lcmlog", 501,
      {FarOff(2, -5000000), FarOff(0, kMin), FarOff(0, 1000000LL * 1000000), FarOff(2, 10020000)}));
  const RunAnalysis a = AnalyseRun(run);
  EXPECT_EQ(a.states_negative_time, 2);
  EXPECT_EQ(a.states_after_end, 2);  // 1e6 s, and one tick after the 10 s end
  EXPECT_EQ(a.states_damaged, 4);
  EXPECT_EQ(a.states_expected, 501 * 3);
  EXPECT_EQ(a.summary.states, 501 * 3);
  EXPECT_DOUBLE_EQ(a.summary.sim_time_s, 10.0);
  EXPECT_DOUBLE_EQ(a.leader_start_m.x(), 0.0);
  EXPECT_DOUBLE_EQ(a.leader_end_m.x(), 10.0);
  EXPECT_NEAR(a.summary.max_position_error_m, 0.0, 1e-12);
  EXPECT_EQ(a.complete_samples, 501);
}

// shoal sim --duration lengthens a run but logs the scenario's own text: when most
// vehicles ran past the scenario's end, they did, and nothing is damaged.
TEST(ImpossibleTimes, ARunLongerThanItsScenarioTextIsNotDamaged) {
  const RunAnalysis a = AnalyseRun(Load(WriteLogWithExtraStates("longer.lcmlog", 1001, {})));
  EXPECT_EQ(a.states_damaged, 0);
  EXPECT_EQ(a.states_expected, 1001 * 3);
  EXPECT_DOUBLE_EQ(a.summary.sim_time_s, 20.0);
}

// Without a scenario the expectation is the time most vehicles reach, never the largest
// time in the log; a time beyond twice that is damaged.
TEST(ImpossibleTimes, WithoutAScenarioMostVehiclesSetTheEnd) {
  constexpr Micros kMax = std::numeric_limits<Micros>::max();
  const RunData run =
      Load(WriteLogWithExtraStates("no_scenario.lcmlog", 500, {FarOff(1, kMax), FarOff(2, -1)}, ""));
  ASSERT_FALSE(run.has_scenario);
  const RunAnalysis a = AnalyseRun(run);
  EXPECT_EQ(a.period_us, kPeriod);
  EXPECT_EQ(a.states_expected, 500 * 3);
  EXPECT_EQ(a.states_after_end, 1);
  EXPECT_EQ(a.states_negative_time, 1);
  EXPECT_DOUBLE_EQ(a.summary.sim_time_s, ToSeconds(499 * kPeriod));
  EXPECT_EQ(a.ticks, 500);
  // Times with every vehicle's state need no scenario to be counted.
  EXPECT_FALSE(a.has_formation);
  EXPECT_EQ(a.complete_samples, 500);
}

// For a plot: the damaged states are removed from the tracks, and a warning says so.
TEST(ImpossibleTimes, DropImpossibleTimesLeavesTheRunAsItRan) {
  constexpr Micros kMax = std::numeric_limits<Micros>::max();
  RunData run = Load(WriteLogWithExtraStates("drop.lcmlog", 501, {FarOff(1, kMax), FarOff(0, -1)}));
  EXPECT_EQ(DropImpossibleTimes(&run), 2);
  for (const VehicleTrack& v : run.vehicles) {
    ASSERT_EQ(v.samples.size(), 501u) << v.id;
    EXPECT_EQ(v.samples.front().utime, 0);
    EXPECT_EQ(v.samples.back().utime, 500 * kPeriod);
  }
  ASSERT_FALSE(run.warnings.empty());
  EXPECT_NE(run.warnings.back().find("2 vehicle states and 0 channel events at impossible times"),
            std::string::npos)
      << run.warnings.back();
  EXPECT_EQ(AnalyseRun(run).states_damaged, 0);
  EXPECT_EQ(DropImpossibleTimes(&run), 0);
}

// ---- CSV ---------------------------------------------------------------------------------

std::vector<std::vector<std::string>> ReadCsv(const std::string& path) {
  std::vector<std::vector<std::string>> rows;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    std::string c;
    while (std::getline(ss, c, ',')) cells.push_back(c);
    rows.push_back(cells);
  }
  return rows;
}

TEST(Csv, EveryVehicleAndEventWithExactNumbers) {
  const RunData run = Load(WriteFormationLog(100));
  const RunAnalysis a = AnalyseRun(run);
  std::vector<std::string> files;
  std::string err;
  const std::string dir = Tmp("csv");
  ASSERT_TRUE(WriteRunCsv(run, a, dir, &files, &err)) << err;
  ASSERT_EQ(files.size(), 5u);  // 3 vehicles, channel events, health
  const auto lead = ReadCsv(dir + "/vehicle_0.csv");
  const auto f1 = ReadCsv(dir + "/vehicle_1.csv");
  ASSERT_EQ(lead.size(), 101u);  // header + 100 samples
  ASSERT_EQ(f1.size(), 101u);
  EXPECT_EQ(lead[0].size(), 30u);
  ASSERT_EQ(f1[0].size(), 36u);
  EXPECT_EQ(f1[0][0], "time_s");
  EXPECT_EQ(f1[0][30], "position_error_m");
  for (std::size_t r = 1; r < f1.size(); ++r) {
    ASSERT_EQ(f1[r].size(), 36u);
    const StateMsg& m = run.vehicles[1].samples[r - 1];
    EXPECT_EQ(std::stod(f1[r][0]), ToSeconds(m.utime));
    EXPECT_EQ(std::stoll(f1[r][1]), m.utime);
    for (int c = 0; c < 5; ++c) EXPECT_EQ(std::stod(f1[r][3 + c]), m.eta(c));  // exact
    EXPECT_EQ(std::stod(f1[r][30]), a.followers[0].errors[r - 1].position_m);
  }
  EXPECT_NEAR(std::stod(f1[1][33]), 3.0, 1e-9);  // error components at t = 0
  EXPECT_NEAR(std::stod(f1[1][34]), 4.0, 1e-9);
  const auto ch = ReadCsv(dir + "/channel_events.csv");
  ASSERT_EQ(ch.size(), 1u);  // header only
  EXPECT_EQ(ch[0].size(), 12u);
  // A file where a directory is needed.
  EXPECT_FALSE(WriteRunCsv(run, a, dir + "/vehicle_0.csv", &files, &err));
  EXPECT_NE(err.find("not a directory"), std::string::npos) << err;
}


// ---- Channel events at impossible times --------------------------------------------------

// 400 ticks (7.98 s of the 10 s scenario) of states and of the channel of WriteChannelLog
// (0 -> 1: 0.1 s, every 4th lost; 1 -> 2: delivered 0.04 s after sending), written as
// single events, then `extra_events` and `extra_states` as a damaged or forged log would
// hold them. Without `toml` the log declares no scenario.
std::string WriteDamagedChannelLog(const std::string& name,
                                   const std::vector<ChannelDecision>& extra_events,
                                   const std::vector<StateMsg>& extra_states = {},
                                   const char* toml = kScenario) {
  const std::string path = Tmp(name);
  LogWriter log(path);
  log.Write(channels::Status(), 0, Status(0, kLauncherId, "running", toml));
  std::int32_t seq = 0;
  for (int k = 0; k < 400; ++k) {
    const Micros t = k * kPeriod;
    for (int id = 0; id <= 2; ++id) {
      log.Write(channels::State(id), t, ToLcm(State(id, t, Vec5::Zero(), Vec5::Zero())));
    }
    const std::int8_t s01 = k % 4 == 3 ? 1 : 0;
    log.Write(channels::ChannelEvents(), t,
              ToLcm(Decision(0, 1, t, 0.1, s01 == 0 ? t + 100000 : 0, s01), seq++));
    log.Write(channels::ChannelEvents(), t, ToLcm(Decision(1, 2, t, 0.03, t + 40000, 0), seq++));
  }
  for (const ChannelDecision& d : extra_events) log.Write(channels::ChannelEvents(), 0, ToLcm(d, seq++));
  for (const StateMsg& m : extra_states) log.Write(channels::State(m.vehicle_id), 0, ToLcm(m));
  return path;
}

// Sent at 1e9 s, at -1 s, on a link the scenario does not have at 1e9 s; delivered 1e9 s
// after it was sent, and delivered a second before it was sent.
std::vector<ChannelDecision> ForgedEvents() {
  constexpr Micros kFar = 1000000LL * 1000000000;  // 1e9 s
  return {Decision(1, 2, kFar, 0.03, kFar + 40000, 0), Decision(0, 1, -1000000, 0.1, 0, 1),
          Decision(2, 0, kFar, 0.1, kFar + 100000, 0), Decision(1, 2, 2000000, 0.03, kFar, 0),
          Decision(0, 1, 3000000, 0.1, 2000000, 0)};
}

void ExpectSameQuantiles(const Quantiles& a, const Quantiles& b, const char* what) {
  EXPECT_EQ(a.count, b.count) << what;
  for (auto f : {&Quantiles::min, &Quantiles::p50, &Quantiles::p99, &Quantiles::max,
                 &Quantiles::mean}) {
    EXPECT_EQ(a.*f, b.*f) << what;
  }
}

// Taken as they are, an event delivered 1e9 s after it was sent would be the realised
// delay's maximum, one delivered before it was sent a negative message age: events at
// impossible times are counted as damaged and every channel figure is the clean run's.
TEST(ImpossibleTimes, ChannelEventsAtImpossibleTimesAreDamagedNotMeasured) {
  const RunData clean_run = Load(WriteDamagedChannelLog("ch_clean.lcmlog", {}));
  const RunData run = Load(WriteDamagedChannelLog("ch_forged.lcmlog", ForgedEvents()));
  ASSERT_EQ(run.channel_events.size(), clean_run.channel_events.size() + 5);
  const ChannelAnalysis clean = AnalyseRun(clean_run).channel;
  const RunAnalysis a = AnalyseRun(run);
  const ChannelAnalysis& c = a.channel;
  EXPECT_EQ(clean.events_damaged, 0);
  EXPECT_EQ(c.events_damaged, 5);
  EXPECT_EQ(c.events_sent_impossible, 3);
  EXPECT_EQ(c.events_delivered_impossible, 2);
  EXPECT_EQ(c.sent, clean.sent);
  EXPECT_EQ(c.delivered, clean.delivered);
  EXPECT_EQ(c.dropped_loss, clean.dropped_loss);
  EXPECT_EQ(a.summary.delivered, clean.delivered);
  EXPECT_EQ(c.unknown_links, 0);  // the forged 2 -> 0 is no link of the run
  EXPECT_EQ(c.model_mismatches, 0);
  ExpectSameQuantiles(c.realised_delay_s, clean.realised_delay_s, "realised delay");
  ExpectSameQuantiles(c.delay_error_s, clean.delay_error_s, "delay error");
  ExpectSameQuantiles(c.age_at_use_s, clean.age_at_use_s, "age at use");
  EXPECT_NEAR(c.realised_delay_s.max, 0.1, 1e-12);
  EXPECT_GE(c.age_at_use_s.min, 0.0);
  ASSERT_EQ(c.links.size(), clean.links.size());
  for (std::size_t li = 0; li < c.links.size(); ++li) {
    EXPECT_EQ(c.links[li].sent, clean.links[li].sent) << li;
    EXPECT_EQ(c.links[li].delivered, clean.links[li].delivered) << li;
    EXPECT_EQ(c.links[li].ticks_before_first, clean.links[li].ticks_before_first) << li;
    ExpectSameQuantiles(c.links[li].realised_delay_s, clean.links[li].realised_delay_s, "link");
    ExpectSameQuantiles(c.links[li].age_at_use_s, clean.links[li].age_at_use_s, "link age");
  }
  // Still aligned with the events, NaN at the damaged ones.
  ASSERT_EQ(c.configured_delay_s.size(), run.channel_events.size());
  for (std::size_t k = 0; k < run.channel_events.size(); ++k) {
    EXPECT_EQ(std::isnan(c.configured_delay_s[k]), k >= clean_run.channel_events.size()) << k;
  }
}

// The last possible delivery: a message sent at the run's end (10 s), delayed by the
// largest delay of any link (0.1 s, + 1 us for rounding tau to microseconds), delivered at
// the next tick (+ one period). Without a scenario the run's own length stands in for the
// largest delay.
TEST(ImpossibleTimes, TheLastPossibleDeliveryIsTheEndPlusTheLargestDelayAndAPeriod) {
  const StateTimeBounds b = StateTimeBoundsOf(Load(WriteDamagedChannelLog("ch_bound.lcmlog", {})));
  EXPECT_EQ(b.limit_us, 10000000);
  EXPECT_EQ(b.deliver_limit_us, 10000000 + 100001 + kPeriod);
  const auto when = [&](Micros send, Micros deliver, std::int8_t status = 0) {
    return ChannelEventTimeOf(ChannelEventRecord{send, deliver, 0.1, 0, 0, 1, status}, b);
  };
  EXPECT_EQ(when(10000000, b.deliver_limit_us), EventTime::kPossible);
  EXPECT_EQ(when(10000000, b.deliver_limit_us + 1), EventTime::kDeliveryImpossible);
  EXPECT_EQ(when(10000001, 10000001), EventTime::kSendImpossible);
  EXPECT_EQ(when(0, 0), EventTime::kPossible);  // no delay at all
  EXPECT_EQ(when(-1, 0), EventTime::kSendImpossible);
  EXPECT_EQ(when(500000, 499999), EventTime::kDeliveryImpossible);
  EXPECT_EQ(when(500000, 0, 1), EventTime::kPossible);  // a drop has no delivery time
  EXPECT_EQ(when(500000, -7, 2), EventTime::kPossible);

  const StateTimeBounds n =
      StateTimeBoundsOf(Load(WriteDamagedChannelLog("ch_bound_none.lcmlog", {}, {}, "")));
  EXPECT_EQ(n.limit_us, 2 * 399 * kPeriod);  // twice what most vehicles reach
  EXPECT_EQ(n.deliver_limit_us, 2 * n.limit_us + kPeriod);
  // Nothing to judge an end by (no scenario, no state): only the order of the times.
  const StateTimeBounds unknown;
  EXPECT_EQ(ChannelEventTimeOf(ChannelEventRecord{kPeriod << 40, (kPeriod << 40) + 1}, unknown),
            EventTime::kPossible);
  EXPECT_EQ(ChannelEventTimeOf(ChannelEventRecord{kPeriod, 0}, unknown),
            EventTime::kDeliveryImpossible);
}

// For a plot: the same events are removed (one rule), and the warning says how many.
TEST(ImpossibleTimes, DropImpossibleTimesRemovesTheSameChannelEvents) {
  const RunData clean = Load(WriteDamagedChannelLog("ch_drop_clean.lcmlog", {}));
  RunData run = Load(WriteDamagedChannelLog("ch_drop.lcmlog", ForgedEvents()));
  EXPECT_EQ(DropImpossibleTimes(&run), 5);
  ASSERT_EQ(run.channel_events.size(), clean.channel_events.size());
  for (std::size_t k = 0; k < run.channel_events.size(); ++k) {
    EXPECT_EQ(run.channel_events[k].send_utime, clean.channel_events[k].send_utime) << k;
    EXPECT_EQ(run.channel_events[k].deliver_utime, clean.channel_events[k].deliver_utime) << k;
  }
  ASSERT_FALSE(run.warnings.empty());
  EXPECT_NE(run.warnings.back().find("0 vehicle states and 5 channel events at impossible times"),
            std::string::npos)
      << run.warnings.back();
  EXPECT_NE(run.warnings.back().find("delivered after 10.12 s"), std::string::npos)
      << run.warnings.back();
  EXPECT_EQ(AnalyseRun(run).channel.events_damaged, 0);
}

// A user importing the CSV gets the run's rows only: states and channel events at
// impossible times would otherwise be rows at 1e9 s or -1 s (with NaN errors) that
// stretch every plot of the file.
TEST(Csv, StatesAndChannelEventsAtImpossibleTimesAreLeftOut) {
  constexpr Micros kMax = std::numeric_limits<Micros>::max();
  const RunData run = Load(WriteDamagedChannelLog(
      "csv_damaged.lcmlog", ForgedEvents(), {FarOff(1, kMax), FarOff(1, -1), FarOff(0, 10020000)}));
  const RunAnalysis a = AnalyseRun(run);
  ASSERT_EQ(a.states_damaged, 3);
  std::vector<std::string> files;
  std::string err;
  const std::string dir = Tmp("csv_damaged");
  ASSERT_TRUE(WriteRunCsv(run, a, dir, &files, &err)) << err;
  for (int id = 0; id <= 2; ++id) {
    const auto rows = ReadCsv(dir + "/vehicle_" + std::to_string(id) + ".csv");
    ASSERT_EQ(rows.size(), 401u) << id;  // header + the 400 ticks
    for (std::size_t r = 1; r < rows.size(); ++r) {
      EXPECT_EQ(std::stoll(rows[r][1]), static_cast<Micros>(r - 1) * kPeriod) << id;
      if (id >= 1) {
        EXPECT_NE(rows[r][30], "NaN") << id << " row " << r;
      }
    }
  }
  const auto ch = ReadCsv(dir + "/channel_events.csv");
  ASSERT_EQ(ch.size(), 1u + 800u);
  for (std::size_t r = 1; r < ch.size(); ++r) {
    const Micros send = std::stoll(ch[r][1]);
    EXPECT_TRUE(send >= 0 && send < 400 * kPeriod) << r;
    if (ch[r][6] == "1") {
      EXPECT_LE(std::stod(ch[r][8]), 0.1 + 1e-12) << r;
    }
  }
}

// With no scenario and no state there is no end to judge by: only an event sent at a
// negative time or delivered before it was sent is damaged, and the DAMAGED line names no
// end (it once printed "after nan s").
TEST(ImpossibleTimes, WithoutAnEndOnlyTheSignAndOrderOfTheTimesCount) {
  RunData run;
  run.channel_events = {ChannelEventRecord{kPeriod << 40, (kPeriod << 40) + 1, 0.0, 0, 0, 1, 0},
                        ChannelEventRecord{-1, 0, 0.0, 0, 0, 1, 1},
                        ChannelEventRecord{kPeriod, 0, 0.0, 0, 0, 1, 0}};
  const RunAnalysis a = AnalyseRun(run);
  EXPECT_EQ(a.channel.events_sent_impossible, 1);
  EXPECT_EQ(a.channel.events_delivered_impossible, 1);
  EXPECT_EQ(a.channel.sent, 1);
  const std::string path = Tmp("no_end.txt");
  std::FILE* f = std::fopen(path.c_str(), "w");
  ASSERT_NE(f, nullptr);
  PrintAnalysisText(f, run, a, AnalysisSource{false, "no_end.lcmlog"});
  std::fclose(f);
  const std::string text = ReadBytes(path);
  EXPECT_NE(text.find("DAMAGED: 2 channel events at impossible times (1 sent at a negative "
                      "time, 1 delivered before sent)"),
            std::string::npos) << text;
  EXPECT_EQ(text.find("nan"), std::string::npos) << text;
}

}  // namespace
}  // namespace shoal
