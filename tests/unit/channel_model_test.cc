// Property tests of core/channel_model: delivery-time arithmetic on the tick grid, the
// delay and loss models, and Channel<int>: links from a scenario with per-link
// overrides, one decision per outgoing link, delivery order, loss statistics, seeded
// determinism and per-link independence of the random streams.
#include "core/channel_model.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <tuple>
#include <utility>
#include <vector>

#include "core/rng.h"

namespace shoal {
namespace {

constexpr Micros kPeriod = 20000;  // 50 Hz

DelayConfig Constant(double s) {
  DelayConfig c;
  c.kind = DelayKind::kConstant;
  c.base_s = s;
  return c;
}
DelayConfig Uniform(double base, double amp) {
  DelayConfig c;
  c.kind = DelayKind::kUniform;
  c.base_s = base;
  c.amplitude_s = amp;
  return c;
}
DelayConfig Sinusoid(double base, double amp, double omega) {
  DelayConfig c;
  c.kind = DelayKind::kSinusoid;
  c.base_s = base;
  c.amplitude_s = amp;
  c.omega_rad_s = omega;
  return c;
}
LossConfig Bernoulli(double p) {
  LossConfig c;
  c.kind = LossKind::kBernoulli;
  c.probability = p;
  return c;
}

/// The paper's swarm (Fig. 1): 5 followers, leader links 1, 3, 5.
Scenario PaperScenario(std::uint64_t seed) {
  Scenario s;
  s.seed = seed;
  s.followers = 5;
  s.edges = {{1, 3}, {2, 1}, {2, 5}, {3, 1}, {4, 5}, {5, 2}, {5, 4}};
  s.leader_links = {1, 3, 5};
  return s;
}

Topology TopologyOf(const Scenario& s) {
  return Topology::Build(s.followers, s.edges, s.leader_links);
}

const Link* FindLink(const std::vector<Link>& links, int from, int to) {
  for (const Link& l : links) {
    if (l.from == from && l.to == to) return &l;
  }
  return nullptr;
}

/// The comparable content of a decision.
using DecisionKey = std::tuple<int, int, std::int32_t, Micros, double, Micros, int>;
DecisionKey Key(const ChannelDecision& d) {
  return {d.sender, d.receiver, d.msg_seq, d.send_utime, d.delay_s, d.deliver_utime,
          static_cast<int>(d.status)};
}

// ---------------------------------------------------------------------------------------
// DeliveryTime

TEST(ChannelDeliveryTimeTest, TickGrid) {
  const Micros tick5 = 5 * kPeriod;
  // Zero delay: usable from the next tick, never the send tick itself.
  EXPECT_EQ(DeliveryTime(tick5, 0.0, kPeriod), 6 * kPeriod);
  EXPECT_EQ(DeliveryTime(tick5 + 1, 0.0, kPeriod), 6 * kPeriod);
  EXPECT_EQ(DeliveryTime(6 * kPeriod - 1, 0.0, kPeriod), 6 * kPeriod);
  // A delay that lands exactly on a tick is delivered at that tick.
  EXPECT_EQ(DeliveryTime(tick5, 0.1, kPeriod), 10 * kPeriod);
  EXPECT_EQ(DeliveryTime(tick5, 0.02, kPeriod), 6 * kPeriod);
  // One microsecond later goes to the following tick.
  EXPECT_EQ(DeliveryTime(tick5, 0.100001, kPeriod), 11 * kPeriod);
  EXPECT_EQ(DeliveryTime(tick5, 0.0999999, kPeriod), 10 * kPeriod);
  // Delay shorter than a period but sent mid-period.
  EXPECT_EQ(DeliveryTime(tick5 + 15000, 0.004, kPeriod), 6 * kPeriod);
  EXPECT_EQ(DeliveryTime(tick5 + 15000, 0.006, kPeriod), 7 * kPeriod);
  // Real time (period 0): send + delay exactly.
  EXPECT_EQ(DeliveryTime(123457, 0.034567, 0), 123457 + 34567);
  EXPECT_EQ(DeliveryTime(123457, 0.0, 0), 123457);
  EXPECT_EQ(DeliveryTime(1700000000000000, 2.5, 0), 1700000000000000 + 2500000);
}

TEST(ChannelDeliveryTimeTest, FirstTickAtOrAfterDueAndAfterSendTick) {
  Rng rng(17);
  for (int k = 0; k < 100000; ++k) {
    const Micros send = static_cast<Micros>(rng.Uniform() * 1e10);
    // Whole-microsecond delays, so send + delay is exact.
    const Micros delay_us = static_cast<Micros>(rng.Uniform() * 300000);
    const double delay_s = static_cast<double>(delay_us) / 1e6;
    const Micros due = send + delay_us;
    const Micros got = DeliveryTime(send, delay_s, kPeriod);
    ASSERT_EQ(got % kPeriod, 0) << send << " " << delay_s;
    ASSERT_GE(got, due);
    ASSERT_GT(got / kPeriod, send / kPeriod);
    // Smallest such tick.
    const Micros prev = got - kPeriod;
    ASSERT_TRUE(prev < due || prev / kPeriod <= send / kPeriod) << send << " " << delay_s;
    ASSERT_EQ(DeliveryTime(send, delay_s, 0), due);
  }
}

// ---------------------------------------------------------------------------------------
// Delay and loss models

// The lockstep clock master's lookahead: no delivery ever comes sooner than
// MinDeliveryLagTicks after its send tick, and the bound is tight for constant delays.
TEST(ChannelLookaheadTest, MinimumLagBoundsEveryDeliveryAndIsTight) {
  const Micros period = 20000;
  EXPECT_EQ(MinDeliveryLagTicks(0.0, period), 1);
  EXPECT_EQ(MinDeliveryLagTicks(0.019, period), 1);
  EXPECT_EQ(MinDeliveryLagTicks(0.02, period), 1);   // exactly one period: next tick
  EXPECT_EQ(MinDeliveryLagTicks(0.0201, period), 2);
  EXPECT_EQ(MinDeliveryLagTicks(0.05, period), 3);   // paper Example 2: 0.1 - 0.05
  DelayConfig sine{DelayKind::kSinusoid, 0.1, 0.05, 1.0};
  DelayConfig uni{DelayKind::kUniform, 0.08, 0.03, 0.0};
  EXPECT_DOUBLE_EQ(MinDelaySeconds(sine), 0.05);
  EXPECT_DOUBLE_EQ(MinDelaySeconds(uni), 0.05);
  EXPECT_DOUBLE_EQ(MinDelaySeconds(DelayConfig{DelayKind::kUniform, 0.01, 0.03, 0.0}), 0.0);
  Rng rng(7, 1, 2);
  for (const DelayConfig& c : {sine, uni, DelayConfig{DelayKind::kConstant, 0.06, 0, 0},
                               DelayConfig{DelayKind::kConstant, 0.0601, 0, 0}}) {
    const std::int64_t lag = MinDeliveryLagTicks(MinDelaySeconds(c), period);
    std::int64_t smallest = 1 << 30;
    for (std::int64_t k = 0; k < 20000; ++k) {
      const Micros send = k * period;
      const Micros at = DeliveryTime(send, DelaySeconds(c, ToSeconds(send), &rng), period);
      smallest = std::min(smallest, at / period - k);
    }
    EXPECT_GE(smallest, lag) << "model kind " << static_cast<int>(c.kind);
    if (c.kind == DelayKind::kConstant) {
      EXPECT_EQ(smallest, lag) << c.base_s;
    }
  }
  // A channel's lookahead is its tightest link (a per-link override of 10 ms -> 1 tick).
  Scenario s = PaperScenario(1);
  s.delay = sine;
  EXPECT_EQ(Channel<int>(BuildLinks(s, Topology::Build(s.followers, s.edges, s.leader_links)),
                         period).MinLagTicks(), 3);
  LinkOverride o;
  o.from = 0;
  o.to = 1;
  o.delay = DelayConfig{DelayKind::kConstant, 0.01, 0, 0};
  s.links.push_back(o);
  EXPECT_EQ(Channel<int>(BuildLinks(s, Topology::Build(s.followers, s.edges, s.leader_links)),
                         period).MinLagTicks(), 1);
}

TEST(ChannelDelaySecondsTest, DeterministicModels) {
  DelayConfig none;
  EXPECT_EQ(DelaySeconds(none, 12.3, nullptr), 0.0);
  EXPECT_EQ(DelaySeconds(Constant(0.3), 0.0, nullptr), 0.3);
  EXPECT_EQ(DelaySeconds(Constant(0.3), 1e5, nullptr), 0.3);
  // Paper Example 2: tau(t) = 0.1 + 0.05 cos t.
  const DelayConfig s = Sinusoid(0.1, 0.05, 1.0);
  EXPECT_NEAR(DelaySeconds(s, 0.0, nullptr), 0.15, 1e-15);
  EXPECT_NEAR(DelaySeconds(s, 3.14159265358979323846 / 2, nullptr), 0.1, 1e-15);
  EXPECT_NEAR(DelaySeconds(s, 3.14159265358979323846, nullptr), 0.05, 1e-15);
  EXPECT_NEAR(DelaySeconds(s, 1.0, nullptr), 0.127015115293407, 1e-15);  // 0.1 + 0.05 cos 1
  EXPECT_NEAR(DelaySeconds(s, 2.0, nullptr), 0.07919265817264289, 1e-15);  // 0.1 + 0.05 cos 2
  EXPECT_NEAR(DelaySeconds(s, 10.0, nullptr), 0.05804642354617738, 1e-15); // 0.1 + 0.05 cos 10
  // Upper bounds h.
  EXPECT_EQ(MaxDelaySeconds(none), 0.0);
  EXPECT_EQ(MaxDelaySeconds(Constant(0.3)), 0.3);
  EXPECT_NEAR(MaxDelaySeconds(s), 0.15, 1e-15);
  EXPECT_NEAR(MaxDelaySeconds(Uniform(0.2, 0.05)), 0.25, 1e-15);
  EXPECT_EQ(NominalDelaySeconds(Uniform(0.2, 0.05), 3.0), 0.2);
  EXPECT_NEAR(NominalDelaySeconds(s, 2.0), DelaySeconds(s, 2.0, nullptr), 0.0);
}

TEST(ChannelDelaySecondsTest, CosOfLastIsStdCosForAnySequenceOfArguments) {
  // Repeats, alternations, a NaN between two equal arguments, -0 after +0, huge arguments:
  // the remembered value is never returned for another argument.
  const double nan = std::nan("");
  const std::vector<double> xs = {0.0,  0.0,   1.0,    1.0, 2.0, 1.0,  1e6,  1e6,  nan,
                                  1e6,  nan,   nan,    -0.0, 0.0, 3e300, 3e300, -1e-320,
                                  4.25, 4.25,  4.25};
  for (std::size_t k = 0; k < xs.size(); ++k) {
    const double want = std::cos(xs[k]);
    const double got = CosOfLast(xs[k]);
    if (std::isnan(want)) {
      EXPECT_TRUE(std::isnan(got)) << k;
    } else {
      EXPECT_EQ(got, want) << k << ": cos(" << xs[k] << ")";
    }
  }
  // The sinusoidal delay at a tick's time, asked for twice, is the same as computed afresh.
  const DelayConfig s = Sinusoid(0.1, 0.05, 1.0);
  for (double t = 0.0; t < 1000.0; t += 0.37) {
    const double first = DelaySeconds(s, t, nullptr);
    EXPECT_EQ(DelaySeconds(s, t, nullptr), first);
    EXPECT_EQ(first, std::max(0.1 + 0.05 * std::cos(1.0 * t), 0.0)) << t;
  }
}

TEST(ChannelDelaySecondsTest, UniformWithinBandWithMeanAtBase) {
  const DelayConfig c = Uniform(0.2, 0.05);
  Rng rng(3);
  double sum = 0.0, lo = 1e9, hi = -1e9;
  const int n = 100000;
  for (int k = 0; k < n; ++k) {
    const double d = DelaySeconds(c, 0.01 * k, &rng);
    ASSERT_GE(d, 0.15);
    ASSERT_LE(d, 0.25);
    sum += d;
    lo = std::min(lo, d);
    hi = std::max(hi, d);
  }
  // Standard error of the mean is 0.05 / sqrt(3 n) = 9e-5.
  EXPECT_NEAR(sum / n, 0.2, 5e-4);
  // The whole band is used.
  EXPECT_LT(lo, 0.1501);
  EXPECT_GT(hi, 0.2499);
}

TEST(ChannelDelaySecondsTest, NeverNegative) {
  Rng rng(4);
  const DelayConfig sin_big = Sinusoid(0.05, 0.1, 2.0);  // would dip to -0.05
  const DelayConfig uni_big = Uniform(0.01, 0.05);
  const DelayConfig negative = Constant(-0.2);
  int clamped = 0;
  for (int k = 0; k < 10000; ++k) {
    const double t = 0.013 * k;
    const double a = DelaySeconds(sin_big, t, &rng);
    const double b = DelaySeconds(uni_big, t, &rng);
    ASSERT_GE(a, 0.0);
    ASSERT_GE(b, 0.0);
    if (a == 0.0) ++clamped;
    if (a > 0.0) {
      ASSERT_NEAR(a, 0.05 + 0.1 * std::cos(2.0 * t), 1e-15);
    }
  }
  EXPECT_GT(clamped, 1000);  // the clamping really happened
  EXPECT_EQ(DelaySeconds(negative, 0.0, &rng), 0.0);
}

TEST(ChannelDroppedTest, NoneNeverDropsAndProbabilityOneAlwaysDrops) {
  Rng rng(5);
  LossConfig none;
  for (int k = 0; k < 1000; ++k) {
    ASSERT_FALSE(Dropped(none, &rng));
    ASSERT_TRUE(Dropped(Bernoulli(1.0), &rng));
    ASSERT_FALSE(Dropped(Bernoulli(0.0), &rng));
  }
}

// ---------------------------------------------------------------------------------------
// BuildLinks

TEST(ChannelBuildLinksTest, DefaultsAndOverridesOnTheRightLinkOnly) {
  Scenario s = PaperScenario(7);
  s.delay = Constant(0.1);
  s.loss = Bernoulli(0.05);
  LinkOverride slow;
  slow.from = 2;
  slow.to = 5;
  slow.delay = Sinusoid(0.2, 0.1, 0.5);
  LinkOverride lossy;
  lossy.from = 0;
  lossy.to = 3;
  lossy.loss = Bernoulli(0.5);
  LinkOverride reverse_of_slow;  // (5, 2) exists too; must not be confused with (2, 5)
  reverse_of_slow.from = 5;
  reverse_of_slow.to = 2;
  reverse_of_slow.delay = Constant(0.7);
  s.links = {slow, lossy, reverse_of_slow};

  const Topology topo = TopologyOf(s);
  const std::vector<Link> links = BuildLinks(s, topo);
  ASSERT_EQ(links.size(), 10u);
  const auto expected_pairs = topo.Links();
  for (std::size_t k = 0; k < links.size(); ++k) {
    EXPECT_EQ(links[k].from, expected_pairs[k].first) << k;
    EXPECT_EQ(links[k].to, expected_pairs[k].second) << k;
  }
  for (const Link& l : links) {
    SCOPED_TRACE(::testing::Message() << "link " << l.from << "->" << l.to);
    if (l.from == 2 && l.to == 5) {
      EXPECT_TRUE(SameDelay(l.delay, *slow.delay));
    } else if (l.from == 5 && l.to == 2) {
      EXPECT_TRUE(SameDelay(l.delay, Constant(0.7)));
    } else {
      EXPECT_TRUE(SameDelay(l.delay, s.delay));
    }
    // A delay-only override keeps the default loss and vice versa.
    EXPECT_EQ(l.loss.kind, LossKind::kBernoulli);
    EXPECT_EQ(l.loss.probability, (l.from == 0 && l.to == 3) ? 0.5 : 0.05);
  }
}

// ---------------------------------------------------------------------------------------
// Channel<int>

TEST(ChannelTest, OneDecisionPerOutgoingLink) {
  Scenario s = PaperScenario(11);
  s.delay = Uniform(0.1, 0.05);
  s.loss = Bernoulli(0.3);
  const Topology topo = TopologyOf(s);
  Channel<int> ch(BuildLinks(s, topo), kPeriod);
  std::map<int, std::vector<int>> outgoing;  // sender -> receivers
  for (const auto& [from, to] : topo.Links()) outgoing[from].push_back(to);
  std::vector<ChannelDecision> decisions;
  std::int32_t seq = 0;
  for (int round = 0; round < 50; ++round) {
    for (int sender = 0; sender <= 6; ++sender) {  // 6 is not in the swarm
      decisions.clear();
      const Micros t = round * kPeriod;
      ch.Submit(sender, seq, t, sender * 1000 + round, &decisions);
      const std::vector<int>& to = outgoing[sender];
      ASSERT_EQ(decisions.size(), to.size()) << "sender " << sender;
      for (std::size_t k = 0; k < to.size(); ++k) {
        EXPECT_EQ(decisions[k].sender, sender);
        EXPECT_EQ(decisions[k].receiver, to[k]);
        EXPECT_EQ(decisions[k].msg_seq, seq);
        EXPECT_EQ(decisions[k].send_utime, t);
        if (decisions[k].status == ChannelDecision::kDelivered) {
          EXPECT_EQ(decisions[k].deliver_utime, DeliveryTime(t, decisions[k].delay_s, kPeriod));
        }
      }
      ++seq;
    }
  }
  // The paper's senders: leader -> {1, 3, 5}; 1 -> {2, 3}; 2 -> {5}; 3 -> {1}; 4 -> {5};
  // 5 -> {2, 4}.
  EXPECT_EQ(outgoing[0], (std::vector<int>{1, 3, 5}));
  EXPECT_EQ(outgoing[1].size() + outgoing[2].size() + outgoing[3].size() + outgoing[4].size() +
                outgoing[5].size(),
            7u);
}

/// Submits 600 messages (all senders in turn, 10 ms apart per round) without delivering,
/// then delivers in 7 ms steps: the order must be (due time, submission order) and
/// nothing may arrive early or a step late.
void CheckDeliveryOrder(Micros period) {
  // Uniform delays give many distinct due times; two constant-delay links into follower 1
  // give ties that only submission order can break.
  Scenario s = PaperScenario(21);
  s.delay = Uniform(0.05, 0.04);
  LinkOverride c1;
  c1.from = 0;
  c1.to = 1;
  c1.delay = Constant(0.03);
  LinkOverride c2;
  c2.from = 3;
  c2.to = 1;
  c2.delay = Constant(0.03);
  s.links = {c1, c2};
  Channel<int> ch(BuildLinks(s, TopologyOf(s)), period);

  struct Expect {
    Micros due;
    int receiver;
    int payload;
  };
  std::vector<Expect> expected;  // in submission order
  std::vector<ChannelDecision> decisions;
  int payload = 0;
  for (int k = 0; k < 600; ++k) {
    const int sender = k % 6;
    decisions.clear();
    ++payload;
    const Micros t = 10000 * (k / 6);
    ch.Submit(sender, k, t, payload, &decisions);
    for (const ChannelDecision& d : decisions) {
      ASSERT_EQ(d.status, ChannelDecision::kDelivered);
      ASSERT_EQ(d.deliver_utime, DeliveryTime(t, d.delay_s, period));
      expected.push_back({d.deliver_utime, d.receiver, payload});
    }
  }
  ASSERT_EQ(ch.pending(), expected.size());
  std::stable_sort(expected.begin(), expected.end(),
                   [](const Expect& a, const Expect& b) { return a.due < b.due; });
  EXPECT_EQ(ch.NextDue(), expected.front().due);
  // Ties actually occur (so the order among equal due times is tested).
  int ties = 0;
  for (std::size_t k = 1; k < expected.size(); ++k) ties += expected[k].due == expected[k - 1].due;
  ASSERT_GT(ties, 50);

  std::vector<Expect> got;
  for (Micros now = 0; now <= 2000000; now += 7000) {
    ch.DeliverDue(now, [&](int receiver, const int& p) { got.push_back({now, receiver, p}); });
    ASSERT_EQ(ch.pending(), expected.size() - got.size());
    if (got.size() < expected.size()) {
      ASSERT_EQ(ch.NextDue(), expected[got.size()].due) << "now " << now;
    }
  }
  ASSERT_EQ(got.size(), expected.size());
  for (std::size_t k = 0; k < got.size(); ++k) {
    ASSERT_EQ(got[k].receiver, expected[k].receiver) << k;
    ASSERT_EQ(got[k].payload, expected[k].payload) << k;
    ASSERT_GE(got[k].due, expected[k].due) << k;        // not early
    ASSERT_LT(got[k].due - 7000, expected[k].due) << k;  // and not a step late
  }
  EXPECT_EQ(ch.pending(), 0u);
  EXPECT_EQ(ch.NextDue(), -1);
}

TEST(ChannelTest, DeliversInDueTimeThenSubmissionOrderInRealTime) { CheckDeliveryOrder(0); }

TEST(ChannelTest, DeliversInDueTimeThenSubmissionOrderOnTheTickGrid) {
  CheckDeliveryOrder(kPeriod);
}

TEST(ChannelTest, LockstepDeliversEveryMessageAtItsDeliveryTick) {
  // The way shoal sim drives the channel: at each tick deliver what is due, then submit
  // what was published at that tick. Every delivery happens exactly at the tick its
  // decision announced, in submission order within the tick.
  Scenario s = PaperScenario(33);
  s.delay = Sinusoid(0.1, 0.05, 1.0);
  s.loss = Bernoulli(0.1);
  LinkOverride slow;
  slow.from = 2;
  slow.to = 5;
  slow.delay = Uniform(0.4, 0.1);
  s.links = {slow};
  Channel<int> ch(BuildLinks(s, TopologyOf(s)), kPeriod);
  std::map<int, std::pair<Micros, int>> due_of;  // payload -> (deliver_utime, receiver)
  std::vector<ChannelDecision> decisions;
  int payload = 0, delivered = 0;
  std::int64_t last_order = -1;
  std::map<int, std::int64_t> order_of;  // payload*8 + receiver -> submission index
  std::int64_t index = 0;
  for (int tick = 0; tick < 3000; ++tick) {
    const Micros now = tick * kPeriod;
    Micros last_due = -1;
    ch.DeliverDue(now, [&](int receiver, const int& p) {
      const int key = p * 8 + receiver;
      ASSERT_EQ(due_of.count(key), 1u) << "unknown delivery";
      EXPECT_EQ(due_of[key].first, now);
      EXPECT_EQ(due_of[key].second, receiver);
      // Within the tick, submission order.
      if (last_due == now) {
        EXPECT_GT(order_of[key], last_order);
      }
      last_due = now;
      last_order = order_of[key];
      due_of.erase(key);
      ++delivered;
    });
    for (int sender = 0; sender <= 5; ++sender) {
      decisions.clear();
      ++payload;
      ch.Submit(sender, payload, now, payload, &decisions);
      for (const ChannelDecision& d : decisions) {
        if (d.status != ChannelDecision::kDelivered) continue;
        due_of[payload * 8 + d.receiver] = {d.deliver_utime, d.receiver};
        order_of[payload * 8 + d.receiver] = index++;
      }
    }
  }
  // Everything not yet due is still pending, and everything due was delivered.
  for (const auto& [key, v] : due_of) EXPECT_GT(v.first, 2999 * kPeriod) << key;
  EXPECT_EQ(ch.pending(), due_of.size());
  EXPECT_GT(delivered, 3000 * 10 * 8 / 10);  // 10 links, 10% loss
}

TEST(ChannelTest, BernoulliLossRate) {
  Scenario s;
  s.seed = 123;
  s.followers = 1;
  s.leader_links = {1};
  s.delay = Constant(0.1);
  s.loss = Bernoulli(0.2);
  Channel<int> ch(BuildLinks(s, TopologyOf(s)), kPeriod);
  std::vector<ChannelDecision> decisions;
  int dropped = 0;
  const int n = 100000;
  std::size_t delivered = 0;
  for (int k = 0; k < n; ++k) {
    decisions.clear();
    const Micros t = static_cast<Micros>(k) * kPeriod;
    ch.Submit(0, k, t, k, &decisions);
    ASSERT_EQ(decisions.size(), 1u);
    if (decisions[0].status == ChannelDecision::kDroppedLoss) {
      ++dropped;
      EXPECT_EQ(decisions[0].deliver_utime, 0);
    }
    ch.DeliverDue(t, [&](int, const int&) { ++delivered; });
  }
  // Standard deviation of the rate is sqrt(0.16 / n) = 0.0013.
  EXPECT_NEAR(static_cast<double>(dropped) / n, 0.2, 0.01);
  EXPECT_EQ(delivered + ch.pending() + dropped, static_cast<std::size_t>(n));
}

/// Decisions for a fixed traffic pattern on the paper's swarm with random delay and loss.
std::vector<DecisionKey> RunTraffic(std::uint64_t seed, const std::vector<int>& senders,
                                    int rounds) {
  Scenario s = PaperScenario(seed);
  s.delay = Uniform(0.1, 0.05);
  s.loss = Bernoulli(0.2);
  Channel<int> ch(BuildLinks(s, TopologyOf(s)), kPeriod);
  std::vector<ChannelDecision> decisions;
  std::int32_t seq = 0;
  for (int r = 0; r < rounds; ++r) {
    for (int sender : senders) ch.Submit(sender, seq++, r * kPeriod, r, &decisions);
    ch.DeliverDue(r * kPeriod, [](int, const int&) {});
  }
  std::vector<DecisionKey> keys;
  for (const ChannelDecision& d : decisions) keys.push_back(Key(d));
  return keys;
}

TEST(ChannelTest, SameSeedSameDecisionsOtherSeedOtherDecisions) {
  const std::vector<int> all = {0, 1, 2, 3, 4, 5};
  const auto a = RunTraffic(42, all, 500);
  const auto b = RunTraffic(42, all, 500);
  const auto c = RunTraffic(43, all, 500);
  ASSERT_EQ(a.size(), 500u * 10u);
  EXPECT_EQ(a, b);
  ASSERT_EQ(c.size(), a.size());
  int differ = 0;
  for (std::size_t k = 0; k < a.size(); ++k) differ += a[k] != c[k];
  // Nearly every decision differs (the delay is continuous).
  EXPECT_GT(differ, static_cast<int>(a.size()) * 9 / 10);
}

TEST(ChannelTest, LinkDecisionsDoNotDependOnOtherTraffic) {
  // Only the leader talks in one run; everyone talks in the other. The leader's links
  // make the same decisions in both, and so do the follower links that carry traffic.
  const auto leader_only = RunTraffic(5, {0}, 400);
  const auto everyone = RunTraffic(5, {5, 3, 0, 1, 4, 2}, 400);
  const auto followers_only = RunTraffic(5, {1, 2, 3, 4, 5}, 400);
  auto on_link = [](const std::vector<DecisionKey>& keys, int from, int to) {
    std::vector<std::tuple<double, Micros, int>> out;
    for (const DecisionKey& k : keys) {
      if (std::get<0>(k) == from && std::get<1>(k) == to)
        out.emplace_back(std::get<4>(k), std::get<5>(k), std::get<6>(k));
    }
    return out;
  };
  for (const auto& [from, to] : TopologyOf(PaperScenario(5)).Links()) {
    SCOPED_TRACE(::testing::Message() << "link " << from << "->" << to);
    const auto& alone = from == 0 ? leader_only : followers_only;
    const auto x = on_link(alone, from, to);
    const auto y = on_link(everyone, from, to);
    ASSERT_EQ(x.size(), 400u);
    EXPECT_EQ(x, y);
  }
  // Different links draw different streams.
  EXPECT_NE(on_link(leader_only, 0, 1), on_link(leader_only, 0, 3));
}

TEST(ChannelTest, LinkStreamDependsOnlyOnSeedAndEndpoints) {
  // Adding an edge elsewhere in the topology (and so another link before some links in
  // the list) leaves the decisions of every existing link unchanged.
  Scenario s = PaperScenario(9);
  s.delay = Uniform(0.1, 0.05);
  s.loss = Bernoulli(0.3);
  Scenario s2 = s;
  s2.edges.push_back({1, 2});  // 1 now also hears 2: link (2, 1), listed first in receiver order
  s2.edges.push_back({3, 4});
  const std::vector<Link> l1 = BuildLinks(s, TopologyOf(s));
  const std::vector<Link> l2 = BuildLinks(s2, TopologyOf(s2));
  ASSERT_EQ(l2.size(), l1.size() + 2);
  for (const Link& a : l1) {
    const Link* b = FindLink(l2, a.from, a.to);
    ASSERT_NE(b, nullptr);
    Rng ra = a.rng, rb = b->rng;
    for (int k = 0; k < 100; ++k) ASSERT_EQ(ra.Next(), rb.Next()) << a.from << "->" << a.to;
  }
  // The streams of distinct links are distinct.
  for (std::size_t i = 0; i < l2.size(); ++i) {
    for (std::size_t j = i + 1; j < l2.size(); ++j) {
      Rng ri = l2[i].rng, rj = l2[j].rng;
      EXPECT_NE(ri.Next(), rj.Next());
    }
  }
}

TEST(ChannelTest, NextDueAndPending) {
  Scenario s = PaperScenario(1);
  s.delay = Constant(0.05);
  LinkOverride fast;
  fast.from = 0;
  fast.to = 5;
  fast.delay = DelayConfig();  // none
  LinkOverride slow;
  slow.from = 0;
  slow.to = 1;
  slow.delay = Constant(0.1);
  s.links = {fast, slow};
  Channel<int> ch(BuildLinks(s, TopologyOf(s)), kPeriod);
  EXPECT_EQ(ch.NextDue(), -1);
  EXPECT_EQ(ch.pending(), 0u);

  std::vector<ChannelDecision> decisions;
  const Micros t0 = 5 * kPeriod;
  ch.Submit(0, 1, t0, 77, &decisions);  // -> 1 at tick 10, -> 3 at tick 8, -> 5 at tick 6
  ASSERT_EQ(decisions.size(), 3u);
  EXPECT_EQ(decisions[0].deliver_utime, 10 * kPeriod);
  EXPECT_EQ(decisions[1].deliver_utime, 8 * kPeriod);
  EXPECT_EQ(decisions[2].deliver_utime, 6 * kPeriod);
  EXPECT_EQ(ch.pending(), 3u);
  EXPECT_EQ(ch.NextDue(), 6 * kPeriod);

  std::vector<std::pair<int, int>> got;
  auto collect = [&](int r, const int& p) { got.emplace_back(r, p); };
  ch.DeliverDue(6 * kPeriod - 1, collect);
  EXPECT_TRUE(got.empty());
  EXPECT_EQ(ch.pending(), 3u);
  ch.DeliverDue(6 * kPeriod, collect);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0], std::make_pair(5, 77));
  EXPECT_EQ(ch.NextDue(), 8 * kPeriod);
  EXPECT_EQ(ch.pending(), 2u);

