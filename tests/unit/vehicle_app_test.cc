// The vehicle process's lockstep logic (VehicleApp on runtime's ClockedNode), in process
// (memq://): a tick is stepped only once its clock tick and every delivery it lists are
// here, whatever order they arrive in, and only the listed deliveries reach the control
// law. UDP keeps no order between datagrams,
// so this is what makes a lockstep run equal shoal sim on a loaded machine.
#include "vehicle/vehicle_app.h"

#include <gtest/gtest.h>

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "core/channel_model.h"
#include "core/leader.h"
#include "core/topology.h"
#include "runtime/channels.h"
#include "runtime/messages.h"
#include "scenario/loader.h"

namespace shoal {
namespace {

constexpr int kId = 1;   // pinned to the leader in Example 2
constexpr int kLag = 3;  // ticks between a leader state and its delivery

Scenario Example2() {
  return LoadScenario(std::string(SHOAL_SOURCE_DIR) + "/scenarios/paper_example2.toml");
}

std::vector<unsigned char> Encode(const StateMsg& m) {
  const vehicle_state_t v = ToLcm(m);
  std::vector<unsigned char> b(static_cast<std::size_t>(v.getEncodedSize()));
  v.encode(b.data(), 0, static_cast<int>(b.size()));
  return b;
}

// Clock tick k listing `deliveries` for vehicle kId, as the emulator lists them.
clock_window_t Tick(const Scenario& s, std::int64_t k, const std::vector<StateMsg>& deliveries) {
  clock_window_t c{};
  c.utime = k * s.period_us();
  c.vehicle_id = kEmulatorId;
  c.seq = static_cast<std::int32_t>(k);
  c.tick = k;
  c.n_ticks = 1;
  c.period_us = s.period_us();
  c.final_tick = 0;
  for (const StateMsg& m : deliveries) {
    const std::vector<unsigned char> b = Encode(m);
    c.delivery_tick.push_back(k);
    c.delivery_receiver.push_back(kId);
    c.delivery_sender.push_back(m.vehicle_id);
    c.delivery_seq.push_back(m.seq);
    c.delivery_digest.push_back(DeliveryDigest(b.data(), static_cast<int>(b.size())));
  }
  c.n_deliveries = static_cast<std::int32_t>(c.delivery_receiver.size());
  return c;
}

struct Rig {
  Scenario s = Example2();
  LcmBus bus{"memq://"};
  VehicleApp node{s, kId, Mode::kLockstep, 0, 10.0, &bus, &bus};
  Follower reference{s, Topology::Build(s.followers, s.edges, s.leader_links), kId};
  Leader leader{s};
  std::vector<StateMsg> sent;  // leader states, by tick

