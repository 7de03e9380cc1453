// Every number shoal analyze --json writes reads back as the same double, bit for bit:
// the JSON text (tools/json_text.h, nlohmann's shortest round-trip form) keeps doubles
// such as 0.1 + 0.2 and 1/3 that a fixed number of digits would change.
#include <gtest/gtest.h>

#include <cstring>

#include "analysis/analysis.h"
#include "analysis/analysis_json.h"
#include "analysis/run_data.h"
#include "tools/json_text.h"

namespace shoal {
namespace {

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// The leader's path of a run whose leader starts at (0.1 + 0.2, 1/3, 2/3) and moves by
// 1e-17-scale steps: start, end and path length go through AnalysisJson and JsonText.
TEST(JsonPrecision, AnalyzeJsonRoundTripsDoublesExactly) {
  const double x0 = 0.1 + 0.2, y0 = 1.0 / 3.0, z0 = 2.0 / 3.0;
  ASSERT_NE(x0, 0.3);  // 0.30000000000000004: %.15g or %.16g would write 0.3
  RunData run;
  run.followers = 0;
  run.vehicles.resize(1);
  for (int k = 0; k < 10; ++k) {
    StateMsg m;
    m.utime = k * 20000;
    m.eta << x0 + k * (1.0 / 7.0), y0, z0 + k * 1e-3, 0.0, 1.0 / 9.0;
    run.vehicles[0].samples.push_back(m);
    ++run.vehicles[0].received;
  }
  const RunAnalysis a = AnalyseRun(run);
  AnalysisSource src;
  src.log = "x.lcmlog";
  const nlohmann::json back = nlohmann::json::parse(JsonText(AnalysisJson(run, a, src)));
  const auto& start = back["leader"]["start_m"];
  ASSERT_TRUE(start.is_array()) << back["leader"];
  EXPECT_TRUE(SameBits(start[0].get<double>(), x0));
  EXPECT_TRUE(SameBits(start[1].get<double>(), y0));
  EXPECT_TRUE(SameBits(start[2].get<double>(), z0));
  const auto& end = back["leader"]["end_m"];
  EXPECT_TRUE(SameBits(end[0].get<double>(), run.vehicles[0].samples.back().eta(0)));
  EXPECT_TRUE(SameBits(end[2].get<double>(), run.vehicles[0].samples.back().eta(2)));
  EXPECT_TRUE(SameBits(back["leader"]["path_length_m"].get<double>(), a.leader_path_length_m));
  EXPECT_TRUE(SameBits(back["sim_time_s"].get<double>(), a.summary.sim_time_s));
}

// The text form itself: 17 significant digits where needed, the shortest otherwise.
TEST(JsonPrecision, JsonTextWritesTheShortestExactForm) {
  nlohmann::ordered_json j;
  j["a"] = 0.1 + 0.2;
  j["b"] = 1.0 / 3.0;
  j["c"] = 0.5;
  EXPECT_EQ(JsonText(j), R"({"a":0.30000000000000004,"b":0.3333333333333333,"c":0.5})");
  const auto back = nlohmann::json::parse(JsonText(j));
  EXPECT_TRUE(SameBits(back["a"].get<double>(), 0.1 + 0.2));
  EXPECT_TRUE(SameBits(back["b"].get<double>(), 1.0 / 3.0));
}

}  // namespace
}  // namespace shoal