  // A later message overtakes nothing: 3 -> 1 (0.05 s) sent at tick 6 is due at tick 9.
  decisions.clear();
  ch.Submit(3, 2, 6 * kPeriod, 88, &decisions);
  ASSERT_EQ(decisions.size(), 1u);
  EXPECT_EQ(decisions[0].deliver_utime, 9 * kPeriod);
  EXPECT_EQ(ch.pending(), 3u);
  EXPECT_EQ(ch.NextDue(), 8 * kPeriod);

  ch.DeliverDue(100 * kPeriod, collect);
  EXPECT_EQ(got, (std::vector<std::pair<int, int>>{{5, 77}, {3, 77}, {1, 88}, {1, 77}}));
  EXPECT_EQ(ch.pending(), 0u);
  EXPECT_EQ(ch.NextDue(), -1);
}

TEST(ChannelTest, FullQueueDropsAndPayloadSlotsAreReused) {
  Scenario s = PaperScenario(2);
  s.delay = Constant(0.02);
  Channel<int> ch(BuildLinks(s, TopologyOf(s)), kPeriod, /*max_pending=*/2);
  std::vector<ChannelDecision> decisions;
  ch.Submit(0, 1, 0, 10, &decisions);
  ASSERT_EQ(decisions.size(), 3u);
  EXPECT_EQ(decisions[0].status, ChannelDecision::kDelivered);
  EXPECT_EQ(decisions[1].status, ChannelDecision::kDelivered);
  EXPECT_EQ(decisions[2].status, ChannelDecision::kDroppedQueue);
  EXPECT_EQ(ch.pending(), 2u);

  // Many rounds of submit/deliver with distinct payloads: every delivery carries its own
  // payload although storage slots are recycled.
  std::vector<std::pair<int, int>> got;
  for (int r = 1; r <= 50; ++r) {
    ch.DeliverDue(r * kPeriod, [&](int rcv, const int& p) { got.emplace_back(rcv, p); });
    ASSERT_EQ(ch.pending(), 0u);
    decisions.clear();
    ch.Submit(3, r, r * kPeriod, 1000 + r, &decisions);  // 3 -> 1
    ASSERT_EQ(decisions.size(), 1u);
  }
  ch.DeliverDue(1000 * kPeriod, [&](int rcv, const int& p) { got.emplace_back(rcv, p); });
  ASSERT_EQ(got.size(), 52u);
  EXPECT_EQ(got[0], std::make_pair(1, 10));
  EXPECT_EQ(got[1], std::make_pair(3, 10));
  for (int r = 1; r <= 50; ++r) EXPECT_EQ(got[1 + r], std::make_pair(1, 1000 + r)) << r;
}

}  // namespace
}  // namespace shoal

