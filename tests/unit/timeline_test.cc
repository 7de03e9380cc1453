// The scenario timeline ([[event]]) in the core: what the Timeline says holds at a time,
// what the channel decides under each event kind, and what a follower does when its
// topology switches or its controller is reset. Events are built in code here; their
// TOML form is tested with the loader.
#include "core/timeline.h"

#include <gtest/gtest.h>

#include <map>
#include <memory>
#include <set>
#include <vector>

#include "core/channel_model.h"
#include "core/follower.h"
#include "core/swarm.h"
#include "scenario/loader.h"

namespace shoal {
namespace {

constexpr Micros kSecond = 1000000;

Scenario Example2() {
  return LoadScenario(std::string(SHOAL_SOURCE_DIR) + "/scenarios/paper_example2.toml");
}

ScenarioEvent Event(EventKind kind, double at_s, double until_s) {
  ScenarioEvent e;
  e.kind = kind;
  e.at_s = at_s;
  e.until_s = until_s;
  return e;
}

/// Runs shoal sim's loop for `seconds` and returns every channel decision and state.
struct Recorder : SwarmObserver {
  std::vector<ChannelDecision> decisions;
  std::vector<StateMsg> states;
  void OnChannel(const ChannelDecision& d) override { decisions.push_back(d); }
  void OnState(const StateMsg& m) override { states.push_back(m); }
};

Recorder Simulate(const Scenario& s, double seconds) {
  Swarm swarm(s, seconds);
  Recorder r;
  swarm.Run(&r);
  return r;
}

bool Within(Micros t, double a, double b) { return t >= a * kSecond && t < b * kSecond; }

TEST(Timeline, EmptyWithoutEventsAndTheWholeRunIsOneState) {
  const Scenario s = Example2();
  const Timeline t(s);
  EXPECT_TRUE(t.empty());
  EXPECT_EQ(t.TopologyAt(5 * kSecond), 0);
}

TEST(Timeline, WindowsHoldFromAtUntilUntil) {
  Scenario s = Example2();
  ScenarioEvent down = Event(EventKind::kLinkDown, 2.0, 4.0);
  down.links = {{0, 1}};
  s.events.push_back(down);
  ScenarioEvent deaf = Event(EventKind::kVehicleDeaf, 3.0, 1e300);
  deaf.vehicles = {4};
  s.events.push_back(deaf);
  const Timeline t(s);
  const int k = t.LinkIndex(0, 1);
  ASSERT_GE(k, 0);
  EXPECT_FALSE(t.LinkDown(k, 2 * kSecond - 1));
  EXPECT_TRUE(t.LinkDown(k, 2 * kSecond));
  EXPECT_TRUE(t.LinkDown(k, 4 * kSecond - 1));
  EXPECT_FALSE(t.LinkDown(k, 4 * kSecond));
  EXPECT_FALSE(t.LinkDown(t.LinkIndex(0, 3), 3 * kSecond));  // not listed
  EXPECT_FALSE(t.Deaf(4, 3 * kSecond - 1));
  EXPECT_TRUE(t.Deaf(4, 3 * kSecond));
  EXPECT_TRUE(t.Deaf(4, 1000 * kSecond));
  EXPECT_FALSE(t.Deaf(3, 1000 * kSecond));
}

// A topology without until_s holds until the next topology event.
TEST(Timeline, TopologiesSwitchAtEachTopologyEvent) {
  Scenario s = Example2();
  ScenarioEvent a = Event(EventKind::kTopology, 1.0, 1e300);
  a.edges = {{2, 1}, {3, 2}, {4, 3}, {5, 4}};
  a.leader_links = {1};
  ScenarioEvent b = Event(EventKind::kTopology, 2.0, 3.0);
  b.edges = {{1, 2}, {3, 2}, {4, 2}, {5, 2}};
  b.leader_links = {2};
  s.events = {a, b};
  const Timeline t(s);
  ASSERT_EQ(t.topologies().size(), 3u);
  EXPECT_EQ(t.TopologyAt(0), 0);
  EXPECT_EQ(t.TopologyAt(1 * kSecond), 1);
  EXPECT_EQ(t.TopologyAt(2 * kSecond), 2);
  EXPECT_EQ(t.TopologyAt(3 * kSecond), 0);  // b ended; a was replaced at 2 s
  EXPECT_TRUE(t.LinkActive(t.LinkIndex(0, 2), 2 * kSecond));
  EXPECT_FALSE(t.LinkActive(t.LinkIndex(0, 2), 1 * kSecond));
  EXPECT_FALSE(t.LinkActive(t.LinkIndex(0, 3), 1 * kSecond));
  EXPECT_TRUE(t.LinkActive(t.LinkIndex(0, 3), 3 * kSecond));
  EXPECT_EQ(t.LinkIndex(0, 4), -1);  // in no topology
}

TEST(Timeline, LinkDownDropsEveryMessageOfItsLinksInItsWindowOnly) {
  Scenario s = Example2();
  ScenarioEvent down = Event(EventKind::kLinkDown, 2.0, 4.0);
  down.links = {{0, 1}, {3, 1}};
  s.events.push_back(down);
  const Recorder r = Simulate(s, 6.0);
  int down_count = 0;
  for (const ChannelDecision& d : r.decisions) {
    const bool listed = (d.sender == 0 || d.sender == 3) && d.receiver == 1;
    const bool in = Within(d.send_utime, 2.0, 4.0);
    EXPECT_EQ(d.status == ChannelDecision::kDroppedLinkDown, listed && in)
        << d.sender << "->" << d.receiver << " at " << d.send_utime;
    down_count += d.status == ChannelDecision::kDroppedLinkDown;
  }
  EXPECT_EQ(down_count, 2 * 100);  // two links, 100 ticks of 20 ms
  EXPECT_STREQ(DropReason(ChannelDecision::kDroppedLinkDown), "link down");
}

TEST(Timeline, ChannelEventReplacesTheModelsOfItsLinksForItsWindow) {
  Scenario s = Example2();
  ScenarioEvent ch = Event(EventKind::kChannel, 1.0, 2.0);
  DelayConfig slow;
  slow.kind = DelayKind::kConstant;
  slow.base_s = 0.5;
  ch.delay = slow;
  LossConfig all;
  all.kind = LossKind::kBernoulli;
  all.probability = 1.0;
  ScenarioEvent lossy = Event(EventKind::kChannel, 3.0, 4.0);
  lossy.loss = all;
  lossy.links = {{1, 2}};
  s.events = {ch, lossy};
  const Recorder r = Simulate(s, 5.0);
  const Recorder base = Simulate(Example2(), 5.0);
  ASSERT_EQ(r.decisions.size(), base.decisions.size());
  for (std::size_t k = 0; k < r.decisions.size(); ++k) {
    const ChannelDecision& d = r.decisions[k];
    if (Within(d.send_utime, 1.0, 2.0)) {
      EXPECT_DOUBLE_EQ(d.delay_s, 0.5);
    } else if (Within(d.send_utime, 3.0, 4.0) && d.sender == 1 && d.receiver == 2) {
      EXPECT_EQ(d.status, ChannelDecision::kDroppedLoss);
    } else if (d.send_utime < 1 * kSecond) {
      // Before any event the run is the run without events.
      EXPECT_EQ(d.delay_s, base.decisions[k].delay_s);
      EXPECT_EQ(d.status, base.decisions[k].status);
    }
  }
  // The lookahead allows for the smallest delay any event gives.
  Scenario fast = Example2();
  ScenarioEvent quick = Event(EventKind::kChannel, 1.0, 2.0);
  DelayConfig none;
  quick.delay = none;
  fast.events = {quick};
  const Timeline t(fast);
  EXPECT_EQ(MinLagTicks(BuildAllLinks(fast), &t, fast.period_us()), 1);
  EXPECT_GT(MinLagTicks(BuildAllLinks(fast), fast.period_us()), 1);
  // So does the lag tick by tick (the event's model, whichever time it is in force).
  const LagBound lags(BuildAllLinks(fast), &t, fast.period_us());
  for (std::int64_t k = 0; k < 300; ++k) ASSERT_EQ(lags.LagAt(k), 1) << k;
  EXPECT_GT(LagBound(BuildAllLinks(fast), nullptr, fast.period_us()).LagAt(0), 1);
}

TEST(Timeline, SilentSendersTransmitNothingAndDeafReceiversGetNothing) {
  Scenario s = Example2();
  ScenarioEvent silent = Event(EventKind::kVehicleSilent, 1.0, 2.0);
  silent.vehicles = {2};
  ScenarioEvent leader = Event(EventKind::kLeaderSilent, 1.5, 2.5);
  ScenarioEvent deaf = Event(EventKind::kVehicleDeaf, 3.0, 4.0);
  deaf.vehicles = {5};
  s.events = {silent, leader, deaf};
  const Recorder r = Simulate(s, 5.0);
  std::map<int, int> by_status;
  for (const ChannelDecision& d : r.decisions) {
    const bool is_silent = (d.sender == 2 && Within(d.send_utime, 1.0, 2.0)) ||
                           (d.sender == 0 && Within(d.send_utime, 1.5, 2.5));
    EXPECT_EQ(d.status == ChannelDecision::kSkippedSilent, is_silent);
    if (d.status == ChannelDecision::kDroppedDeaf) {
      EXPECT_EQ(d.receiver, 5);
      // Deafness holds at the time the message would have been due.
      const Micros due = DeliveryTime(d.send_utime, d.delay_s, s.period_us());
      EXPECT_TRUE(Within(due, 3.0, 4.0)) << due;
    } else if (d.status == ChannelDecision::kDelivered && d.receiver == 5) {
      EXPECT_FALSE(Within(d.deliver_utime, 3.0, 4.0)) << d.deliver_utime;
    }
    ++by_status[d.status];
  }
  EXPECT_GT(by_status[ChannelDecision::kDroppedDeaf], 0);
  EXPECT_TRUE(NotTransmitted(ChannelDecision::kSkippedSilent));
  EXPECT_FALSE(NotTransmitted(ChannelDecision::kDroppedDeaf));
}

TEST(Timeline, LinksOutsideTheTopologyInForceCarryNothing) {
  Scenario s = Example2();
  ScenarioEvent chain = Event(EventKind::kTopology, 2.0, 4.0);
  chain.edges = {{2, 1}, {3, 2}, {4, 3}, {5, 4}};
  chain.leader_links = {1};
  s.events = {chain};
  const Recorder r = Simulate(s, 5.0);
  const Topology base = Topology::Build(s.followers, s.edges, s.leader_links);
  const Topology sw = Topology::Build(s.followers, chain.edges, chain.leader_links);
  auto in = [](const Topology& t, int from, int to) {
    return from == 0 ? t.Pinned(to) : t.A()(to - 1, from - 1) > 0.0;
  };
  int switched = 0;
  for (const ChannelDecision& d : r.decisions) {
    const bool during = Within(d.send_utime, 2.0, 4.0);
    EXPECT_TRUE(in(during ? sw : base, d.sender, d.receiver))
        << d.sender << "->" << d.receiver << " at " << d.send_utime;
    switched += during && d.sender == 4 && d.receiver == 5;
  }
  EXPECT_EQ(switched, 100);
}

// A state sent while the topology in force gives its sender no link goes to nobody: no
// decision, and the modem is not taken, so the first state after it is transmitted.
TEST(Timeline, ASenderWithoutLinksLeavesItsModemFree) {
  Scenario s = Example2();
  s.modem_min_interval_s = 1.0;
  ScenarioEvent star = Event(EventKind::kTopology, 0.45, 1.05);
  star.edges = {};
  star.leader_links = {1, 2, 3, 4, 5};
  s.events = {star};
  const Recorder r = Simulate(s, 2.5);
  std::set<Micros> sent;
  for (const ChannelDecision& d : r.decisions) {
    if (d.sender == 1 && !NotTransmitted(d.status)) sent.insert(d.send_utime);
  }
  EXPECT_EQ(sent, (std::set<Micros>{0, 1060000, 2060000}));
}

// A link that leaves the topology and comes back longer than the timeout later starts
// empty, as at the run's start: the message from before the switch is no timeout, and
// no reason to flag the state stale, on a channel that loses nothing.
TEST(Timeline, ALinkBackInTheTopologyStartsWithNothing) {
  Scenario s = Example2();  // no loss; follower 5 hears 2 and 4
  ScenarioEvent without = Event(EventKind::kTopology, 1.0, 3.0);
  without.edges = {{1, 3}, {2, 1}, {2, 5}, {3, 1}, {4, 5}, {5, 4}};  // 5 no longer hears 2
  without.leader_links = s.leader_links;
  s.events = {without};
  Swarm swarm(s, 6.0);
  std::int64_t stale = 0;
  struct Obs : SwarmObserver {
    std::int64_t* stale;
    void OnState(const StateMsg& m) override {
      *stale += m.vehicle_id == 5 && (m.flags & StateMsg::kFlagStaleNeighbour) != 0;
    }
  } obs;
  obs.stale = &stale;
  swarm.Run(&obs);
  EXPECT_EQ(swarm.followers()[4]->counters().neighbour_timeouts, 0);
  EXPECT_EQ(stale, 0);
}

TEST(Timeline, FollowerUsesOnlyTheNeighboursOfTheTopologyInForce) {
  Scenario s = Example2();
  // Follower 2 hears 1 and 5 in [swarm]; from 1.5 s on it hears only the leader.
  ScenarioEvent star = Event(EventKind::kTopology, 1.5, 1e300);
  star.edges = {};
  star.leader_links = {1, 2, 3, 4, 5};
  s.events = {star};
  Swarm swarm(s, 3.0);
  std::vector<int> active;
  struct Obs : SwarmObserver {
    std::vector<int>* active;
    void OnHealth(Micros, const Follower& f) override {
      if (f.id() == 2) active->push_back(f.counters().active_neighbours);
    }
  } obs;
  obs.active = &active;
  swarm.Run(&obs);
  ASSERT_GE(active.size(), 3u);
  EXPECT_EQ(active[0], 0);  // t = 0: nothing received yet
  EXPECT_EQ(active[1], 2);  // t = 1 s: followers 1 and 5
  EXPECT_EQ(active[2], 1);  // t = 2 s: the leader only
}

TEST(Timeline, ControllerResetZeroesTheForceAndForgetsForItsOutage) {
  Scenario s = Example2();
  ScenarioEvent reset = Event(EventKind::kControllerReset, 2.0, 1e300);
  reset.vehicles = {3};
  reset.outage_s = 1.0;
  s.events = {reset};
  const Recorder r = Simulate(s, 5.0);
  const Recorder base = Simulate(Example2(), 5.0);
  ASSERT_EQ(r.states.size(), base.states.size());
  int reset_ticks = 0;
  for (std::size_t k = 0; k < r.states.size(); ++k) {
    const StateMsg& m = r.states[k];
    const bool in = m.vehicle_id == 3 && Within(m.utime, 2.0, 3.0);
    EXPECT_EQ((m.flags & StateMsg::kFlagControllerReset) != 0, in) << m.vehicle_id << " " << m.utime;
    if (in) {
      EXPECT_EQ(m.tau.norm(), 0.0);
      EXPECT_EQ(m.accel_cmd.norm(), 0.0);
      ++reset_ticks;
    }
    if (m.utime <= 2 * kSecond) {  // the state at 2 s was reached before the reset
      EXPECT_EQ(m.eta, base.states[k].eta);
    }
  }
  EXPECT_EQ(reset_ticks, 50);
  // After the outage the controller acts again.
  bool acts = false;
  for (const StateMsg& m : r.states) acts = acts || (m.vehicle_id == 3 && m.utime > 3 * kSecond && m.tau.norm() > 0);
  EXPECT_TRUE(acts);
}

// The deliveries due at the tick a reset ends are kept (the timeline of a tick applies
// before its deliveries); those due inside the window are not.
TEST(Timeline, DeliveriesDueWhenTheResetEndsAreKept) {
  Scenario s = Example2();
  ScenarioEvent reset = Event(EventKind::kControllerReset, 2.0, 1e300);
  reset.vehicles = {3};
  reset.outage_s = 1.0;
  s.events = {reset};
  Swarm swarm(s, 5.0);
  Recorder r;
  swarm.Run(&r);
  std::int64_t due_inside = 0;
  for (const ChannelDecision& d : r.decisions) {
    if (d.receiver == 3 && d.status == ChannelDecision::kDelivered) {
      due_inside += Within(d.deliver_utime, 2.0, 3.0);
    }
  }
  ASSERT_GT(due_inside, 0);
  EXPECT_EQ(swarm.followers()[2]->counters().msgs_ignored_reset, due_inside);
}

// Two reset windows that touch are two resets: the second forgets what the first window
// recorded (here: the own history the uncertain factor reaches back into).
TEST(Timeline, TouchingResetWindowsResetTwice) {
  Scenario s = Example2();
  ScenarioEvent first = Event(EventKind::kControllerReset, 2.0, 1e300);
  first.vehicles = {3};
  first.outage_s = 1.0;
  ScenarioEvent second = first;
  second.at_s = 3.0;
  const Timeline t([&] {
    Scenario c = s;
    c.events = {first, second};
    return c;
  }());
  EXPECT_EQ(t.ResetStart(3, 2 * kSecond), 2 * kSecond);
  EXPECT_EQ(t.ResetStart(3, 3 * kSecond), 3 * kSecond);
  EXPECT_EQ(t.ResetStart(3, 4 * kSecond), Timeline::kNoReset);
  EXPECT_EQ(t.ResetStart(2, 2 * kSecond), Timeline::kNoReset);
  Scenario two = s, one = s;
  two.events = {first, second};
  ScenarioEvent whole = first;
  whole.outage_s = 2.0;
  one.events = {whole};
  const Recorder a = Simulate(two, 5.0), b = Simulate(one, 5.0);
  ASSERT_EQ(a.states.size(), b.states.size());
  bool differs = false;
  for (std::size_t k = 0; k < a.states.size(); ++k) {
    if (a.states[k].utime <= 3 * kSecond) {
      EXPECT_EQ(a.states[k].eta, b.states[k].eta);
    } else if (a.states[k].vehicle_id == 3) {
      differs = differs || a.states[k].eta != b.states[k].eta;
    }
  }
  EXPECT_TRUE(differs);
}

}  // namespace
}  // namespace shoal
