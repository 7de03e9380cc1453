#include "campaign/plan.h"

#include "campaign/map.h"

#include <gtest/gtest.h>

namespace shoal {
namespace {

const std::string kScenario = std::string(SHOAL_SOURCE_DIR) + "/scenarios/paper_example2.toml";

Campaign Parse(const std::string& body) {
  return ParseCampaign("[campaign]\nscenario = \"" + kScenario + "\"\n" + body, "sweep.toml");
}

std::string PlanError(const Campaign& c, const std::vector<std::string>& cli_set = {}) {
  try {
    PlanPoints(c, ReadScenarioText(c.scenario), BaseOverrides(c, cli_set), MakePoints(c));
  } catch (const CampaignError& e) {
    return e.what();
  }
  return "";
}

TEST(CampaignPlan, OverridesApplyCampaignSetThenFlagsThenAxes) {
  const Campaign c = Parse("set = [\"control.k1=0.2\"]\n[[axis]]\nkey = \"control.k2\"\nvalues = [1.5]\n");
  const auto overrides = PointOverrides(c, BaseOverrides(c, {"control.k1=0.25"}), MakePoints(c)[0]);
  ASSERT_EQ(overrides.size(), 3u);
  EXPECT_EQ(overrides[0].origin, "sweep.toml:3: set control.k1=0.2");
  EXPECT_EQ(overrides[1].value, "0.25");
  EXPECT_EQ(overrides[2].key, "control.k2");
  EXPECT_EQ(overrides[2].value, "1.5");
  EXPECT_EQ(overrides[2].origin, "sweep.toml:4: axis control.k2");
}

TEST(CampaignPlan, ABadAxisValueNamesTheAxisLineAndPoint) {
  const std::string error = PlanError(
      Parse("[[axis]]\nkey = \"control.k1\"\nvalues = [0.2]\n"
            "[[axis]]\nkey = \"channel.delay.base_s\"\nvalues = [0.1, -1]\n"));
  EXPECT_EQ(error.rfind("sweep.toml:6: axis channel.delay.base_s: channel.delay.base_s: ", 0), 0u)
      << error;
  EXPECT_NE(error.find("(got -1)"), std::string::npos) << error;
  EXPECT_NE(error.find("(point 1)"), std::string::npos) << error;
  EXPECT_NE(PlanError(Parse("[[axis]]\nkey = \"control.k9\"\nvalues = [1]\n")).find("axis control.k9"),
            std::string::npos);
  EXPECT_NE(PlanError(Parse(""), {"control.k1=-3"}).find("--set control.k1=-3"), std::string::npos);
  EXPECT_NE(PlanError(Parse(""), {"=3"}).find("--set"), std::string::npos);
}

TEST(CampaignPlan, TheoryIsTheExactDelayMarginAndTheorem3AlongTheOtherMapAxis) {
  const Campaign c = Parse(
      "duration_s = 50\nset = ['channel.delay={ model = \"constant\", base_s = 0.1 }']\n"
      "[[axis]]\nkey = \"channel.delay.base_s\"\nvalues = [0.1, 0.2]\n"
      "[[axis]]\nkey = \"control.k2\"\nvalues = [1.152, 2.0]\n");
  const auto points = MakePoints(c);
  const auto base = BaseOverrides(c, {});
  const auto plans = PlanPoints(c, ReadScenarioText(c.scenario), base, points);
  ASSERT_EQ(plans.size(), 4u);
  EXPECT_EQ(plans[0].duration_s, 50);
  EXPECT_EQ(PointTimeout(c, plans[0]), 65);
  const auto theory = MapTheory(c, ReadScenarioText(c.scenario), base, points);
  EXPECT_EQ(theory["delay_axis"], "channel.delay.base_s");
  EXPECT_EQ(theory["along"], "control.k2");
  const auto& curve = theory["points"];
  ASSERT_EQ(curve.size(), 2u);  // one per k2: the delay axis does not change the bounds
  EXPECT_EQ(curve[0]["at"], 1.152);
  // docs/theory.md, Example 2: a constant delay has no offset from its base.
  EXPECT_NEAR(curve[0]["exact_on_axis"].get<double>(), 0.3435, 5e-4);
  EXPECT_TRUE(curve[0]["theorem3_on_axis"].is_null());  // infeasible even at h = 0
  EXPECT_FALSE(curve[0]["theorem3_why"].get<std::string>().empty());
  EXPECT_GT(curve[1]["exact_on_axis"].get<double>(), 0.0);
  EXPECT_NE(curve[1]["exact_on_axis"], curve[0]["exact_on_axis"]);
}

TEST(CampaignPlan, WithoutADelayAxisTheTheoryIsTheFirstPointsForReference) {
  const Campaign c = Parse("[[axis]]\nkey = \"run.seed\"\nrange = [1, 3]\n");
  const auto points = MakePoints(c);
  const auto theory = MapTheory(c, ReadScenarioText(c.scenario), BaseOverrides(c, {}), points);
  EXPECT_TRUE(theory["delay_axis"].is_null());
  ASSERT_EQ(theory["points"].size(), 1u);
  EXPECT_NEAR(theory["points"][0]["exact_margin_s"].get<double>(), 0.3435, 5e-4);
}

}  // namespace
}  // namespace shoal