namespace shoal {
namespace {

// Regressions found in review of the timing wheel.
Channel<int> OneLink(double delay_s) {
  Link l;
  l.from = 0;
  l.to = 1;
  l.delay.kind = DelayKind::kConstant;
  l.delay.base_s = delay_s;
  return Channel<int>({l}, 20000);
}

TEST(ChannelWheelRegression, AMessageAlreadyDueGoesOutAtTheNextDelivery) {
  Channel<int> ch = OneLink(0.1);
  std::vector<ChannelDecision> d;
  int got = 0;
  ch.DeliverDue(1000000, [&](int, const int&) { ++got; });
  ch.Submit(0, 1, 800000, 7, &d);  // due at 900000, already past
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0].deliver_utime, 900000);
  ch.DeliverDue(1020000, [&](int r, const int& v) {
    EXPECT_EQ(r, 1);
    EXPECT_EQ(v, 7);
    ++got;
  });
  EXPECT_EQ(got, 1);
  EXPECT_EQ(ch.pending(), 0u);
}

TEST(ChannelWheelRegression, AFirstMessageAtALargeTimeDoesNotGrowTheWheel) {
  Channel<int> ch = OneLink(0.1);
  std::vector<ChannelDecision> d;
  const Micros t = 1700000000000000;  // ~54 years in microseconds
  ch.Submit(0, 1, t, 3, &d);
  int got = 0;
  ch.DeliverDue(t + 80000, [&](int, const int&) { ++got; });
  EXPECT_EQ(got, 0);
  ch.DeliverDue(t + 100000, [&](int, const int&) { ++got; });
  EXPECT_EQ(got, 1);
}

