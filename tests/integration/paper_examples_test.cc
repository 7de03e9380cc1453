// The shipped scenarios converge in shoal sim (in process, the same core as the CLI): the
// paper's two examples, and the REMUS 100 scenario within the vehicle's limits.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "core/swarm.h"
#include "core/theory.h"
#include "core/topology.h"
#include "scenario/loader.h"

namespace shoal {
namespace {

struct Outcome {
  bool converged;
  double t_conv;
  double final_pos;
  std::int64_t saturated;
};

Outcome RunScenario(const std::string& rel) {
  const Scenario s = LoadScenario(std::string(SHOAL_SOURCE_DIR) + "/" + rel);
  Swarm swarm(s);
  swarm.Run(nullptr);
  std::int64_t sat = 0;
  for (const auto& f : swarm.followers()) sat += f->counters().saturated_ticks;
  EXPECT_EQ(swarm.diverged_id(), 0);
  return {swarm.metrics().converged(), swarm.metrics().convergence_time_s(),
          swarm.metrics().final_worst().position_m, sat};
}

TEST(PaperExamples, Example1Converges) {
  const Outcome o = RunScenario("scenarios/paper_example1.toml");
  EXPECT_TRUE(o.converged);
  EXPECT_GT(o.t_conv, 5.0);  // the initial errors are tens of metres
  EXPECT_LT(o.t_conv, 150.0);
  EXPECT_LT(o.final_pos, 0.1);
  EXPECT_EQ(o.saturated, 0);  // the paper's double integrator: limits never bind
}

TEST(PaperExamples, Example2ConvergesLaterThanExample1) {
  const Outcome o1 = RunScenario("scenarios/paper_example1.toml");
  const Outcome o2 = RunScenario("scenarios/paper_example2.toml");
  EXPECT_TRUE(o2.converged);
  EXPECT_LT(o2.final_pos, 0.1);
  EXPECT_GT(o2.t_conv, o1.t_conv);  // delays and the uncertain factor slow it down
  EXPECT_EQ(o2.saturated, 0);
}

// Every scenario shipped in scenarios/ loads and converges without a diverging vehicle.
TEST(ShippedScenarios, EveryOneConverges) {
  std::vector<std::string> names;
  for (const auto& e :
       std::filesystem::directory_iterator(std::string(SHOAL_SOURCE_DIR) + "/scenarios")) {
    if (e.path().extension() == ".toml") names.push_back(e.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  // The files the documentation and the tests name are all there.
  for (const char* must : {"paper_example1.toml", "paper_example2.toml", "remus_realistic.toml"}) {
    EXPECT_NE(std::find(names.begin(), names.end(), must), names.end()) << must;
  }
  for (const std::string& name : names) {
    SCOPED_TRACE(name);
    const Outcome o = RunScenario("scenarios/" + name);
    EXPECT_TRUE(o.converged);
  }
}

/// Largest speed |[u v w]| and pitch |theta| of any follower over a run.
class EnvelopeObserver : public SwarmObserver {
 public:
  void OnState(const StateMsg& m) override {
    if (m.vehicle_id == 0) return;  // the leader's path is not a vehicle
    max_speed_ = std::max(max_speed_, m.nu.head<3>().norm());
    max_pitch_ = std::max(max_pitch_, std::abs(m.eta(3)));
  }
  double max_speed_ = 0.0;
  double max_pitch_ = 0.0;
};

// scenarios/remus_realistic.toml keeps to what a REMUS 100 can do (docs/reference.md,
// "Limits and virtual inputs"): limits no larger than the vehicle's, a delay inside the
// exact delay margin with a factor 2 to spare, speeds up to 2.5 m/s, |pitch| up to 30 deg,
// and it converges without any saturated tick (measured: none; convergence at 61.8 s).
TEST(RemusRealistic, ReachesTheFormationWithinTheVehiclesLimits) {
  const Scenario s = LoadScenario(std::string(SHOAL_SOURCE_DIR) + "/scenarios/remus_realistic.toml");
  const Vec5 remus_limits = (Vec5() << 100.0, 10.0, 10.0, 6.0, 6.0).finished();
  for (int k = 0; k < 5; ++k) EXPECT_LE(s.vehicle.tau_max(k), remus_limits(k)) << "channel " << k;

  const theory::DelayBounds delay = theory::DelayBoundsOf(s);
  EXPECT_TRUE(delay.constant);
  EXPECT_GT(delay.h_s, 0.0);  // an acoustic link is never instantaneous
  const Topology topo = Topology::Build(s.followers, s.edges, s.leader_links);
  const theory::DelayMargin margin =
      theory::ComputeDelayMargin(theory::HEigenvalues(topo.H()), s.k1, s.k2);
  EXPECT_TRUE(margin.stable_at_zero);
  EXPECT_GT(margin.tau_s, 2.0 * delay.h_s);

  Swarm swarm(s);
  EnvelopeObserver env;
  swarm.Run(&env);
  EXPECT_EQ(swarm.diverged_id(), 0);
  EXPECT_TRUE(swarm.metrics().converged());
  EXPECT_LT(swarm.metrics().convergence_time_s(), 0.5 * s.duration_s);
  EXPECT_LT(swarm.metrics().final_worst().position_m, 0.01);
  for (const auto& f : swarm.followers()) {
    EXPECT_EQ(f->counters().saturated_ticks, 0) << "follower " << f->id();
  }
  EXPECT_GT(env.max_speed_, 1.0);  // the observer saw the followers cruise
  EXPECT_LE(env.max_speed_, 2.5);
  EXPECT_LE(env.max_pitch_, 30.0 * 3.14159265358979323846 / 180.0);
}

}  // namespace
}  // namespace shoal