  Rig() { node.Init(); }
  void Pump() {
    while (node.HandleBus(0) > 0) {
    }
  }
  std::int64_t ticks() const { return node.follower().counters().ticks; }
  // Tick k in order: the leader's state of tick k - kLag delivered and listed, then the
  // clock tick; the reference steps alike. `extra` runs before the clock tick.
  void InOrderTick(int k, const std::function<void()>& extra = nullptr) {
    std::vector<StateMsg> list;
    if (k >= kLag) {
      list.push_back(sent[k - kLag]);
      bus.Publish(channels::Rx(kId), ToLcm(sent[k - kLag]));
      reference.Receive(sent[k - kLag]);
    }
    if (extra) extra();
    bus.Publish(channels::Clock(), Tick(s, k, list));
    Pump();
    reference.Tick(k * s.period_us());
  }
};

TEST(VehicleAppLockstep, AppliesTheListedDeliveriesWhateverOrderTheyArriveIn) {
  Rig r;
  const int n = 60;
  for (int k = 0; k < n; ++k) r.sent.push_back(r.leader.Tick(k * r.s.period_us()));
  // The delivery of tick k (the leader's state of tick k - kLag) arrives in three ways by
  // turns: before its clock tick, after it, and early (before the previous tick's clock).
  std::map<int, bool> published;
  auto publish_rx = [&](int k) {
    if (k < kLag || k >= n || published[k]) return;
    published[k] = true;
    r.bus.Publish(channels::Rx(kId), ToLcm(r.sent[k - kLag]));
  };
  for (int k = 0; k < n; ++k) {
    std::vector<StateMsg> list;
    if (k >= kLag) list.push_back(r.sent[k - kLag]);
    if (k % 3 == 0) publish_rx(k);
    if (k % 3 == 1) publish_rx(k + 1);  // held a tick ahead: must not be used at tick k
    r.bus.Publish(channels::Clock(), Tick(r.s, k, list));
    r.Pump();
    if (k >= kLag && !published[k]) {
      EXPECT_EQ(r.ticks(), k) << "tick " << k << " stepped before its delivery arrived";
      publish_rx(k);
      r.Pump();
    }
    ASSERT_EQ(r.ticks(), k + 1) << "tick " << k;
    // The reference: shoal sim's order, delivery first, then the tick.
    if (k >= kLag) r.reference.Receive(r.sent[k - kLag]);
    r.reference.Tick(k * r.s.period_us());
    ASSERT_EQ(r.node.follower().state().eta, r.reference.state().eta) << "tick " << k;
    ASSERT_EQ(r.node.follower().state().nu, r.reference.state().nu) << "tick " << k;
  }
  EXPECT_EQ(r.node.follower().counters().msgs_received, n - kLag);
}

// LCM handlers step nothing: the bus's own dispatch copies a clock message, or holds a
// delivery where it was received; the app's HandleBus applies the copies and steps what is
// complete, outside the handlers.
TEST(VehicleAppLockstep, HandlersStepNothingTheStepHappensAfterDispatch) {
  Rig r;
  r.bus.Publish(channels::Clock(), Tick(r.s, 0, {}));
  ASSERT_EQ(r.bus.Handle(0), 1);  // the handler ran: the message is copied, not applied
  EXPECT_EQ(r.ticks(), 0);
  EXPECT_EQ(r.node.HandleBus(0), 0);  // nothing new on the bus; the copy is applied now
  EXPECT_EQ(r.ticks(), 1);
  // Tick 1 lists a delivery that has not come yet: it waits for it.
  r.sent.push_back(r.leader.Tick(0));
  r.bus.Publish(channels::Clock(), Tick(r.s, 1, {r.sent[0]}));
  r.Pump();
  EXPECT_EQ(r.ticks(), 1);
  r.bus.Publish(channels::Rx(kId), ToLcm(r.sent[0]));
  ASSERT_EQ(r.bus.Handle(0), 1);  // the delivery is held by its handler, nothing stepped
  EXPECT_EQ(r.ticks(), 1);
  EXPECT_EQ(r.node.HandleBus(0), 0);  // the tick it completed is stepped after the dispatch
  EXPECT_EQ(r.ticks(), 2);
  EXPECT_EQ(r.node.follower().counters().msgs_received, 1);
  EXPECT_EQ(r.node.counters().bad_clock, 0);
}

TEST(VehicleAppLockstep, AClockTickArrivingEarlyWaitsForTheTicksBeforeIt) {
  Rig r;
  for (int k = 0; k < 4; ++k) r.sent.push_back(r.leader.Tick(k * r.s.period_us()));
  r.bus.Publish(channels::Clock(), Tick(r.s, 2, {}));
  r.bus.Publish(channels::Clock(), Tick(r.s, 1, {}));
  r.Pump();
  EXPECT_EQ(r.ticks(), 0);
  r.bus.Publish(channels::Clock(), Tick(r.s, 0, {}));
  r.Pump();
  EXPECT_EQ(r.ticks(), 3);
  // A second tick 2, or one in the past, is refused and counted.
  r.bus.Publish(channels::Clock(), Tick(r.s, 2, {}));
  r.bus.Publish(channels::Clock(), Tick(r.s, 3, {}));
  r.bus.Publish(channels::Clock(), Tick(r.s, 3, {}));
  r.Pump();
  EXPECT_EQ(r.ticks(), 4);
  EXPECT_EQ(r.node.counters().bad_clock, 2);
}

TEST(VehicleAppLockstep, AnUnlistedPlausibleMessageNeverReachesTheControlLaw) {
  Rig r;
  const int n = 20;
  for (int k = 0; k < n; ++k) r.sent.push_back(r.leader.Tick(k * r.s.period_us()));
  // A forged leader state: valid, finite, newest seq, far away. No tick lists it.
  StateMsg forged = r.sent[0];
  forged.seq = 1000000;
  forged.utime = 0;
  forged.eta(0) += 500.0;
  r.bus.Publish(channels::Rx(kId), ToLcm(forged));
  for (int k = 0; k < n; ++k) r.InOrderTick(k);
  ASSERT_EQ(r.ticks(), n);
  EXPECT_EQ(r.node.follower().state().eta, r.reference.state().eta);
  EXPECT_EQ(r.node.follower().state().nu, r.reference.state().nu);
}

TEST(VehicleAppLockstep, InvalidDeliveriesAreCountedOnArrival) {
  Rig r;
  StateMsg m = r.leader.Tick(0);
  StateMsg nan = m;
  nan.eta(1) = std::nan("");
  StateMsg unknown = m;
  unknown.vehicle_id = 4;  // not an in-neighbour of follower 1
  r.bus.Publish(channels::Rx(kId), ToLcm(nan));
  r.bus.Publish(channels::Rx(kId), ToLcm(unknown));
  const unsigned char garbage[16] = {1, 2, 3};
  r.bus.PublishRaw(channels::Rx(kId), garbage, sizeof(garbage));
  r.Pump();
  EXPECT_EQ(r.node.follower().counters().msgs_dropped_invalid, 2);
  EXPECT_EQ(r.node.rx_counters().bad_rx, 1);
}

// A delay model that lets messages overtake (uniform jitter): a delivery older than the
// one already applied is listed at its own tick; shoal sim counts it as old there. The
// vehicle must step that tick (not wait for a message it dropped) and count it once.
TEST(VehicleAppLockstep, AnOvertakenDeliveryIsCountedOldAndDoesNotBlockItsTick) {
  Rig r;
  for (int k = 0; k < 8; ++k) r.sent.push_back(r.leader.Tick(k * r.s.period_us()));
  for (int k = 0; k < 7; ++k) {
    std::vector<StateMsg> list;
    if (k == 3) list.push_back(r.sent[1]);  // tick 1's state at tick 3
    if (k == 5) list.push_back(r.sent[0]);  // tick 0's state at tick 5: overtaken
    for (const StateMsg& m : list) {
      r.bus.Publish(channels::Rx(kId), ToLcm(m));
      r.reference.Receive(m);
    }
    r.bus.Publish(channels::Clock(), Tick(r.s, k, list));
    r.Pump();
    r.reference.Tick(k * r.s.period_us());
  }
  EXPECT_EQ(r.ticks(), 7);
  EXPECT_EQ(r.node.follower().counters().msgs_dropped_old, 1);
  EXPECT_EQ(r.node.follower().counters().msgs_dropped_old,
            r.reference.counters().msgs_dropped_old);
  EXPECT_EQ(r.node.follower().state().eta, r.reference.state().eta);
}

// A tick that lists held deliveries out of their arrival order, with one held for a later
// tick between them: both are applied in the listed order and leave the held list, and the
// one between them is still held, and applied, at its own tick.
TEST(VehicleAppLockstep, ListedOutOfArrivalOrderAroundOneHeldForLater) {
  Rig r;
  for (int k = 0; k < 6; ++k) r.sent.push_back(r.leader.Tick(k * r.s.period_us()));
  StateMsg from3 = r.sent[0];  // follower 1 also hears follower 3 (Example 2)
  from3.vehicle_id = 3;
  from3.flags = 0;
  from3.eta(0) -= 6.0;
  from3.eta_dot(1) += 0.25;
  // Held in this order: follower 3's, the leader's of tick 1 (for tick 4), the leader's of
  // tick 0; tick 3 lists the last and the first, in that order.
  for (const StateMsg& m : {from3, r.sent[1], r.sent[0]}) {
    r.bus.Publish(channels::Rx(kId), ToLcm(m));
  }
  for (int k = 0; k < 6; ++k) {
    std::vector<StateMsg> list;
    if (k == 3) list = {r.sent[0], from3};
    if (k == 4) list = {r.sent[1]};
    for (const StateMsg& m : list) r.reference.Receive(m);
    r.bus.Publish(channels::Clock(), Tick(r.s, k, list));
    r.Pump();
    r.reference.Tick(k * r.s.period_us());
    ASSERT_EQ(r.ticks(), k + 1) << "tick " << k;
    ASSERT_EQ(r.node.follower().state().eta, r.reference.state().eta) << "tick " << k;
    ASSERT_EQ(r.node.follower().state().nu, r.reference.state().nu) << "tick " << k;
  }
  EXPECT_EQ(r.node.follower().counters().msgs_received, 3);
  EXPECT_EQ(r.reference.counters().msgs_received, 3);
  EXPECT_EQ(r.node.follower().counters().msgs_dropped_old, 0);
  EXPECT_EQ(r.node.rx_counters().unlisted_rx, 0);
}

// A forged copy of an upcoming delivery (same sender and seq, other content) arriving
// first is not the delivery: the tick's digest tells them apart.
TEST(VehicleAppLockstep, AForgedCopyOfAListedDeliveryIsNotApplied) {
  Rig r;
  for (int k = 0; k < 6; ++k) r.sent.push_back(r.leader.Tick(k * r.s.period_us()));
  StateMsg forged = r.sent[1];
  forged.eta(0) += 500.0;
  r.bus.Publish(channels::Rx(kId), ToLcm(forged));
  for (int k = 0; k < 5; ++k) {
    std::vector<StateMsg> list;
    if (k == 4) {
      list.push_back(r.sent[1]);
      r.bus.Publish(channels::Rx(kId), ToLcm(r.sent[1]));
      r.reference.Receive(r.sent[1]);
    }
    r.bus.Publish(channels::Clock(), Tick(r.s, k, list));
    r.Pump();
    r.reference.Tick(k * r.s.period_us());
  }
  ASSERT_EQ(r.ticks(), 5);
  EXPECT_EQ(r.node.follower().state().eta, r.reference.state().eta);
  EXPECT_EQ(r.node.follower().state().nu, r.reference.state().nu);
}

// A replay (an old state nobody lists) is counted as old once no tick can list it any
// more; an unlisted one that is not old as invalid (unlisted). Neither is applied.
TEST(VehicleAppLockstep, UnlistedMessagesAreCountedWhenNoTickCanListThemAnyMore) {
  Rig r;
  const int n = 40;  // 0.8 s: past the largest delay (0.15 s) plus two periods
  for (int k = 0; k < n; ++k) r.sent.push_back(r.leader.Tick(k * r.s.period_us()));
  // A state of follower 3 (an in-neighbour of 1 from which this test delivers nothing):
  // never old, never listed.
  StateMsg forged = r.sent[5];
  forged.vehicle_id = 3;
  forged.seq = 7;
  r.bus.Publish(channels::Rx(kId), ToLcm(forged));
  for (int k = 0; k < n; ++k) {
    r.InOrderTick(k, [&] {
      if (k == 10) r.bus.Publish(channels::Rx(kId), ToLcm(r.sent[2]));  // a replay
    });
  }
  ASSERT_EQ(r.ticks(), n);
  EXPECT_EQ(r.node.follower().counters().msgs_dropped_old, 1);
  EXPECT_EQ(r.node.rx_counters().unlisted_rx, 1);
  EXPECT_EQ(r.node.follower().state().eta, r.reference.state().eta);
}

// The longest window from tick 0 the channel's lag allows.
std::int64_t WindowFromZero(const Scenario& s) {
  const Timeline timeline(s);
  return LagBound(BuildAllLinks(s), &timeline, s.period_us()).Window(0, 1000);
}

// Clock ticks further ahead than the channel's delivery lag at the ticks between (in
// Example 2 at tick 0, tau = 0.15 s: 8 ticks, where its smallest delay allows 3) cannot
// come from the clock master: refused and counted.
TEST(VehicleAppLockstep, AClockTickTooFarAheadIsRefused) {
  Rig r;
  const std::int64_t ahead = WindowFromZero(r.s);
  ASSERT_EQ(ahead, 8);
  r.bus.Publish(channels::Clock(), Tick(r.s, ahead, {}));
  r.Pump();
  EXPECT_EQ(r.node.counters().bad_clock, 1);
  for (int k = 0; k < ahead; ++k) r.bus.Publish(channels::Clock(), Tick(r.s, k, {}));
  r.bus.Publish(channels::Clock(), Tick(r.s, ahead, {}));
  r.Pump();
  EXPECT_EQ(r.ticks(), ahead + 1);
  EXPECT_EQ(r.node.counters().bad_clock, 1);
}

// The clock master releases a window of ticks in one clock message (as many as the
// channel's delivery lag allows): each tick is stepped with the deliveries listed
// for it, in order, exactly as with one message per tick.
clock_window_t Window(const Scenario& s, std::int64_t first, int n,
                    const std::map<std::int64_t, std::vector<StateMsg>>& deliveries) {
  clock_window_t c = Tick(s, first, {});
  c.n_ticks = n;
  for (const auto& [tick, list] : deliveries) {
    const clock_window_t one = Tick(s, tick, list);
    c.delivery_tick.insert(c.delivery_tick.end(), one.delivery_tick.begin(), one.delivery_tick.end());
    c.delivery_receiver.insert(c.delivery_receiver.end(), one.delivery_receiver.begin(),
                               one.delivery_receiver.end());
    c.delivery_sender.insert(c.delivery_sender.end(), one.delivery_sender.begin(),
                             one.delivery_sender.end());
    c.delivery_seq.insert(c.delivery_seq.end(), one.delivery_seq.begin(), one.delivery_seq.end());
    c.delivery_digest.insert(c.delivery_digest.end(), one.delivery_digest.begin(),
                             one.delivery_digest.end());
  }
  c.n_deliveries = static_cast<std::int32_t>(c.delivery_tick.size());
  return c;
}

TEST(VehicleAppLockstep, AWindowClockStepsEachTickWithItsOwnDeliveries) {
  Rig r;
  const int n = 30;
  for (int k = 0; k < n; ++k) r.sent.push_back(r.leader.Tick(k * r.s.period_us()));
  for (int first = 0; first < n; first += kLag) {
    std::map<std::int64_t, std::vector<StateMsg>> list;
    for (int k = first; k < first + kLag; ++k) {
      if (k >= kLag) list[k] = {r.sent[k - kLag]};
    }
    // The clock first, the deliveries after it (the worst order): nothing may be stepped
    // until the first tick's delivery is here.
    r.bus.Publish(channels::Clock(), Window(r.s, first, kLag, list));
    r.Pump();
    if (first >= kLag) {
      EXPECT_EQ(r.ticks(), first) << "window " << first;
    }
    for (int k = first; k < first + kLag; ++k) {
      if (k >= kLag) r.bus.Publish(channels::Rx(kId), ToLcm(r.sent[k - kLag]));
    }
    r.Pump();
    ASSERT_EQ(r.ticks(), first + kLag) << "window " << first;
    for (int k = first; k < first + kLag; ++k) {
      if (k >= kLag) r.reference.Receive(r.sent[k - kLag]);
      r.reference.Tick(k * r.s.period_us());
    }
    ASSERT_EQ(r.node.follower().state().eta, r.reference.state().eta) << "window " << first;
    ASSERT_EQ(r.node.follower().state().nu, r.reference.state().nu) << "window " << first;
  }
  EXPECT_EQ(r.node.follower().counters().msgs_received, n - kLag);
  EXPECT_EQ(r.node.counters().bad_clock, 0);
}

TEST(VehicleAppLockstep, AMalformedWindowIsRefused) {
  Rig r;
  for (int k = 0; k < 4; ++k) r.sent.push_back(r.leader.Tick(k * r.s.period_us()));
  clock_window_t none = Window(r.s, 0, 1, {});
  none.n_ticks = 0;
  r.bus.Publish(channels::Clock(), none);
  // Past the channel's lag.
  r.bus.Publish(channels::Clock(), Window(r.s, 0, static_cast<int>(WindowFromZero(r.s)) + 1, {}));
  r.bus.Publish(channels::Clock(), Window(r.s, 0, 2, {{2, {r.sent[0]}}}));  // listed outside
  r.Pump();
  EXPECT_EQ(r.node.counters().bad_clock, 3);
  EXPECT_EQ(r.ticks(), 0);
  r.bus.Publish(channels::Clock(), Tick(r.s, 1, {}));
  r.bus.Publish(channels::Clock(), Window(r.s, 0, 2, {}));  // overlaps tick 1, announced
  r.Pump();
  EXPECT_EQ(r.node.counters().bad_clock, 4);
  EXPECT_EQ(r.ticks(), 0);
  r.bus.Publish(channels::Clock(), Window(r.s, 0, 1, {}));
  r.Pump();
  EXPECT_EQ(r.ticks(), 2);
}

// A slow channel (a constant delay of 1 s: 50 ticks of lag) whose windows of 25 ticks
// arrive in pairs out of order, each before its deliveries: the ticks announced ahead are
// held (in a ring indexed by tick, which grows for windows this long) and stepped in
// order with their own deliveries, as shoal sim steps them.
TEST(VehicleAppLockstep, LongWindowsArrivingOutOfOrderStepAsShoalSim) {
  Scenario s = Example2();
  s.delay = DelayConfig(DelayKind::kConstant, 1.0, 0.0, 0.0);
  LcmBus bus{"memq://"};
  VehicleApp node{s, kId, Mode::kLockstep, 0, 10.0, &bus, &bus};
  node.Init();
  Follower reference{s, Topology::Build(s.followers, s.edges, s.leader_links), kId};
  Leader leader{s};
  const Timeline timeline(s);
  const int lag = static_cast<int>(LagBound(BuildAllLinks(s), &timeline, s.period_us()).Window(0, 1000));
  ASSERT_EQ(lag, 50);
  const int w = lag / 2;
  const int n = 8 * w;
  std::vector<StateMsg> sent;
  for (int k = 0; k < n; ++k) sent.push_back(leader.Tick(k * s.period_us()));
  auto window = [&](int first) {
    std::map<std::int64_t, std::vector<StateMsg>> list;
    for (int k = first; k < first + w; ++k) {
      if (k >= lag) list[k] = {sent[k - lag]};
    }
    return Window(s, first, w, list);
  };
  auto pump = [&] {
    while (node.HandleBus(0) > 0) {
    }
  };
  for (int pair = 0; pair < n; pair += 2 * w) {
    bus.Publish(channels::Clock(), window(pair + w));  // the later window first
    bus.Publish(channels::Clock(), window(pair));
    pump();
    // Before the deliveries only the ticks that list none are stepped (the first 50).
    EXPECT_EQ(node.follower().counters().ticks, std::max(pair, std::min(pair + 2 * w, lag)))
        << "windows " << pair;
    for (int k = pair; k < pair + 2 * w; ++k) {
      if (k >= lag) bus.Publish(channels::Rx(kId), ToLcm(sent[k - lag]));
    }
    pump();
    ASSERT_EQ(node.follower().counters().ticks, pair + 2 * w) << "windows " << pair;
    for (int k = pair; k < pair + 2 * w; ++k) {
      if (k >= lag) reference.Receive(sent[k - lag]);
      reference.Tick(k * s.period_us());
    }
    ASSERT_EQ(node.follower().state().eta, reference.state().eta) << "windows " << pair;
    ASSERT_EQ(node.follower().state().nu, reference.state().nu) << "windows " << pair;
  }
  EXPECT_EQ(node.follower().counters().msgs_received, n - lag);
  EXPECT_EQ(node.counters().bad_clock, 0);
}

}  // namespace
}  // namespace shoal