// A delay longer than the wheel (65536 ticks: 1311 s at 50 Hz) no longer sizes the wheel
// by itself (1e9 s once meant std::bad_alloc): such a delivery waits aside and enters its
// bucket before anything submitted later can, so the order stays (tick, submission).
TEST(ChannelWheelRegression, DelaysBeyondTheWheelWaitAsideAndKeepTheirOrder) {
  std::vector<Link> links(2);
  links[0].from = 0;
  links[0].to = 1;
  links[0].delay = Constant(2000.0);  // 100000 ticks
  links[1].from = 2;
  links[1].to = 1;
  links[1].delay = Constant(0.1);
  Channel<int> ch(links, kPeriod);
  std::vector<ChannelDecision> d;
  ch.Submit(0, 1, 0, 10, &d);
  EXPECT_EQ(ch.NextDue(), 2000000000);
  std::vector<std::pair<std::int64_t, int>> got;
  for (std::int64_t tick = 1; tick <= 100001; ++tick) {
    ch.DeliverDue(tick * kPeriod, [&](int, const int& v) { got.emplace_back(tick, v); });
    if (tick == 99995) ch.Submit(2, 1, tick * kPeriod, 20, &d);  // due at tick 100000 too
  }
  const std::vector<std::pair<std::int64_t, int>> expected = {{100000, 10}, {100000, 20}};
  EXPECT_EQ(got, expected);
  EXPECT_EQ(ch.pending(), 0u);
  links[0].delay = Constant(1e9);  // neither wheel nor queue grows to 5e10 ticks
  Channel<int> huge(std::vector<Link>{links[0]}, kPeriod);
  huge.Submit(0, 1, 0, 1, &d);
  EXPECT_EQ(huge.pending(), 1u);
}

