// `shoal analyze` as a user runs it: agreement with shoal sim's own figures, the JSON keys
// of shoal run, CSV files, damaged logs and bad input.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "runtime/channels.h"
#include "runtime/log_reader.h"
#include "runtime/log_writer.h"
#include "runtime/messages.h"
#include "tests/integration/test_util.h"

namespace shoal {
namespace {

using shoal::testing::ReadFile;
using shoal::testing::ParseJson;
using shoal::testing::RunShoal;
using shoal::testing::SourcePath;
using shoal::testing::TmpPath;
using Json = nlohmann::ordered_json;

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
  const auto sj = ParseJson(sim.out), aj = ParseJson(ana.out);
  for (const char* key : {"scenario", "converged", "convergence_time_s", "final_position_error_m",
                          "final_velocity_error_mps", "final_attitude_error_rad",
                          "max_position_error_m", "sim_time_s", "ticks", "channel_delivered",
                          "channel_dropped", "interrupted", "diverged_follower"}) {
    ASSERT_TRUE(sj.contains(key)) << key;
    EXPECT_EQ(aj[key], sj[key]) << key;  // numbers to the last bit
  }
  EXPECT_NEAR(aj["convergence_time_s"].get<double>(), 52.54, 1e-9);
  // Per follower: shoal sim's keys, value for value to the last bit, in the same order,
  // start analyze's objects.
  ASSERT_EQ(sj["followers"].size(), 5u) << sim.out;
  ASSERT_EQ(aj["followers"].size(), 5u) << ana.out;
  for (std::size_t i = 0; i < 5; ++i) {
    const auto& sf = sj["followers"][i];
    const auto& af = aj["followers"][i];
    ASSERT_EQ(sf.size(), 7u) << sf;
    auto ai = af.items().begin();
    for (const auto& [key, value] : sf.items()) {
      ASSERT_NE(ai, af.items().end()) << af;
      EXPECT_EQ(ai.key(), key) << af;
      EXPECT_EQ(ai.value(), value) << key << " of follower " << sf["id"];
      ++ai;
    }
  }
  EXPECT_EQ(aj["mode"], "sim");
  EXPECT_EQ(aj["scenario_source"], "log");
  EXPECT_EQ(aj["log_states"], 6 * 3001);
  EXPECT_EQ(aj["log_states_expected"], 6 * 3001);
  EXPECT_EQ(aj["damaged"], false);
}

TEST(AnalyzeCli, JsonHasEveryKeyOfShoalRun) {
  const auto ana = RunShoal("analyze " + SimLog() + " --json", "analyze_cli_keys");
  ASSERT_EQ(ana.status, 0) << ana.err;
  const auto j = ParseJson(ana.out);
  // The keys of `shoal run --json` (launcher/run_report.cc, docs/run.md), but the launcher's
  // own (process_output_dir, cpu_latency_request).
  for (const char* key : {"scenario", "mode", "converged", "convergence_time_s",
                          "final_position_error_m", "final_velocity_error_mps",
                          "final_attitude_error_rad", "sim_time_s", "wall_time_s",
                          "realtime_factor", "diverged_follower", "channel", "loop",
                          "all_processes_ok", "problems", "interrupted", "log", "log_states",
                          "log_states_expected", "lcm_url"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  for (const char* key : {"delivered", "dropped", "delay_error_p99_s"}) {
    EXPECT_TRUE(j["channel"][key].is_number()) << key;
  }
  for (const char* key : {"lateness_p99_s", "overruns"}) {
    EXPECT_TRUE(j["loop"][key].is_number()) << key;
  }
  // A shoal sim log: the channel's tick quantisation is below one period, never negative
  // beyond the microsecond rounding of tau.
  const double p99 = j["channel"]["realised_delay_error_p99_s"].get<double>();
  EXPECT_GT(p99, 0.0);
  EXPECT_LT(p99, 0.02);
  EXPECT_GE(j["channel"]["realised_delay_error_min_s"].get<double>(), -0.5e-6);
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
  const auto j = ParseJson(r.out);
  EXPECT_EQ(j["damaged"], true);
  const double t = j["sim_time_s"].get<double>();
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
  const auto j = ParseJson(r.out);
  EXPECT_EQ(j["scenario_source"], "file");
  EXPECT_EQ(j["scenario"], "paper_example1");
  // Example 1 has no delay: every event of the Example 2 log drew another tau. Under it, the
  // 20 deliveries the run's last 0.15 s of states make after its final tick (60 s) are
  // impossible (at most a period after it): left out as damaged, and the rest mismatch.
  EXPECT_EQ(j["channel_events_delivered_at_impossible_time"], 20);
  EXPECT_EQ(j["channel"]["model_mismatches"], 3001 * 10 - 20);
}

// A log without the scenario's text (its statuses lost) and no --scenario: the formation
// is unknown, null rather than "not converged", and the warning is in the JSON too.
// A scenario of fewer followers than the log: the others' states are ignored, and said so.
TEST(AnalyzeCli, WhatTheAnalysisCannotJudgeOrIgnoresIsSaid) {
  const std::string bare = TmpPath("analyze_cli_no_status.lcmlog");
  {
    LcmLogReader in;
    std::string err;
    ASSERT_TRUE(in.Open(SimLog(), &err)) << err;
    LogWriter out(bare);
    LogEventView ev;
    while (in.Next(&ev)) {
      if (ev.channel != channels::Status()) {
        out.WriteRaw(std::string(ev.channel), ev.timestamp, ev.data, ev.size);
      }
    }
    out.Close();
  }
  auto r = RunShoal("analyze " + bare + " --json", "analyze_cli_bare");
  ASSERT_EQ(r.status, 0) << r.err;
  auto j = ParseJson(r.out);
  EXPECT_TRUE(j["converged"].is_null()) << j["converged"];
  EXPECT_TRUE(j["convergence_time_s"].is_null());
  ASSERT_FALSE(j["followers"].empty());
  EXPECT_TRUE(j["followers"][0]["converged"].is_null());
  EXPECT_NE(j["warnings"].dump().find("no scenario text"), std::string::npos) << j["warnings"];
  r = RunShoal("analyze " + SimLog() + " --json --scenario " +
                   SourcePath("scenarios/acoustic_survey.toml"), "analyze_cli_fewer");
  ASSERT_EQ(r.status, 0) << r.err;
  j = ParseJson(r.out);
  // Vehicle 5's states, beyond the scenario's 4 followers, and the channel's decisions on
  // its links.
  const std::int64_t rejected = j["log_rejected"].get<std::int64_t>();
  EXPECT_GT(rejected, 3001);
  EXPECT_EQ(j["log_undecodable"], 0);
  const std::string said = std::to_string(rejected) + " messages were inconsistent";
  EXPECT_NE(j["warnings"].dump().find(said), std::string::npos) << j["warnings"];
  EXPECT_NE(r.err.find(said), std::string::npos) << r.err;
}

// Two different runs' logs joined into one cannot be told apart state by state: the
// analysis says so, naming the scenario texts that differ, and so does shoal_log.py.
TEST(AnalyzeCli, TwoRunsJoinedIntoOneLogAreNamed) {
  const std::string a = TmpPath("joined_a.lcmlog"), b = TmpPath("joined_b.lcmlog");
  const std::string joined = TmpPath("joined.lcmlog");
  RunShoal("sim " + SourcePath("scenarios/paper_example2.toml") + " --duration 4 --quiet --out " + a,
           "joined_a");
  RunShoal("sim " + SourcePath("scenarios/paper_example1.toml") + " --duration 4 --quiet --out " + b,
           "joined_b");
  ASSERT_EQ(std::system(("cat '" + a + "' '" + b + "' > '" + joined + "'").c_str()), 0);
  const char* said = "2 runs' scenario texts differ in this log";
  const auto r = RunShoal("analyze " + joined + " --json", "joined_ana");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(ParseJson(r.out)["warnings"].dump().find(said), std::string::npos) << r.out;
  const auto one = RunShoal("analyze " + a + " --json", "joined_one");
  EXPECT_EQ(ParseJson(one.out)["warnings"].dump().find("scenario texts differ"), std::string::npos)
      << one.out;
  const std::string py_err = TmpPath("joined_py.err");
  EXPECT_EQ(std::system(("python3 '" + SourcePath("python/shoal_log.py") + "' '" + joined +
                         "' >/dev/null 2>'" + py_err + "'").c_str()), 0);
  EXPECT_NE(ReadFile(py_err).find(said), std::string::npos) << ReadFile(py_err);
}

// A log recorded twice (here: concatenated with itself) holds every state twice: the run
// still recorded each state once, so the count is the run's, never 200 %, and a warning
// says why.
TEST(AnalyzeCli, ALogConcatenatedWithItselfCountsEachStateOnce) {
  const std::string one = TmpPath("twice_one.lcmlog"), two = TmpPath("twice_two.lcmlog");
  ASSERT_EQ(RunShoal("sim " + SourcePath("scenarios/paper_example2.toml") + " --duration 20 --out " +
                         one, "twice_sim").status, 1);  // not converged in 20 s
  ASSERT_EQ(std::system(("cat '" + one + "' '" + one + "' > '" + two + "'").c_str()), 0);
  const auto r = RunShoal("analyze " + two + " --json", "twice_ana");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = ParseJson(r.out);
  EXPECT_EQ(j["log_states"], 6 * 1001) << r.out;
  EXPECT_EQ(j["log_states_expected"], 6 * 1001) << r.out;
  EXPECT_NE(r.err.find("6006 vehicle states appear more than once"), std::string::npos) << r.err;
  // The channel's decisions and the health reports too, each once.
  const auto once = RunShoal("analyze " + one + " --json", "twice_once");
  ASSERT_EQ(once.status, 0) << once.err;
  const auto k = ParseJson(once.out);
  EXPECT_EQ(j["channel"], k["channel"]);
  EXPECT_EQ(j["loop"], k["loop"]);
  EXPECT_NE(r.err.find("10010 channel decisions and 105 health reports appear more than once"),
            std::string::npos)
      << r.err;
}

// A 20 s Example 2 log (of a 600 s scenario) followed by four states at impossible times,
// far from any slot: follower 3 at utime = INT64_MAX, the leader at -1 s, follower 2 at
// 1e9 s, follower 4 at 274.4 s (after the run's final tick, within the scenario's); and four
// channel events at impossible times. Returns the damaged log; *clean is the log as shoal
// sim wrote it.
std::string DamagedTimesLog(const std::string& tag, std::string* clean) {
  *clean = TmpPath(tag + "_clean.lcmlog");
  const std::string forged = TmpPath(tag + "_forged.lcmlog"), damaged = TmpPath(tag + ".lcmlog");
  EXPECT_EQ(RunShoal("sim " + kExample2 + " --duration 20 --quiet --out " + *clean, tag + "_sim")
                .status, 1);  // not converged in 20 s
  {
    LogWriter log(forged);
    const std::pair<int, std::int64_t> bad[] = {
        {3, std::numeric_limits<std::int64_t>::max()}, {0, -1000000}, {2, 1000000000000000},
        {4, 274435456}};
    for (const auto& [id, utime] : bad) {
      StateMsg m;
      m.vehicle_id = id;
      m.utime = utime;
      m.eta = Vec5::Constant(1e6);
      m.eta_dot = m.nu = Vec5::Constant(1e3);
      log.Write(channels::State(id), 20000000, ToLcm(m));
    }
    // Channel events on link 1 -> 2 sent at 1e9 s and at -1 s, delivered 1e9 s after
    // sending (the last possible delivery is 600 s + 0.15 s + a period), and delivered
    // before sending.
    const std::pair<std::int64_t, std::int64_t> times[] = {{1000000000000000, 1000000000100000},
                                                           {-1000000, 0},
                                                           {10000000, 1000000010000000},
                                                           {12000000, 11000000}};
    std::int32_t seq = 0;
    for (const auto& [send, deliver] : times) {
      ChannelDecision d;
      d.sender = 1;
      d.receiver = 2;
      d.send_utime = send;
      d.deliver_utime = deliver;
      d.delay_s = 0.1;
      log.Write(channels::ChannelEvents(), 20000000, ToLcm(d, seq++));
    }
  }
  EXPECT_EQ(std::system(("cat '" + *clean + "' '" + forged + "' > '" + damaged + "'").c_str()), 0);
  return damaged;
}

// Taken as the run's end, one state at utime = INT64_MAX would make the expectation 2.8e15
// states: the scenario in the log (duration, period) and the run's final clock tick give
// it, and the states at impossible times are counted as damaged, left out of every metric.
TEST(AnalyzeCli, StatesAtImpossibleTimesAreDamagedNotTheRunsLength) {
  std::string clean;
  const std::string damaged = DamagedTimesLog("impossible_times", &clean);
  const auto r = RunShoal("analyze " + damaged + " --json", "impossible_ana");
  const auto c = RunShoal("analyze " + clean + " --json", "impossible_clean");
  ASSERT_EQ(r.status, 0) << r.err;
  ASSERT_EQ(c.status, 0) << c.err;
  const auto j = ParseJson(r.out), cj = ParseJson(c.out);
  EXPECT_EQ(j["log_states_expected"], 6 * 1001) << r.out;
  EXPECT_EQ(j["log_states"], 6 * 1001);
  EXPECT_EQ(j["log_states_damaged"], 4);
  EXPECT_EQ(j["log_states_negative_time"], 1);
  EXPECT_EQ(j["log_states_after_end"], 3);
  EXPECT_EQ(j["log_end_s"], 20.0);  // the run's final clock tick, not the scenario's 600 s
  EXPECT_EQ(cj["log_states_damaged"], 0);
  for (const char* key : {"sim_time_s", "ticks", "final_position_error_m", "max_position_error_m",
                          "converged", "followers", "leader", "complete_samples"}) {
    EXPECT_EQ(j[key], cj[key]) << key;
  }
  const auto t = RunShoal("analyze " + damaged, "impossible_text");
  EXPECT_NE(t.out.find("of 6006 expected"), std::string::npos) << t.out;
  EXPECT_NE(t.out.find("DAMAGED: 4 vehicle states at impossible times (1 negative, 3 after"),
            std::string::npos) << t.out;
  // shoal compare holds the forged states against the clean log: in A only, so the logs
  // differ (exit 1) and agree on everything else.
  const auto cmp = RunShoal("compare " + damaged + " " + clean + " --json", "impossible_cmp");
  EXPECT_EQ(cmp.status, 1) << cmp.err;
  EXPECT_EQ(ParseJson(cmp.out)["only_in_a"], 4) << cmp.out;
  EXPECT_EQ(ParseJson(cmp.out)["max_position_diff_m"], 0.0) << cmp.out;
  EXPECT_EQ(RunShoal("compare " + damaged + " " + clean + " --allow-missing", "impossible_cmp2")
                .status, 0);
}


// Rows of a CSV file (without its header).
std::vector<std::string> CsvRows(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> rows;
  std::string line;
  std::getline(in, line);
  while (std::getline(in, line)) rows.push_back(line);
  return rows;
}

// Taken as the log holds them, a delivery 1e9 s after sending would be the realised
// delay's maximum and one before sending a negative delay: channel events at impossible
// times are counted as damaged, every channel figure is the clean log's, and the CSV files
// hold the run's rows only.
TEST(AnalyzeCli, ChannelEventsAtImpossibleTimesAreDamagedNotMeasured) {
  std::string clean;
  const std::string damaged = DamagedTimesLog("impossible_events", &clean);
  const auto r = RunShoal("analyze " + damaged + " --json", "impossible_ev_ana");
  const auto c = RunShoal("analyze " + clean + " --json", "impossible_ev_clean");
  ASSERT_EQ(r.status, 0) << r.err;
  ASSERT_EQ(c.status, 0) << c.err;
  const auto j = ParseJson(r.out), cj = ParseJson(c.out);
  EXPECT_EQ(j["channel_events_damaged"], 4) << r.out;
  EXPECT_EQ(j["channel_events_sent_at_impossible_time"], 2);
  EXPECT_EQ(j["channel_events_delivered_at_impossible_time"], 2);
  // The run's final tick at 20 s (of Example 2's 600 s declared), tau at most 0.1 + 0.05 s
  // (0.15000000000000002 in doubles, rounded up to 150001 us; + 1 us for the rounding of
  // tau), 50 Hz.
  EXPECT_NEAR(j["log_last_delivery_s"].get<double>(), 20.170002, 1e-9);
  EXPECT_EQ(cj["channel_events_damaged"], 0) << c.out;  // a real run's sinusoidal delays
  for (const char* key : {"channel", "channel_delivered", "channel_dropped"}) {
    EXPECT_EQ(j[key], cj[key]) << key;
  }
  const auto t = RunShoal("analyze " + damaged, "impossible_ev_text");
  EXPECT_NE(t.out.find("DAMAGED: 4 channel events at impossible times (2 sent at a negative "
                       "time or after 20.00 s, 2 delivered before sent or after 20.17 s)"),
            std::string::npos) << t.out;
  const std::string dir_d = TmpPath("impossible_ev_csv"), dir_c = TmpPath("impossible_ev_csv_c");
  std::system(("rm -rf " + dir_d + " " + dir_c).c_str());
  ASSERT_EQ(RunShoal("analyze " + damaged + " --csv " + dir_d, "impossible_ev_csv").status, 0);
  ASSERT_EQ(RunShoal("analyze " + clean + " --csv " + dir_c, "impossible_ev_csv_c").status, 0);
  for (const std::string f : {"vehicle_0", "vehicle_2", "vehicle_3", "channel_events"}) {
    const auto d = CsvRows(dir_d + "/" + f + ".csv"), cl = CsvRows(dir_c + "/" + f + ".csv");
    EXPECT_FALSE(cl.empty()) << f;
    EXPECT_TRUE(d == cl) << f << ": " << d.size() << " rows, clean " << cl.size();
  }
}

/// A copy of `in` with each event passed through `edit` (its channel, stamp and bytes,
/// which it may change), kept when it returns true.
template <typename Edit>
void Rewrite(const std::string& in, const std::string& out, Edit edit) {
  LcmLogReader r;
  std::string err;
  ASSERT_TRUE(r.Open(in, &err)) << err;
  LogWriter w(out);
  LogEventView ev;
  while (r.Next(&ev)) {
    std::string channel(ev.channel);
    std::int64_t stamp = ev.timestamp;
    std::string data(reinterpret_cast<const char*>(ev.data), static_cast<std::size_t>(ev.size));
    if (edit(channel, &stamp, &data)) {
      w.WriteRaw(channel, stamp, data.data(), static_cast<int>(data.size()));
    }
  }
  w.Close();
}

/// python/shoal_log.py LOG --json, parsed (and its exit status).
std::pair<int, Json> PythonSummary(const std::string& log, const std::string& tag) {
  const std::string out = TmpPath(tag + "_py.json"), err = TmpPath(tag + "_py.err");
  const int raw = std::system(("python3 '" + SourcePath("python/shoal_log.py") + "' '" + log +
                               "' --json >'" + out + "' 2>'" + err + "'").c_str());
  const int status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  return {status, status == 0 ? ParseJson(ReadFile(out)) : Json(ReadFile(err))};
}

// Every state of follower 3 damaged (no bytes): no tick has every vehicle's state, so the
// swarm's errors are unknown, not 0, and the run's length is its states', not 0 s.
// shoal_log.py, given every state of one vehicle at an impossible time, says that vehicle
// has none instead of failing.
TEST(AnalyzeCli, NoTickWithEveryVehiclesStateLeavesTheErrorsUnknown) {
  const std::string src = TmpPath("no_tick_src.lcmlog"), log = TmpPath("no_tick.lcmlog");
  ASSERT_EQ(RunShoal("sim " + kExample2 + " --duration 20 --quiet --out " + src, "no_tick_sim")
                .status, 1);  // not converged in 20 s
  Rewrite(src, log, [](const std::string& ch, std::int64_t*, std::string* data) {
    if (ch == channels::State(3)) data->clear();
    return true;
  });
  const auto r = RunShoal("analyze " + log + " --json", "no_tick_ana");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = ParseJson(r.out);
  for (const char* key : {"final_position_error_m", "max_position_error_m", "converged"}) {
    EXPECT_TRUE(j[key].is_null()) << key << ": " << j[key];
  }
  EXPECT_DOUBLE_EQ(j["sim_time_s"].get<double>(), 20.0) << r.out;
  EXPECT_EQ(j["log_undecodable"], 1001) << r.out;
  const auto t = RunShoal("analyze " + log, "no_tick_text");
  EXPECT_NE(t.out.find("swarm errors: unknown (no tick has a valid state of every vehicle"),
            std::string::npos) << t.out;
  EXPECT_EQ(t.out.find("final errors"), std::string::npos) << t.out;
  // Each follower's own errors, against the leader, stand: follower 1's are a number.
  ASSERT_GE(j["followers"].size(), 1u) << r.out;
  EXPECT_TRUE(j["followers"][0]["max_position_error_m"].is_number()) << j["followers"][0];
  EXPECT_TRUE(j["followers"][0]["converged"].is_boolean()) << j["followers"][0];

  const std::string negative = TmpPath("no_tick_negative.lcmlog");
  Rewrite(src, negative, [](const std::string& ch, std::int64_t*, std::string* data) {
    vehicle_state_t v;
    if (ch == channels::State(3) &&
        v.decode(data->data(), 0, static_cast<int>(data->size())) > 0) {
      v.utime = -1 - v.utime;
      data->assign(static_cast<std::size_t>(v.getEncodedSize()), '\0');
      v.encode(data->data(), 0, static_cast<int>(data->size()));
    }
    return true;
  });
  const std::string text = TmpPath("no_tick_negative_py.txt");
  EXPECT_EQ(std::system(("python3 '" + SourcePath("python/shoal_log.py") + "' '" + negative +
                         "' >'" + text + "' 2>&1").c_str()), 0) << ReadFile(text);
  EXPECT_NE(ReadFile(text).find("vehicle 3: 0 states, no state"), std::string::npos)
      << ReadFile(text);
}

// The scenario text in the log damaged (its follower count changed to 3, which its edges
// and offsets contradict): it does not load. Said once, as such, not also as missing; and
// shoal_log.py reads it as shoal analyze does, with the statuses' 5 followers.
TEST(AnalyzeCli, ADamagedScenarioTextIsSaidNotToLoadAndReadAsAnalyzeReadsIt) {
  const std::string src = TmpPath("scen_damaged_src.lcmlog"), log = TmpPath("scen_damaged.lcmlog");
  ASSERT_EQ(RunShoal("sim " + kExample2 + " --duration 4 --quiet --out " + src, "scen_damaged_sim")
                .status, 1);
  int changed = 0;
  Rewrite(src, log, [&changed](const std::string& ch, std::int64_t*, std::string* data) {
    run_status_t st;
    if (ch == channels::Status() &&
        st.decode(data->data(), 0, static_cast<int>(data->size())) > 0) {
      const std::size_t at = st.scenario_toml.find("followers = 5");
      if (at != std::string::npos) {
        st.scenario_toml[at + 12] = '3';
        ++changed;
        data->assign(static_cast<std::size_t>(st.getEncodedSize()), '\0');
        st.encode(data->data(), 0, static_cast<int>(data->size()));
      }
    }
    return true;
  });
  ASSERT_GT(changed, 0);
  const auto r = RunShoal("analyze " + log + " --json", "scen_damaged_ana");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = ParseJson(r.out);
  const std::string warnings = j["warnings"].dump();
  EXPECT_NE(warnings.find("the scenario text in the log does not load"), std::string::npos)
      << warnings;
  EXPECT_EQ(warnings.find("no scenario text"), std::string::npos) << warnings;
  const auto [status, py] = PythonSummary(log, "scen_damaged");
  ASSERT_EQ(status, 0) << py;
  EXPECT_EQ(py["followers"], 5) << py.dump();
  EXPECT_EQ(py["states"], j["log_states"]) << py.dump();
  EXPECT_NE(py["warnings"].dump().find("the scenario text in the log does not load"),
            std::string::npos) << py["warnings"];
}

// A recording's stamps (here a shoal sim log restamped onto a wall clock) with one event's
// stamp damaged to 2^62: it is left out of the recording's span, said, and the wall time
// is the clean log's.
TEST(AnalyzeCli, OneStampFarFromItsNeighboursIsLeftOutOfTheWallTime) {
  const std::string src = TmpPath("stamp_src.lcmlog"), clean = TmpPath("stamp_clean.lcmlog");
  const std::string damaged = TmpPath("stamp_damaged.lcmlog");
  ASSERT_EQ(RunShoal("sim " + kExample2 + " --duration 20 --quiet --out " + src, "stamp_sim")
                .status, 1);
  constexpr std::int64_t kWall = 1700000000000000;  // 2023-11-14, in us
  Rewrite(src, clean, [](const std::string&, std::int64_t* stamp, std::string*) {
    *stamp += kWall;
    return true;
  });
  int n = 0;
  Rewrite(src, damaged, [&n](const std::string&, std::int64_t* stamp, std::string*) {
    *stamp = ++n == 5000 ? (std::int64_t{1} << 62) : *stamp + kWall;
    return true;
  });
  const auto c = RunShoal("analyze " + clean + " --json", "stamp_clean_ana");
  const auto d = RunShoal("analyze " + damaged + " --json", "stamp_damaged_ana");
  ASSERT_EQ(d.status, 0) << d.err;
  const auto cj = ParseJson(c.out), dj = ParseJson(d.out);
  ASSERT_TRUE(cj["wall_time_s"].is_number()) << c.out;
  EXPECT_DOUBLE_EQ(dj["wall_time_s"].get<double>(), cj["wall_time_s"].get<double>()) << d.out;
  EXPECT_NE(dj["warnings"].dump().find("1 event(s) have a receive time over an hour"),
            std::string::npos) << dj["warnings"];
}

// shoal compare says how many states it could not compare: states that do not decode, and
// a state naming another vehicle than its channel's (not compared as that vehicle's).
TEST(CompareCli, StatesThatDoNotDecodeOrNameAnotherVehicleAreCountedNotCompared) {
  const std::string src = TmpPath("cmp_dmg_src.lcmlog"), log = TmpPath("cmp_dmg.lcmlog");
  ASSERT_EQ(RunShoal("sim " + kExample2 + " --duration 4 --quiet --out " + src, "cmp_dmg_sim")
                .status, 1);
  int states2 = 0;
  Rewrite(src, log, [&states2](const std::string& ch, std::int64_t*, std::string* data) {
    if (ch == channels::State(3)) data->resize(data->size() / 2);  // cut: does not decode
    vehicle_state_t v;
    if (ch == channels::State(2) && ++states2 == 10 &&
        v.decode(data->data(), 0, static_cast<int>(data->size())) > 0) {
      v.vehicle_id = 4;  // follower 4's state on follower 2's channel
      v.eta[0] += 100.0;
      v.encode(data->data(), 0, static_cast<int>(data->size()));
    }
    return true;
  });
  const auto r = RunShoal("compare " + log + " " + src + " --allow-missing --json", "cmp_dmg");
  EXPECT_EQ(r.status, 0) << r.out << r.err;
  const auto j = ParseJson(r.out);
  EXPECT_EQ(j["max_position_diff_m"].get<double>(), 0.0) << r.out;
  EXPECT_NE(r.err.find("201 vehicle states do not decode and 1 name another vehicle than their "
                       "channel's"),
            std::string::npos) << r.err;
}

}  // namespace
}  // namespace shoal
