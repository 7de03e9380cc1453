// Follower node: bus-input validation, staleness, and protocol (10) with the own state
// taken from the history at each neighbour message's send time.
#include "core/follower.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "core/leader_path.h"

namespace shoal {
namespace {

constexpr Micros kPeriod = 20000;

// Two followers: 1 hears the leader, 2 hears 1 and the leader.
Scenario TwoFollowers() {
  Scenario s;
  s.name = "two";
  s.followers = 2;
  s.edges = {{2, 1}};
  s.leader_links = {1, 2};
  s.k1 = 0.3;
  s.k2 = 1.1;
  s.offsets_m = {Vec3(1.0, -2.0, 0.5), Vec3(-3.0, 0.0, 0.0)};
  s.initial.resize(2);
  s.initial[0].given = true;
  s.initial[0].eta << 1, 2, 3, 0.1, 3.0;
  s.initial[0].nu << 1.0, 0.1, -0.1, 0.0, 0.05;
  s.initial[1].given = true;
  s.initial[1].eta << -4, 5, 6, -0.05, -3.1;
  s.initial[1].nu << 0.5, 0, 0, 0.01, -0.02;
  s.vehicle.tau_max = Vec5::Constant(1e9);
  s.vehicle.integrator_step_s = 0.005;
  return s;
}

StateMsg Msg(int id, std::int32_t seq, Micros utime, const Vec5& eta, const Vec5& eta_dot) {
  StateMsg m;
  m.vehicle_id = id;
  m.seq = seq;
  m.utime = utime;
  m.eta = eta;
  m.eta_dot = eta_dot;
  return m;
}

// The period is split into the fewest whole RK4 steps no longer than the step asked for;
// a ratio a rounding away from a whole number is that number.
TEST(Follower, Rk4StepsAreNoLongerThanAsked) {
  Scenario s = TwoFollowers();
  const auto steps = [&](double rate_hz, double step_s) {
    s.control_rate_hz = rate_hz;
    s.vehicle.integrator_step_s = step_s;
    return Follower::Rk4Substeps(s);
  };
  EXPECT_EQ(steps(50, 0.02), 1);
  EXPECT_EQ(steps(50, 0.01), 2);
  EXPECT_EQ(steps(50, 0.0134), 2);  // 1.49 steps: two of 0.01 s, not one of 0.02 s
  EXPECT_EQ(steps(50, 0.019), 2);
  EXPECT_EQ(steps(10, 0.02), 5);    // 0.1 / 0.02 is 5.000000000000001
  EXPECT_EQ(steps(50, 0.02 / 3), 3);
  EXPECT_EQ(steps(50, 1e-12), kMaxRk4Substeps);  // the loader refuses it; never an overflow
}

TEST(Follower, RejectsBadInputAndCountsIt) {
  const Scenario s = TwoFollowers();
  const Topology topo = Topology::Build(s.followers, s.edges, s.leader_links);
  Follower f(s, topo, 2);
  const Vec5 z = Vec5::Zero();

  // Given a good message from neighbour 1, when the same seq arrives again or an older
  // one, then it is dropped as old.
  EXPECT_EQ(f.Receive(Msg(1, 5, 100000, z, z)), RxResult::kAccepted);
  EXPECT_EQ(f.Receive(Msg(1, 5, 100000, z, z)), RxResult::kOld);
  EXPECT_EQ(f.Receive(Msg(1, 4, 80000, z, z)), RxResult::kOld);
  EXPECT_EQ(f.Receive(Msg(1, 6, 100000, z, z)), RxResult::kOld);  // same time, newer seq
  // Unknown senders: a follower that is not a neighbour, an id out of range, negative.
  EXPECT_EQ(f.Receive(Msg(2, 1, 1, z, z)), RxResult::kUnknownSender);
  EXPECT_EQ(f.Receive(Msg(7, 1, 1, z, z)), RxResult::kUnknownSender);
  EXPECT_EQ(f.Receive(Msg(-3, 1, 1, z, z)), RxResult::kUnknownSender);
  // NaN and Inf anywhere.
  StateMsg bad = Msg(0, 1, 1, z, z);
  bad.eta(3) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(f.Receive(bad), RxResult::kNonFinite);
  bad = Msg(0, 1, 1, z, z);
  bad.tau(0) = std::numeric_limits<double>::infinity();
  EXPECT_EQ(f.Receive(bad), RxResult::kNonFinite);

  EXPECT_EQ(f.counters().msgs_received, 1);
  EXPECT_EQ(f.counters().msgs_dropped_old, 3);
  EXPECT_EQ(f.counters().msgs_dropped_invalid, 5);
}

// Every one of a message's 25 numbers, each non-finite value, and the extreme finite ones.
TEST(StateMsg, AllFiniteFindsANonFiniteValueInAnyField) {
  const double kNonFinite[] = {std::numeric_limits<double>::quiet_NaN(),
                               -std::numeric_limits<double>::quiet_NaN(),
                               std::numeric_limits<double>::signaling_NaN(),
                               std::numeric_limits<double>::infinity(),
                               -std::numeric_limits<double>::infinity()};
  const double kFinite[] = {std::numeric_limits<double>::max(),
                            -std::numeric_limits<double>::max(),
                            std::numeric_limits<double>::denorm_min(), -0.0, 1e300, -1.5};
  for (int field = 0; field < 5; ++field) {
    for (int i = 0; i < 5; ++i) {
      const auto with = [&](double x) {
        StateMsg m;
        Vec5* vectors[] = {&m.eta, &m.nu, &m.eta_dot, &m.accel_cmd, &m.tau};
        for (Vec5* v : vectors) v->setConstant(std::numeric_limits<double>::max());
        (*vectors[field])(i) = x;
        return m;
      };
      for (const double x : kNonFinite) {
        EXPECT_FALSE(with(x).AllFinite()) << "field " << field << " index " << i << " " << x;
      }
      for (const double x : kFinite) {
        EXPECT_TRUE(with(x).AllFinite()) << "field " << field << " index " << i << " " << x;
      }
    }
  }
}

TEST(Follower, NoNeighbourDataMeansZeroCommand) {
  const Scenario s = TwoFollowers();
  const Topology topo = Topology::Build(s.followers, s.edges, s.leader_links);
  Follower f(s, topo, 1);
  const StateMsg& m = f.Tick(0);
  EXPECT_EQ(m.accel_cmd, Vec5::Zero());
  EXPECT_EQ(f.counters().active_neighbours, 0);
}

// Runs follower 2 for several ticks, feeding messages with different (per-link) delays,
// and checks the command against protocol (10) computed by hand from the follower's own
// published states at the messages' send times.
TEST(Follower, ProtocolUsesOwnStateAtEachMessagesSendTime) {
  const Scenario s = TwoFollowers();
  const Topology topo = Topology::Build(s.followers, s.edges, s.leader_links);
  Follower f(s, topo, 2);

  std::vector<StateMsg> own;  // follower 2's published states, tick by tick
  for (int k = 0; k < 10; ++k) own.push_back(f.Tick(k * kPeriod));

  // Leader message sent at tick 3 (delay 0.12 s), neighbour 1 sent at tick 7 (0.04 s).
  Vec5 eta0, eta0_dot, eta1, eta1_dot;
  eta0 << 10, -5, 2, 0.2, -3.0;
  eta0_dot << 0.4, 0.1, -0.1, 0.01, 0.02;
  eta1 << -2, 7, 4, 0.05, 3.1;
  eta1_dot << 0.2, -0.3, 0.0, 0.0, -0.01;
  ASSERT_EQ(f.Receive(Msg(0, 3, 3 * kPeriod, eta0, eta0_dot)), RxResult::kAccepted);
  ASSERT_EQ(f.Receive(Msg(1, 7, 7 * kPeriod, eta1, eta1_dot)), RxResult::kAccepted);
  const StateMsg m = f.Tick(10 * kPeriod);

  auto wrap = [](double a) { return std::remainder(a, 2 * M_PI); };
  const Vec5 d2 = (Vec5() << -3, 0, 0, 0, 0).finished();
  const Vec5 d1 = (Vec5() << 1, -2, 0.5, 0, 0).finished();
  Vec5 expected = Vec5::Zero();
  {  // leader term with own state at tick 3
    Vec5 e = eta0 - (own[3].eta - d2);
    e(3) = wrap(e(3));
    e(4) = wrap(e(4));
    expected += s.k1 * e + s.k2 * (eta0_dot - own[3].eta_dot);
  }
  {  // neighbour 1 term with own state at tick 7
    Vec5 e = (eta1 - d1) - (own[7].eta - d2);
    e(3) = wrap(e(3));
    e(4) = wrap(e(4));
    expected += s.k1 * e + s.k2 * (eta1_dot - own[7].eta_dot);
  }
  EXPECT_LT((m.accel_cmd - expected).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_EQ(f.counters().active_neighbours, 2);
  // Headings 3.1 and own ~-3.1 are close across +-pi: the wrapped term is small.
  EXPECT_LT(std::abs(m.accel_cmd(4)), 5.0);
}

TEST(Follower, StaleNeighbourDropsOutAndIsCounted) {
  Scenario s = TwoFollowers();
  s.neighbour_timeout_s = 0.1;
  const Topology topo = Topology::Build(s.followers, s.edges, s.leader_links);
  Follower f(s, topo, 2);
  const Vec5 z = Vec5::Zero();
  f.Tick(0);
  ASSERT_EQ(f.Receive(Msg(0, 0, 0, z, z)), RxResult::kAccepted);
  ASSERT_EQ(f.Receive(Msg(1, 0, 0, z, z)), RxResult::kAccepted);
  f.Tick(kPeriod);
  EXPECT_EQ(f.counters().active_neighbours, 2);
  // Only the leader keeps sending.
  for (int k = 2; k <= 8; ++k) {
    ASSERT_EQ(f.Receive(Msg(0, k, (k - 1) * kPeriod, z, z)), RxResult::kAccepted);
    const StateMsg& m = f.Tick(k * kPeriod);
    const bool stale = k * kPeriod > 100000;
    EXPECT_EQ(f.counters().active_neighbours, stale ? 1 : 2) << "tick " << k;
    EXPECT_EQ((m.flags & StateMsg::kFlagStaleNeighbour) != 0, stale) << "tick " << k;
  }
  EXPECT_EQ(f.counters().neighbour_timeouts, 1);  // counted once per transition
  // A fresh message revives it.
  ASSERT_EQ(f.Receive(Msg(1, 9, 8 * kPeriod, z, z)), RxResult::kAccepted);
  f.Tick(9 * kPeriod);
  EXPECT_EQ(f.counters().active_neighbours, 2);
}

TEST(Follower, NeverUsesDataFromTheFuture) {
  const Scenario s = TwoFollowers();
  const Topology topo = Topology::Build(s.followers, s.edges, s.leader_links);
  Follower f(s, topo, 1);
  const Vec5 z = Vec5::Zero();
  f.Tick(0);
  ASSERT_EQ(f.Receive(Msg(0, 1, 5 * kPeriod, z, z)), RxResult::kAccepted);
  const StateMsg& m = f.Tick(kPeriod);
  EXPECT_EQ(f.counters().active_neighbours, 0);
  EXPECT_EQ(m.accel_cmd, Vec5::Zero());
}

TEST(Follower, StartsAtLeaderPlusOffsetWhenNoInitialStateGiven) {
  Scenario s = TwoFollowers();
  s.initial[0].given = false;
  const Topology topo = Topology::Build(s.followers, s.edges, s.leader_links);
  Follower f(s, topo, 1);
  const Vec5 l = LeaderPath(s.leader).At(0.0).eta;
  EXPECT_LT((f.state().eta.head<3>() - (l.head<3>() + s.offsets_m[0])).norm(), 1e-12);
  EXPECT_EQ(f.state().nu, Vec5::Zero());
}

TEST(Follower, PaperDisturbanceRelativeToLeaderVanishesOnTheLeader) {
  // A follower with zero offset sitting exactly on the leader's path and moving with it
  // feels F_i = f(x_i) - f(x_0) = 0 when relative_to_leader is set, and f(x_0) otherwise.
  for (const bool relative : {true, false}) {
    Scenario s;
    s.followers = 1;
    s.leader_links = {1};
    s.k1 = 1e-9;  // (almost) no control: isolate the disturbance
    s.k2 = 1e-9;
    s.offsets_m = {Vec3::Zero()};
    s.initial.resize(1);
    const LeaderSample l0 = LeaderPath(s.leader).At(0.0);
    s.initial[0].given = true;
    s.initial[0].eta = l0.eta;
    s.initial[0].nu = l0.nu;
    s.vehicle.tau_max = Vec5::Constant(1e9);
    s.disturbance.kind = DisturbanceKind::kPaperExample2;
    s.disturbance.relative_to_leader = relative;
    const Topology topo = Topology::Build(1, s.edges, s.leader_links);
    Follower with(s, topo, 1);
    s.disturbance.kind = DisturbanceKind::kNone;
    Follower without(s, topo, 1);
    with.Tick(0);
    without.Tick(0);
    const double diff = (with.state().nu - without.state().nu).norm();
    if (relative) {
      EXPECT_LT(diff, 1e-12);
    } else {
      EXPECT_GT(diff, 1e-4);
    }
  }
}

}  // namespace
}  // namespace shoal