// ---------------------------------------------------------------------------------------
// Acoustic, trace, Gilbert-Elliott and modem rate limit

DelayConfig Acoustic(double max_range, double processing, double jitter = 0.0,
                     double loss_at_max = 0.0) {
  DelayConfig c;
  c.kind = DelayKind::kAcoustic;
  c.sound_speed_mps = 1500.0;
  c.processing_s = processing;
  c.jitter_s = jitter;
  c.max_range_m = max_range;
  c.loss_at_max_range = loss_at_max;
  return c;
}

Link OneLink(int from, int to, const DelayConfig& delay, const LossConfig& loss = {}) {
  Link l;
  l.from = from;
  l.to = to;
  l.delay = delay;
  l.loss = loss;
  l.rng = Rng(3, 0x11A4ULL + from, to);
  l.loss_rng = Rng(3, 0x6E11ULL + from, to);
  return l;
}

// tau = range / c + processing, range from the sender's position at send time to the
// receiver's newest state sent strictly before it; to 1e-9 s.
TEST(AcousticDelay, RangeOverSoundSpeedPlusProcessing) {
  Channel<int> ch({OneLink(0, 1, Acoustic(5000.0, 0.3))}, kPeriod);
  std::vector<ChannelDecision> d;
  ch.Submit(1, 0, 0, 0, &d, Vec3(100.0, 200.0, 10.0));  // receiver at tick 0
  ch.Submit(0, 0, kPeriod, 0, &d, Vec3(-1100.0, 700.0, 30.0));
  ASSERT_EQ(d.size(), 1u);
  const double range = (Vec3(-1100.0, 700.0, 30.0) - Vec3(100.0, 200.0, 10.0)).norm();
  EXPECT_NEAR(d[0].delay_s, range / 1500.0 + 0.3, 1e-9);
  EXPECT_EQ(d[0].status, ChannelDecision::kDelivered);
  EXPECT_EQ(d[0].deliver_utime, DeliveryTime(kPeriod, d[0].delay_s, kPeriod));
}

