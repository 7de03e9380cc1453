// The paper's two examples converge in shoal sim (in process, the same core as the CLI).
#include <gtest/gtest.h>

#include "core/swarm.h"
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

}  // namespace
}  // namespace shoal
