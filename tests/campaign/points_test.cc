#include "campaign/points.h"

#include <gtest/gtest.h>

#include <set>
#include <string>

namespace shoal {
namespace {

Campaign Parse(const std::string& body) {
  return ParseCampaign("[campaign]\nscenario = \"s.toml\"\n" + body, "c.toml");
}

TEST(CampaignPoints, GridIsNestedLoopsFirstAxisSlowest) {
  const auto points = MakePoints(Parse("[[axis]]\nkey = \"a\"\nvalues = [1, \"x\"]\n"
                                       "[[axis]]\nkey = \"b\"\nrange = [5, 7]\n"));
  ASSERT_EQ(points.size(), 6u);
  const char* expected[6][2] = {{"1", "5"},     {"1", "6"},     {"1", "7"},
                                {"\"x\"", "5"}, {"\"x\"", "6"}, {"\"x\"", "7"}};
  for (int p = 0; p < 6; ++p) {
    EXPECT_EQ(points[p].index, p);
    EXPECT_EQ(points[p].values[0], expected[p][0]);
    EXPECT_EQ(points[p].values[1], expected[p][1]);
  }
  EXPECT_EQ(points[3].json[0], "x");
  EXPECT_EQ(points[4].json[1], 6);
}

TEST(CampaignPoints, FromToIsInclusiveEvenOrLog) {
  auto points = MakePoints(Parse("[[axis]]\nkey = \"a\"\nfrom = 0.05\nto = 0.5\nsteps = 10\n"));
  ASSERT_EQ(points.size(), 10u);
  EXPECT_EQ(points[0].values[0], "0.05");
  EXPECT_EQ(points[9].values[0], "0.5");
  EXPECT_NEAR(points[1].json[0].get<double>(), 0.1, 1e-15);
  points = MakePoints(Parse("[[axis]]\nkey = \"a\"\nfrom = 1\nto = 1000\nsteps = 4\nlog = true\n"));
  EXPECT_EQ(points[0].values[0], "1.0");
  EXPECT_NEAR(points[1].json[0].get<double>(), 10, 1e-9);
  EXPECT_NEAR(points[2].json[0].get<double>(), 100, 1e-9);
  EXPECT_EQ(points[3].values[0], "1000.0");
}

TEST(CampaignPoints, NoAxesIsOnePoint) {
  const auto points = MakePoints(Parse(""));
  ASSERT_EQ(points.size(), 1u);
  EXPECT_TRUE(points[0].values.empty());
}

TEST(CampaignPoints, LatinHypercubeIsStratifiedAndSeeded) {
  const std::string body =
      "sampling = \"lhs\"\nsamples = 50\nseed = 7\n"
      "[[axis]]\nkey = \"a\"\nfrom = 0\nto = 1\n"
      "[[axis]]\nkey = \"b\"\nfrom = 1\nto = 100\nlog = true\n"
      "[[axis]]\nkey = \"c\"\nrange = [1, 5]\n";
  const auto points = MakePoints(Parse(body));
  ASSERT_EQ(points.size(), 50u);
  std::set<int> strata_a, strata_b;
  int count_c[6] = {0};
  for (const auto& p : points) {
    const double a = p.json[0].get<double>();
    const double b = p.json[1].get<double>();
    ASSERT_GE(a, 0);
    ASSERT_LT(a, 1);
    strata_a.insert(static_cast<int>(a * 50));
    strata_b.insert(static_cast<int>(std::log(b) / std::log(100.0) * 50));
    ++count_c[p.json[2].get<int>()];
  }
  EXPECT_EQ(strata_a.size(), 50u);  // one point in each of the 50 strata
  EXPECT_EQ(strata_b.size(), 50u);  // log-uniform: strata of log b
  for (int v = 1; v <= 5; ++v) EXPECT_EQ(count_c[v], 10) << v;  // stratified choice
  // The same seed draws the same points; another seed others.
  const auto again = MakePoints(Parse(body));
  for (std::size_t p = 0; p < points.size(); ++p) EXPECT_EQ(points[p].values, again[p].values);
  std::string other = body;
  other.replace(other.find("seed = 7"), 8, "seed = 8");
  EXPECT_NE(MakePoints(Parse(other))[0].values, points[0].values);
}

TEST(CampaignPoints, LatinHypercubeValuesPinned) {
  // Pinned draws: the sampler's output must not change between builds or platforms
  // (core/rng.h is explicit; no std:: distribution is used).
  const auto points = MakePoints(Parse("sampling = \"lhs\"\nsamples = 3\nseed = 1\n"
                                       "[[axis]]\nkey = \"a\"\nfrom = 0\nto = 3\n"));
  ASSERT_EQ(points.size(), 3u);
  std::string all;
  for (const auto& p : points) all += p.values[0] + " ";
  EXPECT_EQ(all, "1.7377477684936582 0.4618681494019702 2.944444044135132 ");
}

}  // namespace
}  // namespace shoal