// The receiver's state of the send tick itself is never used, whichever order the tick's
// states enter in: the result does not depend on arrival order within a tick.
TEST(AcousticDelay, ReceiverPositionIsItsStateBeforeTheSendTickWhateverTheOrder) {
  const Vec3 rx_old(0.0, 0.0, 0.0), rx_now(900.0, 0.0, 0.0), tx(0.0, 1500.0, 0.0);
  std::vector<double> delays;
  for (bool receiver_first : {true, false}) {
    Channel<int> ch({OneLink(0, 1, Acoustic(5000.0, 0.0)), OneLink(1, 2, Constant(0.1))},
                    kPeriod);
    std::vector<ChannelDecision> d;
    ch.Submit(1, 0, 0, 0, &d, rx_old);
    if (receiver_first) ch.Submit(1, 1, kPeriod, 0, &d, rx_now);
    ch.Submit(0, 0, kPeriod, 0, &d, tx);
    if (!receiver_first) ch.Submit(1, 1, kPeriod, 0, &d, rx_now);
    for (const ChannelDecision& e : d) {
      if (e.sender == 0) delays.push_back(e.delay_s);
    }
  }
  ASSERT_EQ(delays.size(), 2u);
  EXPECT_NEAR(delays[0], 1.0, 1e-12);  // 1500 m from rx_old
  EXPECT_EQ(delays[0], delays[1]);
}

// Before the receiver's first state its position is unknown: range 0.
TEST(AcousticDelay, UnknownReceiverPositionCountsAsRangeZero) {
  Channel<int> ch({OneLink(0, 1, Acoustic(5000.0, 0.2))}, kPeriod);
  std::vector<ChannelDecision> d;
  ch.Submit(0, 0, 0, 0, &d, Vec3(3000.0, 0.0, 0.0));
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0].delay_s, 0.2);
}

