#include "campaign/results.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <sstream>

namespace shoal {
namespace {

using ojson = nlohmann::ordered_json;

Campaign TwoAxes() {
  return ParseCampaign("[campaign]\nscenario = \"s.toml\"\n"
                       "[[axis]]\nkey = \"d\"\nvalues = [0.1, 0.2, 0.3]\n"
                       "[[axis]]\nkey = \"k\"\nvalues = [1, 2]\n"
                       "[pass]\nconverged = true\n",
                       "c.toml");
}

/// Rows of TwoAxes where a point passes when d < limit(k).
Rows MakeRows(const Campaign& c, const std::vector<CampaignPoint>& points) {
  Rows rows;
  for (const CampaignPoint& p : points) {
    PointOutcome o;
    o.index = p.index;
    o.status = PointStatus::kOk;
    o.exit_status = 0;
    const double limit = p.json[1] == 1 ? 0.25 : 0.15;
    o.result = {{"converged", p.json[0].get<double>() < limit}, {"e", {{"m", 1.5}}}};
    rows[p.index] = MakeRow(c, p, o, "shoal sim s.toml");
  }
  return rows;
}

std::string TmpDir(const std::string& name) {
  const std::string dir = std::string(SHOAL_BINARY_DIR) + "/test_tmp/results_" + name;
  std::system(("rm -rf " + dir).c_str());
  return dir;
}

TEST(CampaignResults, ParsesShards) {
  Shard s;
  std::string error;
  EXPECT_TRUE(ParseShard("2/4", &s, &error));
  EXPECT_TRUE(s.Has(5));
  EXPECT_FALSE(s.Has(4));
  for (const char* bad : {"0/4", "5/4", "1/0", "a/b", "1/2x", ""}) {
    EXPECT_FALSE(ParseShard(bad, &s, &error)) << bad;
  }
  EXPECT_NE(error.find("must be K/N"), std::string::npos);
}

TEST(CampaignResults, RowHasTheDocumentedFieldsInOrder) {
  const Campaign c = TwoAxes();
  const auto points = MakePoints(c);
  const Rows rows = MakeRows(c, points);
  std::string keys;
  for (auto it = rows.at(4).begin(); it != rows.at(4).end(); ++it) keys += it.key() + " ";
  EXPECT_EQ(keys, "point d k status exit_status pass why wall_s cpu_s converged e.m command ");
  EXPECT_EQ(rows.at(4)["why"], "converged = false, not true");
  PointOutcome crash;
  crash.index = 1;
  crash.status = PointStatus::kCrashed;
  crash.signal = 11;
  crash.why = "crashed: killed by signal 11 (SIGSEGV)";
  const ojson row = MakeRow(c, points[1], crash, "x");
  EXPECT_TRUE(row["exit_status"].is_null());
  EXPECT_EQ(row["pass"], false);
  EXPECT_EQ(row["why"], crash.why);
}

TEST(CampaignResults, SummaryHasPassRatesAndBoundaries) {
  const Campaign c = TwoAxes();
  const auto points = MakePoints(c);
  const ojson manifest = MakeManifest(c, "text", {}, points, {}, ojson::object());
  const ojson s = Summarize(manifest, MakeRows(c, points));
  EXPECT_EQ(s["passed"], 3);
  EXPECT_EQ(s["failed"], 3);
  const ojson& d = s["axes"][0];
  EXPECT_EQ(d["values"][0]["pass_rate"], 1.0);
  EXPECT_EQ(d["values"][1]["pass_rate"], 0.5);
  ASSERT_EQ(d["boundary"].size(), 2u);
  EXPECT_EQ(d["boundary"][0].dump(), R"({"fixed":{"k":1},"last_pass":0.2,"first_fail":0.3})");
  EXPECT_EQ(d["boundary"][1].dump(), R"({"fixed":{"k":2},"last_pass":0.1,"first_fail":0.2})");
  const ojson& k = s["axes"][1];
  EXPECT_EQ(k["boundary"][2].dump(), R"({"fixed":{"d":0.3},"last_pass":null,"first_fail":1})");
  EXPECT_EQ(s["map"].dump(), R"({"x":"d","y":"k","x_log":false,"y_log":false})");
}

TEST(CampaignResults, CsvQuotesWhatNeedsIt) {
  Rows rows;
  rows[0] = {{"point", 0}, {"why", "a, \"b\""}, {"v", {{"model", "c"}}}};
  rows[1] = {{"point", 1}, {"extra", true}};
  EXPECT_EQ(RowsCsv(rows),
            "point,why,v,extra\n0,\"a, \"\"b\"\"\",\"{\"\"model\"\":\"\"c\"\"}\",\n1,,,true\n");
}

TEST(CampaignResults, ResumesOnlyTheSameCampaign) {
  const Campaign c = TwoAxes();
  const auto points = MakePoints(c);
  const Rows rows = MakeRows(c, points);
  const std::string dir = TmpDir("resume");
  const ojson manifest = MakeManifest(c, "text", {}, points, {}, ojson::object());
  {
    ResultsDir out(dir, manifest);
    EXPECT_TRUE(out.rows().empty());
    out.Append(rows.at(3));
    out.Append(rows.at(1));
  }
  // Damaged lines: not rows (their points run again), never a crash of resume or merge.
  std::ofstream(dir + "/results.jsonl", std::ios::app)
      << "{\"point\": 4}\n{\"point\": 5, \"pass\": 1, \"status\": \"ok\"}\n{\"point\": 2, \"torn";
  {
    ResultsDir again(dir, manifest);
    ASSERT_EQ(again.rows().size(), 2u);  // the damaged and torn lines are not rows
    EXPECT_EQ(again.rows().at(3), rows.at(3));
    again.Append(rows.at(0));
    again.Finish();
  }
  std::ifstream in(dir + "/results.jsonl");
  std::string first;
  std::getline(in, first);
  EXPECT_EQ(first, rows.at(0).dump());  // rewritten in point order
  EXPECT_THROW(ResultsDir(dir, MakeManifest(c, "other text", {}, points, {}, ojson::object())),
               CampaignError);
  EXPECT_THROW(ResultsDir(dir, MakeManifest(c, "text", {}, points, {1, 2}, ojson::object())),
               CampaignError);
  EXPECT_THROW(ResultsDir(dir, MakeManifest(c, "text", {"control.k1=1"}, points, {}, ojson::object())),
               CampaignError);
}

TEST(CampaignResults, MergeRebuildsOneRunAndNamesMissingPoints) {
  const Campaign c = TwoAxes();
  const auto points = MakePoints(c);
  const Rows rows = MakeRows(c, points);
  const ojson manifest = MakeManifest(c, "text", {}, points, {}, ojson::object());
  const std::string whole = TmpDir("whole");
  WriteResults((std::system(("mkdir -p " + whole).c_str()), whole), manifest, rows);
  std::vector<std::string> dirs;
  for (int k = 1; k <= 2; ++k) {
    dirs.push_back(TmpDir("shard" + std::to_string(k)));
    ResultsDir shard(dirs.back(), MakeManifest(c, "text", {}, points, {k, 2}, ojson::object()));
    for (const auto& [p, row] : rows) {
      if (p % 2 == k - 1) shard.Append(row);
    }
  }
  const std::string merged = TmpDir("merged");
  EXPECT_THROW(MergeResults({dirs[1], dirs[0]}, dirs[0], false, false), CampaignError);
  EXPECT_EQ(MergeResults({dirs[1], dirs[0]}, merged, false, false), rows);
  for (const char* file : {"/results.jsonl", "/results.csv", "/summary.json"}) {
    std::ifstream a(whole + file), b(merged + file);
    std::stringstream ta, tb;
    ta << a.rdbuf();
    tb << b.rdbuf();
    EXPECT_EQ(ta.str(), tb.str()) << file;
  }
  try {
    MergeResults({dirs[0]}, TmpDir("m1"), false, false);
    ADD_FAILURE();
  } catch (const CampaignError& e) {
    EXPECT_NE(std::string(e.what()).find("missing from every directory: 1, 3, 5"),
              std::string::npos) << e.what();
  }
  EXPECT_EQ(MergeResults({dirs[0]}, TmpDir("m2"), true, false).size(), 3u);
  EXPECT_THROW(MergeResults({dirs[0], dirs[0], dirs[1]}, TmpDir("m3"), false, false),
               CampaignError);
}

}  // namespace
}  // namespace shoal