namespace shoal {
namespace {

// shoal run --stagger: the leader keeps the period's start, the followers' loops are
// spread evenly over its first half, each at a phase of its own; with a channel whose
// smallest delay is not above one period (a state could be due before it went out), no
// process gets a phase.
TEST(ClockedNodeStagger, FollowersSpreadOverHalfAPeriodOnlyWhenTheDelayLeavesRoom) {
  Scenario s = Example2();
  ASSERT_EQ(s.period_us(), 20000);
  EXPECT_EQ(ClockedNode::StaggerPhaseUs(s, 0), 0);
  std::vector<Micros> phases;
  for (int id = 1; id <= s.followers; ++id) phases.push_back(ClockedNode::StaggerPhaseUs(s, id));
  ASSERT_EQ(phases.size(), 5u);
  EXPECT_EQ(phases.front(), 10000 / 6);
  EXPECT_EQ(phases.back(), 5 * 10000 / 6);
  for (std::size_t k = 1; k < phases.size(); ++k) {
    EXPECT_GE(phases[k] - phases[k - 1], 10000 / 6) << k;
    EXPECT_LE(phases[k] - phases[k - 1], 10000 / 6 + 1) << k;
  }
  EXPECT_LT(phases.back(), s.period_us() / 2);

  s.delay = DelayConfig(DelayKind::kConstant, 0.015, 0.0, 0.0);  // less than a period
  for (int id = 0; id <= s.followers; ++id) EXPECT_EQ(ClockedNode::StaggerPhaseUs(s, id), 0) << id;
}

}  // namespace
}  // namespace shoal