TEST(AcousticDelay, BeyondMaxRangeIsLostAndRangeLossRisesFromHalfRange) {
  Channel<int> ch({OneLink(0, 1, Acoustic(1000.0, 0.0, 0.0, 0.4))}, kPeriod);
  std::vector<ChannelDecision> d;
  ch.Submit(1, 0, 0, 0, &d, Vec3::Zero());
  ch.Submit(0, 0, kPeriod, 0, &d, Vec3(1000.5, 0.0, 0.0));
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0].status, ChannelDecision::kDroppedRange);
  EXPECT_STREQ(DropReason(d[0].status), "out of acoustic range");
  EXPECT_EQ(AcousticRangeLoss(Acoustic(1000.0, 0.0, 0.0, 0.4), 400.0), 0.0);
  EXPECT_NEAR(AcousticRangeLoss(Acoustic(1000.0, 0.0, 0.0, 0.4), 750.0), 0.2, 1e-15);
  EXPECT_NEAR(AcousticRangeLoss(Acoustic(1000.0, 0.0, 0.0, 0.4), 1000.0), 0.4, 1e-15);
  // At 750 m a fifth of the messages are lost.
  int lost = 0;
  const int n = 200000;
  for (int k = 2; k < n + 2; ++k) {
    d.clear();
    ch.Submit(1, k, (2 * k) * kPeriod, 0, &d, Vec3::Zero());
    ch.Submit(0, k, (2 * k + 1) * kPeriod, 0, &d, Vec3(750.0, 0.0, 0.0));
    ch.DeliverDue((2 * k + 1) * kPeriod + 2000000, [](int, const int&) {});
    lost += d.back().status == ChannelDecision::kDroppedLoss;
  }
  EXPECT_NEAR(static_cast<double>(lost) / n, 0.2, 0.005);
}

TEST(AcousticDelay, BoundsJitterAndLookahead) {
  const DelayConfig c = Acoustic(3000.0, 0.25, 0.1);
  EXPECT_NEAR(MaxDelaySeconds(c), 2.0 + 0.25 + 0.1, 1e-15);
  EXPECT_EQ(MinDelaySeconds(c), 0.25);
  // Lookahead from processing_s alone: the range can be about 0.
  EXPECT_EQ(MinLagTicks({OneLink(0, 1, c)}, kPeriod), MinDeliveryLagTicks(0.25, kPeriod));
  EXPECT_EQ(MinLagTicks({OneLink(0, 1, Acoustic(3000.0, 0.0))}, kPeriod), 1);
  Rng rng(5);
  for (int k = 0; k < 10000; ++k) {
    const double tau = DelaySeconds(c, 0.0, &rng, 1500.0);
    ASSERT_GE(tau, 1.25);
    ASSERT_LT(tau, 1.35);
  }
}

std::shared_ptr<const DelayTrace> Trace(bool hold) {
  auto t = std::make_shared<DelayTrace>();
  t->t_s = {1.0, 2.0, 4.0};
  t->delay_s = {0.5, 1.5, 0.7};
  t->hold = hold;
  return t;
}

TEST(TraceDelay, LinearOrHeldAndConstantOutsideTheRows) {
  DelayConfig c;
  c.kind = DelayKind::kTrace;
  c.trace = Trace(false);
  EXPECT_EQ(DelaySeconds(c, 0.0, nullptr), 0.5);  // before the first row: the first delay
  EXPECT_EQ(DelaySeconds(c, 1.0, nullptr), 0.5);
  EXPECT_NEAR(DelaySeconds(c, 1.25, nullptr), 0.75, 1e-15);
  EXPECT_NEAR(DelaySeconds(c, 3.0, nullptr), 1.1, 1e-15);
  EXPECT_EQ(DelaySeconds(c, 4.0, nullptr), 0.7);
  EXPECT_EQ(DelaySeconds(c, 100.0, nullptr), 0.7);  // after the last row: the last delay
  c.trace = Trace(true);
  EXPECT_EQ(DelaySeconds(c, 1.999999, nullptr), 0.5);
  EXPECT_EQ(DelaySeconds(c, 2.0, nullptr), 1.5);
  EXPECT_EQ(DelaySeconds(c, 3.9, nullptr), 1.5);
  EXPECT_EQ(MaxDelaySeconds(c), 1.5);
  EXPECT_EQ(MinDelaySeconds(c), 0.5);
}

LossConfig GilbertElliott(double gb, double bg, double lg, double lb) {
  LossConfig c;
  c.kind = LossKind::kGilbertElliott;
  c.p_good_to_bad = gb;
  c.p_bad_to_good = bg;
  c.loss_good = lg;
  c.loss_bad = lb;
  return c;
}

// Over 1e6 draws: the loss rate is the stationary (p_gb loss_bad + p_bg loss_good) /
// (p_gb + p_bg), and with loss_bad = 1, loss_good = 0 a burst of losses (a sojourn in the
// bad state) lasts 1 / p_bg messages on average.
TEST(GilbertElliottLoss, LossRateAndBurstLengthMatchTheirClosedForms) {
  const int n = 1000000;
  {
    const LossConfig c = GilbertElliott(0.05, 0.25, 0.0, 1.0);
    Rng rng(9);
    bool bad = false, prev = false;
    std::int64_t lost = 0, bursts = 0;
    for (int k = 0; k < n; ++k) {
      const bool l = Dropped(c, &rng, &bad);
      lost += l;
      bursts += l && !prev;
      prev = l;
    }
    EXPECT_NEAR(static_cast<double>(lost) / n, 0.05 / 0.3, 0.005);
    EXPECT_NEAR(static_cast<double>(lost) / bursts, 1.0 / 0.25, 0.1);
  }
  {
    const LossConfig c = GilbertElliott(0.02, 0.1, 0.01, 0.6);
    Rng rng(10);
    bool bad = false;
    std::int64_t lost = 0;
    for (int k = 0; k < n; ++k) lost += Dropped(c, &rng, &bad);
    EXPECT_NEAR(static_cast<double>(lost) / n, (0.02 * 0.6 + 0.1 * 0.01) / 0.12, 0.006);
  }
}

// Each link has its own chain and stream: a link's losses do not depend on the others.
TEST(GilbertElliottLoss, PerLinkStreamsAreIndependentAndSeeded) {
  Scenario s = PaperScenario(4);
  s.loss = GilbertElliott(0.1, 0.3, 0.0, 1.0);
  const Topology topo = Topology::Build(s.followers, s.edges, s.leader_links);
  const auto outcomes = [&](bool only_leader) {
    Channel<int> ch(BuildLinks(s, topo), kPeriod);
    std::vector<ChannelDecision> d;
    std::vector<int> leader_to_1;
    for (int k = 0; k < 2000; ++k) {
      for (int id = 0; id <= (only_leader ? 0 : 5); ++id) ch.Submit(id, k, k * kPeriod, 0, &d);
      ch.DeliverDue(k * kPeriod, [](int, const int&) {});
    }
    for (const ChannelDecision& e : d) {
      if (e.sender == 0 && e.receiver == 1) leader_to_1.push_back(e.status);
    }
    return leader_to_1;
  };
  const std::vector<int> a = outcomes(false), b = outcomes(true);
  EXPECT_EQ(a, b);
  EXPECT_GT(std::count(a.begin(), a.end(), ChannelDecision::kDroppedLoss), 100);
}

