#include "campaign/criteria.h"

#include <gtest/gtest.h>

namespace shoal {
namespace {

std::vector<CampaignCriterion> Criteria(const std::string& pass) {
  return ParseCampaign("[campaign]\nscenario = \"s.toml\"\n[pass]\n" + pass, "c.toml").pass;
}

const nlohmann::ordered_json kRun = nlohmann::ordered_json::parse(
    R"({"converged": true, "final_position_error_m": 0.2, "name": "x",
        "channel": {"delay_error_p99_s": 0.002, "links": [1, 2]}, "none": null})");

TEST(CampaignCriteria, FlattensScalarsToDottedKeys) {
  const auto flat = FlattenScalars(kRun);
  EXPECT_EQ(flat.size(), 4u);
  EXPECT_EQ(flat["channel.delay_error_p99_s"], 0.002);
  EXPECT_FALSE(flat.contains("channel.links"));
  EXPECT_FALSE(flat.contains("none"));
}

TEST(CampaignCriteria, PassesWhenEveryCriterionHolds) {
  const Judgement j = JudgeRun(
      Criteria("converged = true\nname = \"x\"\nfinal_position_error_m = { min = 0.1, max = 0.5 }\n"
               "\"channel.delay_error_p99_s\" = { max = 0.01 }\n"),
      kRun);
  EXPECT_TRUE(j.pass);
  EXPECT_EQ(j.why, "");
}

TEST(CampaignCriteria, WhyListsEachFailureWithItsValue) {
  const Judgement j = JudgeRun(
      Criteria("converged = false\nfinal_position_error_m = { max = 0.1 }\n"
               "\"channel.delay_error_p99_s\" = { min = 0.01 }\nname = 3\nmissing.metric = 1\n"),
      kRun);
  EXPECT_FALSE(j.pass);
  EXPECT_EQ(j.why,
            "converged = true, not false; final_position_error_m = 0.2 > max 0.1; "
            "channel.delay_error_p99_s = 0.002 < min 0.01; name = \"x\", not 3; "
            "missing.metric: missing from the run's JSON");
}

TEST(CampaignCriteria, NumbersCompareAcrossIntegerAndFloat) {
  EXPECT_TRUE(JudgeRun(Criteria("n = 2\n"), nlohmann::ordered_json::parse(R"({"n": 2.0})")).pass);
  EXPECT_FALSE(JudgeRun(Criteria("n = { max = 1 }\n"),
                        nlohmann::ordered_json::parse(R"({"n": "1"})")).pass);
}

}  // namespace
}  // namespace shoal
