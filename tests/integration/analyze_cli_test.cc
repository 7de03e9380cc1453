// `shoal analyze` as a user runs it: agreement with shoal sim's own figures, the JSON keys
// of shoal run, CSV files, damaged logs and bad input.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "tests/integration/test_util.h"

namespace shoal {
namespace {

using shoal::testing::ReadFile;
using shoal::testing::JsonNumber;
using shoal::testing::JsonRaw;
using shoal::testing::RunShoal;
using shoal::testing::SourcePath;
using shoal::testing::TmpPath;

const std::string kExample2 = SourcePath("scenarios/paper_example2.toml");

// One shoal sim log of Example 2 (60 s: converges at 52.54 s) shared by the tests.
const std::string& SimLog() {
  static const std::string log = [] {
    // Per process: CTest runs each test of this file as its own process, in parallel.
    const std::string id = std::to_string(getpid());
    const std::string p = TmpPath("analyze_cli_ex2_" + id + ".lcmlog");
    RunShoal("sim " + kExample2 + " --duration 60 --quiet --out " + p, "analyze_cli_sim_" + id);
    return p;
  }();
  return log;
}

TEST(AnalyzeCli, AgreesWithShoalSimOnEveryFigureItPrints) {
  const auto sim = RunShoal("sim " + kExample2 + " --duration 60 --json", "analyze_cli_simj");
  ASSERT_EQ(sim.status, 0) << sim.err;
  const auto ana = RunShoal("analyze " + SimLog() + " --json", "analyze_cli_ana");
  ASSERT_EQ(ana.status, 0) << ana.err;
  for (const char* key : {"scenario", "converged", "convergence_time_s", "final_position_error_m",
                          "final_velocity_error_mps", "final_attitude_error_rad",
                          "max_position_error_m", "sim_time_s", "ticks", "channel_delivered",
                          "channel_dropped", "interrupted", "diverged_follower"}) {
    EXPECT_EQ(JsonRaw(ana.out, key), JsonRaw(sim.out, key)) << key;
  }
  EXPECT_EQ(JsonRaw(ana.out, "convergence_time_s"), "52.54");
  // Per follower: shoal sim's objects, key for key and digit for digit, start analyze's.
  const std::regex follower(R"(\{"id":[0-9]+,[^{}]*\})");
  int n = 0;
  for (std::sregex_iterator it(sim.out.begin(), sim.out.end(), follower), end; it != end; ++it) {
    std::string obj = it->str();
    obj.pop_back();  // the closing brace: analyze adds keys after these
    EXPECT_NE(ana.out.find(obj + ","), std::string::npos) << obj;
    ++n;
  }
  EXPECT_EQ(n, 5);
  EXPECT_EQ(JsonRaw(ana.out, "mode"), "\"sim\"");
  EXPECT_EQ(JsonRaw(ana.out, "scenario_source"), "\"log\"");
  EXPECT_EQ(JsonRaw(ana.out, "log_states"), std::to_string(6 * 3001));
  EXPECT_EQ(JsonRaw(ana.out, "log_states_expected"), std::to_string(6 * 3001));
  EXPECT_EQ(JsonRaw(ana.out, "damaged"), "false");
}

TEST(AnalyzeCli, JsonHasEveryKeyOfShoalRun) {
  const auto ana = RunShoal("analyze " + SimLog() + " --json", "analyze_cli_keys");
  ASSERT_EQ(ana.status, 0) << ana.err;
  // The keys of `shoal run --json` (tools/run_command.cc, docs/run.md).
  for (const char* key : {"scenario", "mode", "converged", "convergence_time_s",
                          "final_position_error_m", "final_velocity_error_mps",
                          "final_attitude_error_rad", "sim_time_s", "wall_time_s",
                          "realtime_factor", "channel", "loop", "all_processes_ok", "problems",
                          "interrupted", "log", "log_states", "log_states_expected", "lcm_url"}) {
    EXPECT_NE(JsonRaw(ana.out, key), "<missing>") << key;
  }
  const auto ch = ana.out.find("\"channel\":{");
  ASSERT_NE(ch, std::string::npos);
  for (const char* key : {"delivered", "dropped", "delay_error_p99_s"}) {
    EXPECT_NE(ana.out.find("\"" + std::string(key) + "\":", ch), std::string::npos) << key;
  }
  const auto loop = ana.out.find("\"loop\":{");
  ASSERT_NE(loop, std::string::npos);
  for (const char* key : {"lateness_p99_s", "overruns"}) {
    EXPECT_NE(ana.out.find("\"" + std::string(key) + "\":", loop), std::string::npos) << key;
  }
  // A shoal sim log: the channel's tick quantisation is below one period, never negative
  // beyond the microsecond rounding of tau.
  const double p99 = std::atof(JsonRaw(ana.out, "realised_delay_error_p99_s").c_str());
  EXPECT_GT(p99, 0.0);
  EXPECT_LT(p99, 0.02);
  EXPECT_GE(std::atof(JsonRaw(ana.out, "realised_delay_error_min_s").c_str()), -0.5e-6);
}

bool IsNumber(const std::string& s) {
  if (s == "NaN") return true;
  char* end = nullptr;
  std::strtod(s.c_str(), &end);
  return !s.empty() && end == s.c_str() + s.size();
}

TEST(AnalyzeCli, CsvFilesAreTidyAndComplete) {
  const std::string dir = TmpPath("analyze_cli_csv");
  std::system(("rm -rf " + dir).c_str());
  const auto r = RunShoal("analyze " + SimLog() + " --csv " + dir, "analyze_cli_csv");
  ASSERT_EQ(r.status, 0) << r.err;
  for (int id = 0; id <= 5; ++id) {
    std::ifstream in(dir + "/vehicle_" + std::to_string(id) + ".csv");
    ASSERT_TRUE(in.good()) << id;
    std::string line;
    std::getline(in, line);
    EXPECT_EQ(line.rfind("time_s,utime_us,seq,x_m,y_m,z_m,", 0), 0u) << line;
    const std::size_t columns = std::count(line.begin(), line.end(), ',') + 1;
    EXPECT_EQ(columns, id == 0 ? 30u : 36u);
    int rows = 0;
    while (std::getline(in, line)) {
      ++rows;
      std::stringstream ss(line);
      std::string cell;
      std::size_t n = 0;
      while (std::getline(ss, cell, ',')) {
        ++n;
        ASSERT_TRUE(IsNumber(cell)) << "vehicle " << id << " row " << rows << ": '" << cell << "'";
      }
      ASSERT_EQ(n, columns);
    }
    EXPECT_EQ(rows, 3001) << id;
  }
  std::ifstream ch(dir + "/channel_events.csv");
  std::string header;
  std::getline(ch, header);
  EXPECT_EQ(header.rfind("send_time_s,send_utime_us,sender,receiver,", 0), 0u) << header;
  int events = 0;
  for (std::string line; std::getline(ch, line);) ++events;
  EXPECT_EQ(events, 3001 * 10);  // 10 links in Example 2, every message delivered
  EXPECT_TRUE(std::ifstream(dir + "/health.csv").good());
}

TEST(AnalyzeCli, TruncatedLogIsAnalysedUpToTheDamageWithAWarning) {
  const std::string bytes = ReadFile(SimLog());
  const std::string cut = TmpPath("analyze_cli_cut.lcmlog");
  std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() / 2 + 77);
  const auto r = RunShoal("analyze " + cut + " --json", "analyze_cli_cut");
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("warning"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("truncated"), std::string::npos) << r.err;
  EXPECT_EQ(JsonRaw(r.out, "damaged"), "true");
  const double t = std::atof(JsonRaw(r.out, "sim_time_s").c_str());
  EXPECT_GT(t, 20.0);
  EXPECT_LT(t, 40.0);
}

TEST(AnalyzeCli, BadInputExitsTwoWithAMessage) {
  struct Case {
    std::string args, expect;
  };
  const std::string empty = TmpPath("analyze_cli_empty.lcmlog");
  std::ofstream(empty).close();
  const std::string file = TmpPath("analyze_cli_file");
  std::ofstream(file) << "x";
  const std::vector<Case> cases = {
      {"", "give a LOG"},
      {"/nonexistent/run.lcmlog", "cannot read"},
      {empty, "empty"},
      {kExample2, "not an LCM log"},
      {TmpPath(""), "not a regular file"},
      {SimLog() + " --live", "not both"},
      {SimLog() + " --duration 3", "--live"},
      {"--live --duration -1", "--duration"},
      {SimLog() + " --csv " + file, "not a directory"},
      {SimLog() + " --scenario /nonexistent/s.toml", "cannot read scenario file"},
      {SimLog() + " --bogus", ""},
  };
  for (const Case& c : cases) {
    const auto r = RunShoal("analyze " + c.args, "analyze_cli_bad");
    EXPECT_EQ(r.status, 2) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.expect), std::string::npos) << c.args << "\n" << r.err;
    EXPECT_TRUE(r.out.empty()) << c.args << "\n" << r.out;
  }
  EXPECT_EQ(RunShoal("analyze --help", "analyze_cli_help").status, 0);
}

TEST(AnalyzeCli, ScenarioFileReplacesTheLogs) {
  const auto r = RunShoal("analyze " + SimLog() + " --json --scenario " +
                              SourcePath("scenarios/paper_example1.toml"), "analyze_cli_scn");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(JsonRaw(r.out, "scenario_source"), "\"file\"");
  EXPECT_EQ(JsonRaw(r.out, "scenario"), "\"paper_example1\"");
  // Example 1 has no delay: every event of the Example 2 log drew another tau.
  EXPECT_EQ(JsonRaw(r.out, "model_mismatches"), std::to_string(3001 * 10));
}

}  // namespace
}  // namespace shoal