// A busy modem skips the state: a "modem busy" decision per link, nothing queued, no draw.
TEST(ModemRateLimit, SenderTransmitsAtMostOncePerInterval) {
  Scenario s = PaperScenario(2);
  s.loss = Bernoulli(0.3);
  s.modem_min_interval_s = 1.0;
  s.modems = {ModemConfig{3, 0.0}};  // follower 3 unlimited
  const std::vector<Micros> intervals = ModemIntervals(s);
  EXPECT_EQ(intervals, (std::vector<Micros>{1000000, 1000000, 1000000, 0, 1000000, 1000000}));
  const Topology topo = Topology::Build(s.followers, s.edges, s.leader_links);
  Channel<int> ch(BuildLinks(s, topo), kPeriod, 1 << 20, intervals);
  Channel<int> unlimited(BuildLinks(s, topo), kPeriod);
  std::vector<ChannelDecision> d, f;
  std::vector<int> sent_ticks;
  for (int k = 0; k <= 150; ++k) {
    d.clear();
    ch.Submit(0, k, k * kPeriod, 0, &d);
    if (d[0].status != ChannelDecision::kSkippedBusy) sent_ticks.push_back(k);
    for (const ChannelDecision& e : d) {
      EXPECT_EQ(e.status == ChannelDecision::kSkippedBusy, k % 50 != 0);
    }
    if (k % 50 == 0) unlimited.Submit(0, k, k * kPeriod, 0, &f);
    d.clear();
    ch.Submit(3, k, k * kPeriod, 0, &d);
    for (const ChannelDecision& e : d) EXPECT_NE(e.status, ChannelDecision::kSkippedBusy);
  }
  EXPECT_EQ(sent_ticks, (std::vector<int>{0, 50, 100, 150}));
  EXPECT_STREQ(DropReason(ChannelDecision::kSkippedBusy), "modem busy");
  // A skipped state draws nothing: the transmitted ones decide as an unlimited link's.
  std::vector<ChannelDecision> sent;
  Channel<int> again(BuildLinks(s, topo), kPeriod, 1 << 20, intervals);
  for (int k = 0; k <= 150; ++k) again.Submit(0, k, k * kPeriod, 0, &sent);
  sent.erase(std::remove_if(sent.begin(), sent.end(),
                            [](const ChannelDecision& e) {
                              return e.status == ChannelDecision::kSkippedBusy;
                            }),
             sent.end());
  ASSERT_EQ(sent.size(), f.size());
  for (std::size_t k = 0; k < f.size(); ++k) EXPECT_EQ(sent[k].status, f[k].status);
}

}  // namespace
}  // namespace shoal

namespace shoal {
namespace {

// Every link of the paper's swarm with `delay`, no loss: for each send tick the fewest
// ticks until a delivery, as the channel decides it (from every sender at every tick).
std::vector<std::int64_t> ObservedLags(const DelayConfig& delay, std::int64_t ticks,
                                       std::vector<Link>* links_out) {
  Scenario s = PaperScenario(7);
  s.delay = delay;
  const std::vector<Link> links =
      BuildLinks(s, Topology::Build(s.followers, s.edges, s.leader_links));
  *links_out = links;
  Channel<int> ch(links, kPeriod);
  std::vector<std::int64_t> lag(static_cast<std::size_t>(ticks),
                                std::numeric_limits<std::int64_t>::max());
  std::vector<ChannelDecision> d;
  for (std::int64_t k = 0; k < ticks; ++k) {
    ch.DeliverDue(k * kPeriod, [](int, const int&) {});
    for (int sender = 0; sender <= s.followers; ++sender) {
      d.clear();
      ch.Submit(sender, static_cast<std::int32_t>(k), k * kPeriod, 0, &d, Vec3::Zero());
      for (const ChannelDecision& c : d) {
        if (c.status != ChannelDecision::kDelivered) continue;
        auto& l = lag[static_cast<std::size_t>(k)];
        l = std::min(l, c.deliver_utime / kPeriod - k);
      }
    }
  }
  return lag;
}

// A delay that is a function of time is evaluated at each tick as the channel evaluates
// it: the bound is the channel's own lag, tick by tick (Example 2's tau(t) = 0.1 + 0.05
// cos(t): 3 to 8 ticks). Windows cut from it hold no delivery of their own states and
// are as long as that allows.
TEST(LagBoundTest, FollowsATimeVaryingDelayTickByTick) {
  std::vector<Link> links;
  const std::int64_t ticks = 1000;  // 20 s, three periods of cos(t)
  const std::vector<std::int64_t> lag = ObservedLags(Sinusoid(0.1, 0.05, 1.0), ticks, &links);
  const LagBound bound(links, nullptr, kPeriod);
  for (std::int64_t k = 0; k < ticks; ++k) {
    ASSERT_EQ(bound.LagAt(k), lag[static_cast<std::size_t>(k)]) << "tick " << k;
  }
  std::int64_t shortest = 100, longest = 0;
  for (std::int64_t first = 0; first + 50 < ticks;) {
    const std::int64_t len = bound.Window(first, 50);
    for (std::int64_t s = first; s < first + len; ++s) {
      ASSERT_GE(s + lag[static_cast<std::size_t>(s)], first + len) << "window " << first;
    }
    // One tick more would hold a delivery of one of its own states.
    bool reached = false;
    for (std::int64_t s = first; s <= first + len; ++s) {
      reached = reached || s + lag[static_cast<std::size_t>(s)] <= first + len;
    }
    EXPECT_TRUE(reached) << "window " << first << " could be longer than " << len;
    shortest = std::min(shortest, len);
    longest = std::max(longest, len);
    first += len;
  }
  EXPECT_EQ(shortest, 3);
  EXPECT_EQ(longest, 8);
  EXPECT_EQ(MinLagTicks(links, kPeriod), 3);
  // The cap holds: a constant 0.8 s delay allows 40 ticks.
  std::vector<Link> slow;
  ObservedLags(Constant(0.8), 10, &slow);
  EXPECT_EQ(LagBound(slow, nullptr, kPeriod).Window(123, 50), 40);
  EXPECT_EQ(LagBound(slow, nullptr, kPeriod).Window(123, 7), 7);
}

// A delay with a draw or a range counts with its smallest value; the smallest model of
// any link, or of a timeline's channel event, bounds every tick; no links bound nothing.
TEST(LagBoundTest, ModelsWithADrawCountWithTheirSmallestDelay) {
  const std::vector<Link> uniform = {OneLink(0, 1, Uniform(0.2, 0.1)),
                                     OneLink(1, 2, Sinusoid(0.3, 0.1, 1.0))};
  const LagBound bound(uniform, nullptr, kPeriod);
  for (std::int64_t k = 0; k < 500; ++k) {
    ASSERT_EQ(bound.LagAt(k), MinDeliveryLagTicks(0.1, kPeriod)) << k;  // 5 ticks
  }
  EXPECT_EQ(LagBound({OneLink(0, 1, Acoustic(3000.0, 0.25))}, nullptr, kPeriod).LagAt(9),
            MinLagTicks({OneLink(0, 1, Acoustic(3000.0, 0.25))}, kPeriod));
  EXPECT_EQ(LagBound({}, nullptr, kPeriod).Window(0, 50), 50);
  DelayConfig none;
  EXPECT_EQ(LagBound({OneLink(0, 1, none)}, nullptr, kPeriod).Window(4, 50), 1);
}

}  // namespace
}  // namespace shoal