namespace shoal {
namespace {

// A bus whose messages reach the host at times the test sets (as a receiver recording the
// kernel's receive times gives them), delivered in publication order.
class ArrivalBus : public Bus {
 public:
  bool PublishRaw(const std::string& channel, const void* data, int size) override {
    const auto* p = static_cast<const unsigned char*>(data);
    queue_.push_back({channel, std::vector<unsigned char>(p, p + size), next_arrival_ns});
    return true;
  }
  void Subscribe(const std::string& channel, Handler handler) override {
    subs_.emplace_back(channel, std::move(handler));
  }
  int Handle(int /*timeout_ms*/) override {
    const int n = static_cast<int>(queue_.size());
    for (const Queued& q : queue_) {
      current_ = q.arrival_ns;
      for (auto& [channel, handler] : subs_) {
        if (channel == q.channel) handler(q.channel, q.bytes.data(), static_cast<int>(q.bytes.size()));
      }
    }
    current_ = -1;
    queue_.clear();
    return n;
  }
  bool RecordArrivals() override { return recording = true; }
  std::int64_t ArrivalNs() const override { return recording ? current_ : -1; }

  std::int64_t next_arrival_ns = -1;
  bool recording = false;

 private:
  struct Queued {
    std::string channel;
    std::vector<unsigned char> bytes;
    std::int64_t arrival_ns;
  };
  std::vector<Queued> queue_;
  std::vector<std::pair<std::string, Handler>> subs_;
  std::int64_t current_ = -1;
};

// A real-time tick reads what reached the host by the tick's time, however late in its
// period the loop runs (a stagger phase, a late wake-up): a message that came after it
// waits, in order, for the next tick, as it would for a loop that ran at the tick's
// instant. A message whose arrival is not known is read at once.
TEST(VehicleAppRealtime, ATickReadsOnlyWhatArrivedByItsTime) {
  const Scenario s = Example2();
  ArrivalBus bus;
  VehicleApp node{s, kId, Mode::kRealtime, 0, 10.0, &bus, &bus};
  node.Init();
  ASSERT_TRUE(bus.recording) << "a real-time process asks its bus for arrival times";
  Leader leader{s};
  const StateMsg a = leader.Tick(0), b = leader.Tick(s.period_us()), c = leader.Tick(2 * s.period_us());
  const std::int64_t tick_ns = 1000000000;  // the time of the tick about to read
  bus.next_arrival_ns = tick_ns - 1;
  bus.Publish(channels::Rx(kId), ToLcm(a));
  bus.next_arrival_ns = tick_ns + 1;
  bus.Publish(channels::Rx(kId), ToLcm(b));
  bus.next_arrival_ns = tick_ns + 2;
  bus.Publish(channels::Rx(kId), ToLcm(c));
  node.HandleBus(0, tick_ns);
  EXPECT_EQ(node.follower().counters().msgs_received, 1);
  EXPECT_EQ(node.counters().held_to_next_tick, 2);
  node.HandleBus(0, tick_ns + 1);  // the next "tick": one more has arrived by its time
  EXPECT_EQ(node.follower().counters().msgs_received, 2);
  EXPECT_EQ(node.follower().counters().msgs_dropped_old, 0) << "kept in arrival order";
  bus.next_arrival_ns = -1;  // not known: read at once
  bus.Publish(channels::Rx(kId), ToLcm(leader.Tick(3 * s.period_us())));
  node.HandleBus(0, tick_ns + 2);
  EXPECT_EQ(node.follower().counters().msgs_received, 4);
  EXPECT_EQ(node.counters().held_to_next_tick, 3);
  EXPECT_EQ(node.follower().counters().msgs_dropped_old, 0);
}

}  // namespace
}  // namespace shoal
