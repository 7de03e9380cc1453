// shoal analyze on runs with a scenario timeline ([[event]]): the channel's timeline
// statuses, the delay model in force for the model check, the links of every topology, and
// per event the formation's excursion and re-convergence and the decisions in its window.
// The runs are shoal sim's (RunSimulation writes the log; it is read back with the
// scenario given in code), the expected figures computed directly from the logged states.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "analysis/analysis.h"
#include "analysis/analysis_json.h"
#include "analysis/analysis_text.h"
#include "analysis/run_data.h"
#include "analysis/sim_report.h"
#include "core/channel_model.h"
#include "core/metrics.h"
#include "scenario/loader.h"

namespace shoal {
namespace {

std::string Tmp(const std::string& name) {
  const std::string dir = std::string(SHOAL_BINARY_DIR) + "/test_tmp";
  std::system(("mkdir -p " + dir).c_str());
  const ::testing::TestInfo* t = ::testing::UnitTest::GetInstance()->current_test_info();
  return dir + "/analysis_events_" + std::string(t->name()) + "_" + name;
}

Scenario Example2(double seconds) {
  Scenario s = LoadScenario(std::string(SHOAL_SOURCE_DIR) + "/scenarios/paper_example2.toml");
  s.duration_s = seconds;
  return s;
}

ScenarioEvent Event(EventKind kind, double at_s, double until_s) {
  ScenarioEvent e;
  e.kind = kind;
  e.at_s = at_s;
  e.until_s = until_s;
  return e;
}

struct Analysed {
  RunData run;
  RunAnalysis a;
};

/// shoal sim's run of `s`, logged, read back with `s` and analysed.
Analysed SimulateAndAnalyse(const Scenario& s) {
  SimRunOptions opt;
  opt.out = Tmp("run.lcmlog");
  SimReport report;
  std::string error;
  EXPECT_TRUE(RunSimulation(s, opt, &report, &error)) << error;
  Analysed r;
  LoadOptions lo;
  lo.scenario = &s;
  EXPECT_TRUE(LoadRunLog(opt.out, lo, &r.run, &error)) << error;
  r.a = AnalyseRun(r.run);
  return r;
}

/// The worst follower at each leader sample, computed directly from the tracks.
struct Worst {
  double t, position, velocity;
  bool violating;
};
std::vector<Worst> WorstErrors(const RunData& run) {
  std::vector<Worst> w;
  const Scenario& s = run.scenario;
  const std::vector<StateMsg>& lead = run.vehicles[0].samples;
  for (std::size_t k = 0; k < lead.size(); ++k) {
    Worst x{ToSeconds(lead[k].utime), 0.0, 0.0, false};
    for (int i = 1; i <= s.followers; ++i) {
      const StateMsg& f = run.vehicles[i].samples.at(k);
      EXPECT_EQ(f.utime, lead[k].utime);
      const FormationErrors e = ErrorsOf(f, s.offsets_m[i - 1], lead[k]);
      x.position = std::max(x.position, e.position_m);
      x.velocity = std::max(x.velocity, e.velocity_mps);
      x.violating = x.violating || e.position_m > s.metrics.position_tol_m ||
                    e.velocity_mps > s.metrics.velocity_tol_mps;
    }
    w.push_back(x);
  }
  return w;
}

/// The first time t >= from after which (up to `to`, inclusive) no sample violates,
/// searching back from `to`; -1 if the sample at `to` violates.
double ReconvergedAt(const std::vector<Worst>& w, double from, double to) {
  double at = -1.0;
  for (auto it = w.rbegin(); it != w.rend(); ++it) {
    if (it->t > to) continue;
    if (it->t < from || it->violating) break;
    at = it->t;
  }
  return at;
}

/// Count of the run's decisions of link (from, to) with status `st` sent in [a, b) seconds.
std::int64_t Decisions(const RunData& run, int from, int to, int st, double a, double b) {
  std::int64_t k = 0;
  for (const ChannelEventRecord& e : run.channel_events) {
    const double t = ToSeconds(e.send_utime);
    k += e.sender == from && e.receiver == to && e.status == st && t >= a && t < b;
  }
  return k;
}

const LinkAnalysis& LinkOf(const RunAnalysis& a, int from, int to) {
  for (const LinkAnalysis& l : a.channel.links) {
    if (l.from == from && l.to == to) return l;
  }
  ADD_FAILURE() << "no link " << from << "->" << to;
  return a.channel.links.front();
}

std::string Text(const Analysed& r) {
  char* buf = nullptr;
  std::size_t size = 0;
  std::FILE* f = open_memstream(&buf, &size);
  PrintAnalysisText(f, r.run, r.a, AnalysisSource{false, "run.lcmlog"});
  std::fclose(f);
  std::string s(buf, size);
  std::free(buf);
  return s;
}

TEST(AnalysisEvents, ControllerResetExcursionAndReconvergenceMatchTheStates) {
  Scenario s = Example2(140.0);
  s.metrics.position_tol_m = 0.3;
  s.metrics.velocity_tol_mps = 0.05;
  ScenarioEvent reset = Event(EventKind::kControllerReset, 65.0, 1e300);
  reset.vehicles = {3};
  reset.outage_s = 10.0;
  s.events = {reset};
  const Analysed r = SimulateAndAnalyse(s);
  ASSERT_EQ(r.a.events.size(), 1u);
  const EventAnalysis& e = r.a.events[0];
  EXPECT_EQ(e.kind, EventKind::kControllerReset);
  EXPECT_EQ(e.at_s, 65.0);
  EXPECT_EQ(e.end_s, 75.0);
  EXPECT_TRUE(e.ends_in_run);
  EXPECT_EQ(e.affects, "vehicle 3");
  EXPECT_EQ(e.horizon_s, 140.0);

  const std::vector<Worst> w = WorstErrors(r.run);
  // Converged before the reset, so the excursion is the reset's.
  ASSERT_GE(ReconvergedAt(w, 0.0, 64.98), 0.0) << "no converged formation before the reset";
  const double back = ReconvergedAt(w, 75.0, 140.0);
  ASSERT_GT(back, 75.0) << "the reset must push the formation out of tolerance";
  EXPECT_TRUE(e.reconverged);
  EXPECT_DOUBLE_EQ(e.reconverged_at_s, back);
  EXPECT_DOUBLE_EQ(e.time_to_reconverge_s, back - 75.0);
  double pos = 0.0, vel = 0.0, before = 0.0;
  for (const Worst& x : w) {
    if (x.t >= 65.0 && x.t <= back) pos = std::max(pos, x.position), vel = std::max(vel, x.velocity);
    if (x.t >= 60.0 && x.t < 65.0) before = std::max(before, x.position);
  }
  EXPECT_DOUBLE_EQ(e.max_position_error_m, pos);
  EXPECT_DOUBLE_EQ(e.max_velocity_error_mps, vel);
  EXPECT_EQ(e.max_position_follower, 3);
  EXPECT_GT(pos, before);
  // Every decision of the window (a reset affects no link: all are counted).
  std::int64_t in_window = 0, counted = 0;
  for (const ChannelEventRecord& d : r.run.channel_events) {
    in_window += d.send_utime >= 65000000 && d.send_utime < 75000000;
  }
  for (std::int64_t n : e.decisions) counted += n;
  EXPECT_EQ(counted, in_window);
  EXPECT_EQ(e.decisions[0], in_window);  // the channel itself works on

  const std::string text = Text(r);
  EXPECT_NE(text.find("event 1 controller_reset at 65.00 s until 75.00 s: vehicle 3"),
            std::string::npos) << text;
  EXPECT_NE(text.find("re-converged"), std::string::npos) << text;
}

TEST(AnalysisEvents, ResetToTheEndOfTheRunDoesNotReconvergeAndIsNullInJson) {
  Scenario s = Example2(100.0);
  s.metrics.position_tol_m = 0.3;
  s.metrics.velocity_tol_mps = 0.05;
  ScenarioEvent reset = Event(EventKind::kControllerReset, 80.0, 1e300);
  reset.vehicles = {2};
  reset.outage_s = 100.0;
  s.events = {reset};
  const Analysed r = SimulateAndAnalyse(s);
  ASSERT_EQ(r.a.events.size(), 1u);
  const EventAnalysis& e = r.a.events[0];
  EXPECT_FALSE(e.ends_in_run);
  EXPECT_EQ(e.end_s, 100.0);
  EXPECT_EQ(e.reference_s, 80.0);
  EXPECT_FALSE(e.reconverged);
  const std::vector<Worst> w = WorstErrors(r.run);
  EXPECT_TRUE(w.back().violating);
  double pos = 0.0;
  for (const Worst& x : w) {
    if (x.t >= 80.0) pos = std::max(pos, x.position);
  }
  EXPECT_DOUBLE_EQ(e.max_position_error_m, pos);
  const auto j = AnalysisJson(r.run, r.a, AnalysisSource{false, "run.lcmlog"});
  EXPECT_TRUE(j["events"][0]["time_to_reconverge_s"].is_null());
  EXPECT_EQ(j["events"][0]["reconverged"], false);
  EXPECT_EQ(j["events"][0]["kind"], "controller_reset");
  EXPECT_NE(Text(r).find("did not re-converge"), std::string::npos);
}

TEST(AnalysisEvents, LinkDownOfAPinnedLinkIsCountedPerLinkAndPerEvent) {
  Scenario s = Example2(20.0);
  ScenarioEvent down = Event(EventKind::kLinkDown, 5.0, 7.0);
  down.links = {{0, 1}};
  s.events = {down};
  const Analysed r = SimulateAndAnalyse(s);
  const ChannelAnalysis& c = r.a.channel;
  const std::int64_t expected = Decisions(r.run, 0, 1, ChannelDecision::kDroppedLinkDown, 5.0, 7.0);
  EXPECT_EQ(expected, 100);  // 2 s of 50 Hz states on the leader's link to follower 1
  EXPECT_EQ(Decisions(r.run, 0, 1, ChannelDecision::kDroppedLinkDown, 0.0, 20.0), 100);
  EXPECT_EQ(c.dropped_link_down, 100);
  EXPECT_EQ(LinkOf(r.a, 0, 1).dropped_link_down, 100);
  EXPECT_EQ(LinkOf(r.a, 0, 3).dropped_link_down, 0);
  EXPECT_EQ(c.dropped_invalid, 0);
  EXPECT_EQ(c.events_damaged, 0);
  EXPECT_EQ(c.model_mismatches, 0);
  EXPECT_EQ(c.unknown_links, 0);
  EXPECT_EQ(c.dropped, c.dropped_loss + c.dropped_queue + c.dropped_range + c.dropped_link_down +
                           c.dropped_deaf + c.dropped_invalid);
  ASSERT_EQ(r.a.events.size(), 1u);
  const EventAnalysis& e = r.a.events[0];
  EXPECT_EQ(e.affects, "link 0->1");
  EXPECT_EQ(e.decisions[ChannelDecision::kDroppedLinkDown], 100);
  EXPECT_EQ(e.decisions[ChannelDecision::kDelivered], 0);
  const auto j = AnalysisJson(r.run, r.a, AnalysisSource{false, "run.lcmlog"});
  EXPECT_EQ(j["channel"]["dropped_link_down"], 100);
  EXPECT_EQ(j["events"][0]["decisions"]["dropped_link_down"], 100);
  EXPECT_NE(Text(r).find("timeline: 100 dropped: link down"), std::string::npos);
}

// Two events on a converged formation: a short outage of the leader's link to follower 1
// and, later, a reset of follower 4. The first's re-convergence is judged up to the
// second's start (its horizon), the second's to the end of the run.
TEST(AnalysisEvents, ShortLinkDownThenResetEachJudgedUpToTheNextEvent) {
  Scenario s = Example2(140.0);
  s.metrics.position_tol_m = 0.3;
  s.metrics.velocity_tol_mps = 0.05;
  ScenarioEvent down = Event(EventKind::kLinkDown, 65.0, 66.5);
  down.links = {{0, 1}};
  ScenarioEvent reset = Event(EventKind::kControllerReset, 90.0, 1e300);
  reset.vehicles = {4};
  reset.outage_s = 8.0;
  s.events = {down, reset};
  const Analysed r = SimulateAndAnalyse(s);
  ASSERT_EQ(r.a.events.size(), 2u);
  const std::vector<Worst> w = WorstErrors(r.run);
  const EventAnalysis& d = r.a.events[0];
  EXPECT_EQ(d.horizon_s, 90.0);
  EXPECT_EQ(d.decisions[ChannelDecision::kDroppedLinkDown], 75);  // 1.5 s at 50 Hz
  // Re-convergence up to (not including) the reset's start at 90 s.
  const double d_back = ReconvergedAt(w, 66.5, 89.98);
  ASSERT_GE(d_back, 66.5);
  EXPECT_TRUE(d.reconverged);
  EXPECT_DOUBLE_EQ(d.reconverged_at_s, d_back);
  double pos = 0.0, vel = 0.0;
  for (const Worst& x : w) {
    if (x.t >= 65.0 && x.t <= d_back) pos = std::max(pos, x.position), vel = std::max(vel, x.velocity);
  }
  EXPECT_DOUBLE_EQ(d.max_position_error_m, pos);
  EXPECT_DOUBLE_EQ(d.max_velocity_error_mps, vel);

  const EventAnalysis& e = r.a.events[1];
  EXPECT_EQ(e.horizon_s, 140.0);
  const double e_back = ReconvergedAt(w, 98.0, 140.0);
  ASSERT_GT(e_back, 98.0);
  EXPECT_DOUBLE_EQ(e.reconverged_at_s, e_back);
  EXPECT_DOUBLE_EQ(e.time_to_reconverge_s, e_back - 98.0);
  EXPECT_EQ(e.max_position_follower, 4);
  EXPECT_GT(e.max_position_error_m, s.metrics.position_tol_m);
}

TEST(AnalysisEvents, SilentAndDeafAreCountedNeitherInvalidNorDamaged) {
  Scenario s = Example2(12.0);
  ScenarioEvent silent = Event(EventKind::kVehicleSilent, 2.0, 3.0);
  silent.vehicles = {2};  // sends to follower 5 only
  ScenarioEvent deaf = Event(EventKind::kVehicleDeaf, 4.0, 5.0);
  deaf.vehicles = {4};    // receives from follower 5 only
  s.events = {silent, deaf};
  const Analysed r = SimulateAndAnalyse(s);
  const ChannelAnalysis& c = r.a.channel;
  EXPECT_EQ(c.skipped_silent, 50);
  EXPECT_EQ(LinkOf(r.a, 2, 5).skipped_silent, 50);
  EXPECT_EQ(c.dropped_deaf, LinkOf(r.a, 5, 4).dropped_deaf);
  // Judged when due: every message due in [4, 5) s, none other (delays vary with tau(t)).
  EXPECT_GE(c.dropped_deaf, 45);
  EXPECT_LE(c.dropped_deaf, 55);
  for (const ChannelEventRecord& e : r.run.channel_events) {
    if (e.status != ChannelDecision::kDroppedDeaf) continue;
    const Micros due = DeliveryTime(e.send_utime, e.delay_s, s.period_us());
    EXPECT_TRUE(due >= 4000000 && due < 5000000) << due;
  }
  EXPECT_EQ(c.dropped_invalid, 0);
  EXPECT_EQ(c.events_damaged, 0);
  EXPECT_EQ(c.model_mismatches, 0);
  // A silent sender's decisions are not sent.
  const LinkAnalysis& l = LinkOf(r.a, 2, 5);
  EXPECT_EQ(l.sent + l.skipped_silent, Decisions(r.run, 2, 5, 0, 0, 13) +
                                           Decisions(r.run, 2, 5, ChannelDecision::kSkippedSilent, 0, 13) +
                                           Decisions(r.run, 2, 5, 1, 0, 13));
  ASSERT_EQ(r.a.events.size(), 2u);
  EXPECT_EQ(r.a.events[0].decisions[ChannelDecision::kSkippedSilent], 50);
  EXPECT_EQ(r.a.events[1].decisions[ChannelDecision::kDroppedDeaf], c.dropped_deaf);
  EXPECT_EQ(r.a.events[1].affects, "vehicle 4");
}

// An event that ends right at the run's end holds on [at, end): the final tick's decisions
// are not its own (here a link_down that starts there makes one); one the end cuts short
// holds at the final tick too.
TEST(AnalysisEvents, AnEventEndingAtTheRunsEndLeavesItsFinalTickOut) {
  Scenario s = Example2(10.0);
  ScenarioEvent silent = Event(EventKind::kVehicleSilent, 9.0, 10.0);
  silent.vehicles = {2};  // sends to follower 5 only
  ScenarioEvent down = Event(EventKind::kLinkDown, 10.0, 1e300);
  down.links = {{2, 5}};
  ScenarioEvent longer = Event(EventKind::kVehicleSilent, 9.5, 11.0);
  longer.vehicles = {4};  // sends to follower 5 only
  s.events = {silent, longer, down};
  const Analysed r = SimulateAndAnalyse(s);
  ASSERT_EQ(r.a.events.size(), 3u);
  const EventAnalysis& e = r.a.events[0];
  EXPECT_FALSE(e.ends_in_run);
  EXPECT_EQ(e.decisions[ChannelDecision::kSkippedSilent], 50);
  EXPECT_EQ(e.decisions[ChannelDecision::kDroppedLinkDown], 0);
  // 9.5 s to the final tick at 10 s, included: 26 states of follower 4.
  EXPECT_EQ(r.a.events[1].decisions[ChannelDecision::kSkippedSilent], 26);
  EXPECT_EQ(r.a.events[2].decisions[ChannelDecision::kDroppedLinkDown], 1);
}

TEST(AnalysisEvents, ChannelEventDelayIsTheModelInForceAndTopologyLinksAreKnown) {
  Scenario s = Example2(12.0);
  ScenarioEvent ch = Event(EventKind::kChannel, 3.0, 6.0);
  ch.links = {{0, 1}};
  DelayConfig d;
  d.kind = DelayKind::kConstant;
  d.base_s = 0.3;
  ch.delay = d;
  ScenarioEvent topo = Event(EventKind::kTopology, 8.0, 1e300);
  topo.edges = {{1, 2}, {2, 1}, {3, 4}, {4, 3}, {5, 4}};
  topo.leader_links = {1, 2, 3, 4, 5};
  s.events = {ch, topo};
  const Analysed r = SimulateAndAnalyse(s);
  const ChannelAnalysis& c = r.a.channel;
  EXPECT_EQ(c.model_mismatches, 0);
  EXPECT_EQ(c.unknown_links, 0);
  EXPECT_TRUE(LinkOf(r.a, 0, 2).in_scenario);  // a link of the second topology only
  EXPECT_GT(LinkOf(r.a, 0, 2).sent, 0);
  // The run drew the event's delay in its window, and the analysis configured it.
  std::int64_t changed = 0;
  for (std::size_t k = 0; k < r.run.channel_events.size(); ++k) {
    const ChannelEventRecord& e = r.run.channel_events[k];
    if (e.sender != 0 || e.receiver != 1) continue;
    const bool in = e.send_utime >= 3000000 && e.send_utime < 6000000;
    if (in) {
      EXPECT_EQ(e.delay_s, 0.3);
      EXPECT_EQ(c.configured_delay_s[k], 0.3);
      ++changed;
    } else {
      EXPECT_NE(c.configured_delay_s[k], 0.3);
    }
  }
  EXPECT_EQ(changed, 150);
  ASSERT_EQ(r.a.events.size(), 2u);
  EXPECT_EQ(r.a.events[1].affects, "edges 1<-2 2<-1 3<-4 4<-3 5<-4, leader links 1, 2, 3, 4, 5");
}

// A link's message age is measured at the ticks at which its receiver uses it: not while
// the topology in force leaves it out, not while the receiver's controller is reset (its
// deliveries are dropped then, and the reset forgets what it held).
TEST(AnalysisEvents, MessageAgeCountsOnlyTheTicksAtWhichTheLinkIsUsed) {
  Scenario s = Example2(12.0);
  ScenarioEvent reset = Event(EventKind::kControllerReset, 1.0, 1e300);
  reset.vehicles = {1};
  reset.outage_s = 1.0;
  ScenarioEvent topo = Event(EventKind::kTopology, 3.0, 8.0);  // 2<-5 and 5<-2 left out
  topo.edges = {{1, 3}, {2, 1}, {3, 1}, {4, 5}, {5, 4}};
  topo.leader_links = {1, 2, 3, 4, 5};
  s.events = {reset, topo};
  const Analysed r = SimulateAndAnalyse(s);
  // Ticks 0..600; in use: 5->2 at [0, 3) and [8, 12]; 0->2 at [3, 8); 3->1 but at [1, 2).
  const std::pair<std::pair<int, int>, std::int64_t> in_use[] = {
      {{5, 2}, 150 + 201}, {{2, 5}, 150 + 201}, {{0, 2}, 250}, {{3, 1}, 601 - 50},
      {{0, 1}, 601 - 50}, {{1, 2}, 601}};
  for (const auto& [link, ticks] : in_use) {
    const LinkAnalysis& l = LinkOf(r.a, link.first, link.second);
    EXPECT_EQ(l.age_at_use_s.count + l.ticks_stale + l.ticks_before_first, ticks)
        << link.first << "->" << link.second;
    EXPECT_EQ(l.ticks_stale, 0) << link.first << "->" << link.second;
    // A link is empty at the start, after a reset and when it comes back, until its first
    // delivery there (Example 2's delay is at most 0.15 s: 8 ticks).
    EXPECT_LE(l.ticks_before_first, 3 * 8) << link.first << "->" << link.second;
  }
  for (const FollowerAnalysis& f : r.a.followers) EXPECT_EQ(f.stale_ticks, 0) << f.id;
}

TEST(AnalysisEvents, RunWithoutEventsHasNoEventTextAndAnEmptyJsonArray) {
  const Analysed r = SimulateAndAnalyse(Example2(3.0));
  EXPECT_TRUE(r.a.events.empty());
  const std::string text = Text(r);
  EXPECT_EQ(text.find("events:"), std::string::npos);
  EXPECT_EQ(text.find("timeline:"), std::string::npos);
  const auto j = AnalysisJson(r.run, r.a, AnalysisSource{false, "run.lcmlog"});
  EXPECT_TRUE(j["events"].is_array());
  EXPECT_TRUE(j["events"].empty());
  EXPECT_EQ(j["channel"]["skipped_silent"], 0);
}

}  // namespace
}  // namespace shoal
