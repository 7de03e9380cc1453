// design/theory_curve: the bounds a stability map draws, against what `shoal design`
// reports for the same scenarios (docs/reference.md, Example 2; scenarios/remus_realistic.toml
// states its Theorem 3 bound), and their translation onto channel.delay.base_s.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>

#include "design/report.h"
#include "design/theory_curve.h"
#include "scenario/loader.h"

namespace shoal {
namespace design {
namespace {

Scenario Load(const std::string& rel) {
  return LoadScenario(std::string(SHOAL_SOURCE_DIR) + "/" + rel);
}

TEST(TheoryCurve, OnlyTheDelayBaseIsADelayAxis) {
  DelayAxis a = DelayAxis::kBound;
  EXPECT_TRUE(DelayAxisOfKey("channel.delay.base_s", &a));
  EXPECT_EQ(a, DelayAxis::kBase);
  EXPECT_FALSE(DelayAxisOfKey("control.k1", &a));
  EXPECT_FALSE(DelayAxisOfKey("channel.delay.amplitude_s", &a));
}

TEST(TheoryCurve, Example2ExactMarginOnHAndOnTheBase) {
  const Scenario s = Load("scenarios/paper_example2.toml");  // sinusoid 0.1 + 0.05 cos t
  const TheoryPoint p = ComputeTheoryPoint(s);
  std::printf("paper_example2: %.3f s per value\n", p.seconds);
  EXPECT_NEAR(p.h_s, 0.15, 1e-12);
  EXPECT_NEAR(p.axis_offset_s, 0.05, 1e-12);
  EXPECT_NEAR(p.exact_margin_s, 0.3435, 1e-3);
  EXPECT_NEAR(p.exact_on_axis, p.exact_margin_s - 0.05, 1e-12);
  EXPECT_TRUE(p.exact_why.empty());
  EXPECT_TRUE(p.note.empty());
  // The same numbers as the report of `shoal design`.
  const DesignReport r = BuildDesignReport(s, DesignRequest{});
  EXPECT_EQ(p.exact_margin_s, r.GoverningMarginS());
  // Theorem 3 certifies nothing for Example 2 (`shoal design`: "max delay: none
  // (infeasible even at h = 0)"): no value, and the reason.
  ASSERT_TRUE(r.theorem3.evaluated);
  EXPECT_FALSE(r.theorem3.max_delay.feasible_at_zero);
  EXPECT_TRUE(std::isnan(p.theorem3_max_delay_s));
  EXPECT_TRUE(std::isnan(p.theorem3_on_axis));
  EXPECT_NE(p.theorem3_why.find("infeasible even at h = 0"), std::string::npos) << p.theorem3_why;
  // Kept as a bound on h when the axis is h itself.
  const TheoryPoint b = ComputeTheoryPoint(s, {DelayAxis::kBound});
  EXPECT_EQ(b.axis_offset_s, 0.0);
  EXPECT_EQ(b.exact_on_axis, b.exact_margin_s);
}

TEST(TheoryCurve, RemusTheorem3MaxDelayAsShoalDesignPrintsIt) {
  const Scenario s = Load("scenarios/remus_realistic.toml");  // constant 0.5 s
  const TheoryPoint p = ComputeTheoryPoint(s);
  std::printf("remus_realistic: %.3f s per value\n", p.seconds);
  EXPECT_NEAR(p.theorem3_max_delay_s, 1.145, 0.01);
  EXPECT_FALSE(p.theorem3_hit_cap);
  EXPECT_TRUE(p.theorem3_why.empty()) << p.theorem3_why;
  EXPECT_EQ(p.axis_offset_s, 0.0);  // constant: h is base_s
  EXPECT_EQ(p.theorem3_on_axis, p.theorem3_max_delay_s);
  EXPECT_NEAR(p.exact_margin_s, 1.90, 0.01);  // the scenario's comment
}

TEST(TheoryCurve, AnAmplitudeThatUsesUpTheBoundHasNoValueOnTheBase) {
  Scenario s = Load("scenarios/paper_example2.toml");
  s.delay.amplitude_s = 0.5;  // h - base = 0.5 s > the exact margin 0.3435 s
  const TheoryPoint p = ComputeTheoryPoint(s);
  EXPECT_NEAR(p.exact_margin_s, 0.3435, 1e-3);  // independent of the delay
  EXPECT_TRUE(std::isnan(p.exact_on_axis));
  EXPECT_NE(p.exact_why.find("uses up the bound"), std::string::npos) << p.exact_why;
  EXPECT_TRUE(std::isnan(p.theorem3_on_axis));
  EXPECT_FALSE(p.theorem3_why.empty());
}

TEST(TheoryCurve, UniformJitterHasNoTheorem3AndSaysWhy) {
  Scenario s = Load("scenarios/remus_realistic.toml");
  s.delay.kind = DelayKind::kUniform;
  s.delay.amplitude_s = 0.1;
  const std::vector<TheoryPoint> c = ComputeTheoryCurve({s, s});
  ASSERT_EQ(c.size(), 2u);
  EXPECT_TRUE(std::isnan(c[0].theorem3_max_delay_s));
  EXPECT_NE(c[0].theorem3_why.find("does not apply"), std::string::npos) << c[0].theorem3_why;
  EXPECT_NEAR(c[0].exact_on_axis, c[0].exact_margin_s - 0.1, 1e-12);
}

TEST(TheoryCurve, SwitchingTopologiesTakeTheSmallestMarginAndNoTheorem3) {
  const Scenario s = Load("scenarios/switching_topology.toml");
  const TheoryPoint p = ComputeTheoryPoint(s);
  const DesignReport r = BuildDesignReport(s, DesignRequest{});
  ASSERT_TRUE(r.switching.has_value());
  EXPECT_EQ(p.exact_margin_s, r.switching->min_margin_s);
  EXPECT_TRUE(std::isnan(p.theorem3_on_axis));
  EXPECT_NE(p.theorem3_why.find("switches"), std::string::npos) << p.theorem3_why;
}

}  // namespace
}  // namespace design
}  // namespace shoal
