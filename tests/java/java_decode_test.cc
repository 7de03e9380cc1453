// Shoal's logs decoded by LCM's Java tools: tests/java/DecodeShoalLog.java reads a real log
// with lcm.logging.Log and decodes every event through shoal_lcmtypes.jar, finding each
// class by its fingerprint with lcm-spy's own lookup (lcm.spy.LCMTypeDatabase); what it
// prints must be what `shoal analyze --json` and `--csv` say of the same log.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cinttypes>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "shoal/channel_event_t.hpp"
#include "shoal/channel_events_t.hpp"
#include "shoal/clock_tick_t.hpp"
#include "shoal/clock_window_t.hpp"
#include "shoal/health2_t.hpp"
#include "shoal/health_t.hpp"
#include "shoal/run_status_t.hpp"
#include "shoal/vehicle_state_t.hpp"
#include "tests/integration/test_util.h"

namespace shoal {
namespace {

using shoal::testing::ParseJson;
using shoal::testing::ReadFile;
using shoal::testing::RunShoal;
using shoal::testing::SourcePath;
using shoal::testing::TmpPath;

/// Runs DecodeShoalLog with `args`; its standard output (fails the test on another status).
std::string RunJava(const std::string& args, const std::string& tag) {
  const std::string out = TmpPath(tag + ".java.out"), err = TmpPath(tag + ".java.err");
  const std::string cmd = std::string(SHOAL_JAVA) + " -cp " + SHOAL_JAVA_CLASSPATH +
                          " DecodeShoalLog " + args + " >" + out + " 2>" + err + " </dev/null";
  const int status = std::system(cmd.c_str());
  EXPECT_EQ(status, 0) << cmd << "\n" << ReadFile(err);
  return ReadFile(out);
}

/// DecodeShoalLog's lines, split into words; the lines whose first word is `keyword`.
std::vector<std::vector<std::string>> Lines(const std::string& text, const std::string& keyword) {
  std::vector<std::vector<std::string>> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    std::istringstream words(line);
    std::vector<std::string> w;
    for (std::string s; words >> s;) w.push_back(s);
    if (!w.empty() && w[0] == keyword) lines.push_back(w);
  }
  return lines;
}

/// The word after `key` in a line, as a number (fails the test when it is not there).
long long Num(const std::vector<std::string>& line, const std::string& key) {
  for (std::size_t i = 0; i + 1 < line.size(); ++i) {
    if (line[i] == key) return std::stoll(line[i + 1]);
  }
  ADD_FAILURE() << "no " << key << " in a line starting " << line[0];
  return -1;
}

std::string Word(const std::vector<std::string>& line, const std::string& key) {
  for (std::size_t i = 0; i + 1 < line.size(); ++i) {
    if (line[i] == key) return line[i + 1];
  }
  ADD_FAILURE() << "no " << key << " in a line starting " << line[0];
  return "";
}

/// A CSV file of shoal analyze --csv: its header's columns and its data rows.
struct Csv {
  std::map<std::string, std::size_t> column;
  std::vector<std::vector<std::string>> rows;
  const std::string& At(std::size_t row, const std::string& name) const {
    return rows.at(row).at(column.at(name));
  }
};

Csv ReadCsv(const std::string& path) {
  Csv csv;
  std::istringstream in(ReadFile(path));
  std::string line;
  if (!std::getline(in, line)) {
    ADD_FAILURE() << "no header in " << path;
    return csv;
  }
  auto split = [](const std::string& l) {
    std::vector<std::string> cells;
    std::istringstream cs(l);
    for (std::string c; std::getline(cs, c, ',');) cells.push_back(c);
    return cells;
  };
  const auto header = split(line);
  for (std::size_t i = 0; i < header.size(); ++i) csv.column[header[i]] = i;
  while (std::getline(in, line)) {
    if (!line.empty()) csv.rows.push_back(split(line));
  }
  return csv;
}

/// The bits of the double a CSV cell holds: shoal analyze writes each double so that it
/// reads back exactly.
std::string Bits(const std::string& cell) {
  const double v = std::strtod(cell.c_str(), nullptr);
  std::uint64_t u = 0;
  std::memcpy(&u, &v, sizeof u);
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016" PRIx64, u);
  return hex;
}

/// The class every Shoal channel holds.
std::string ClassOf(const std::string& channel) {
  if (channel.rfind("SHOAL_STATE_", 0) == 0 || channel.rfind("SHOAL_RX_", 0) == 0) {
    return "shoal.vehicle_state_t";
  }
  if (channel.rfind("SHOAL_HEALTH_", 0) == 0) return "shoal.health2_t";
  if (channel == "SHOAL_CHANNEL") return "shoal.channel_events_t";
  if (channel == "SHOAL_CLOCK") return "shoal.clock_window_t";
  if (channel == "SHOAL_STATUS") return "shoal.run_status_t";
  return "unknown channel " + channel;
}

enum class Trailer { kNone, kAuthentication };

/// Every event decoded, re-encoded to its own bytes, with the trailer the run gives it.
void CheckChannels(const std::string& decoded, const nlohmann::ordered_json& analyze,
                   Trailer trailer) {
  const auto log = Lines(decoded, "log");
  ASSERT_EQ(log.size(), 1u) << decoded;
  EXPECT_EQ(Num(log[0], "undecoded"), 0);
  EXPECT_EQ(Num(log[0], "events"), analyze["log_events"].get<long long>());
  long long events = 0;
  for (const auto& c : Lines(decoded, "channel")) {
    const long long n = Num(c, "events");
    events += n;
    EXPECT_EQ(Word(c, "type"), ClassOf(c[1])) << c[1];
    EXPECT_EQ(Num(c, "reencoded_equal"), n) << c[1];
    EXPECT_EQ(Num(c, "trailer_other"), 0) << c[1];
    EXPECT_EQ(Num(c, trailer == Trailer::kNone ? "trailer_none" : "trailer_auth"), n) << c[1];
  }
  EXPECT_EQ(events, analyze["log_events"].get<long long>());
}

/// States per vehicle, and the first and last state's position to the bit, against the
/// JSON's counts and the CSV's rows.
void CheckStates(const std::string& decoded, const nlohmann::ordered_json& analyze,
                 const std::string& csv_dir) {
  const int followers = static_cast<int>(analyze["followers"].size());
  const auto vehicles = Lines(decoded, "vehicle");
  ASSERT_EQ(vehicles.size(), static_cast<std::size_t>(followers + 1)) << decoded;
  long long states = 0;
  for (const auto& v : vehicles) {
    const int id = std::stoi(v[1]);
    const long long n = Num(v, "states");
    states += n;
    if (id >= 1) {
      EXPECT_EQ(n, analyze["followers"][id - 1]["samples"].get<long long>()) << id;
    }
    const Csv csv = ReadCsv(csv_dir + "/vehicle_" + v[1] + ".csv");
    ASSERT_EQ(static_cast<long long>(csv.rows.size()), n) << "vehicle " << id;
    for (const auto& s : Lines(decoded, "state")) {
      if (s[1] != v[1]) continue;
      const std::size_t row = s[2] == "first" ? 0 : csv.rows.size() - 1;
      EXPECT_EQ(Word(s, "utime"), csv.At(row, "utime_us")) << id << " " << s[2];
      EXPECT_EQ(Word(s, "seq"), csv.At(row, "seq")) << id << " " << s[2];
      ASSERT_GE(s.size(), 4u);  // ... bits X Y Z
      ASSERT_EQ(s[s.size() - 4], "bits") << id;
      EXPECT_EQ(s[s.size() - 3], Bits(csv.At(row, "x_m"))) << id << " " << s[2] << " x";
      EXPECT_EQ(s[s.size() - 2], Bits(csv.At(row, "y_m"))) << id << " " << s[2] << " y";
      EXPECT_EQ(s[s.size() - 1], Bits(csv.At(row, "z_m"))) << id << " " << s[2] << " z";
    }
  }
  EXPECT_EQ(states, analyze["log_states"].get<long long>());
  EXPECT_EQ(Lines(decoded, "state").size(), 2 * vehicles.size());
}

/// Channel decisions by status against the JSON's channel figures and the CSV's rows;
/// health reports per process; the first status's scenario.
void CheckDecisionsHealthStatus(const std::string& decoded, const nlohmann::ordered_json& analyze,
                                const std::string& csv_dir) {
  const auto d = Lines(decoded, "decisions");
  ASSERT_EQ(d.size(), 1u) << decoded;
  const auto& c = analyze["channel"];
  const char* by_status[] = {"delivered",          "dropped_loss",   "dropped_queue",
                             "dropped_invalid",    "skipped_modem_busy", "dropped_range",
                             "skipped_silent",     "dropped_link_down",  "dropped_deaf"};
  for (int s = 0; s < 9; ++s) {
    EXPECT_EQ(Num(d[0], "status" + std::to_string(s)), c[by_status[s]].get<long long>()) << s;
  }
  EXPECT_EQ(Num(d[0], "status_other"), 0);
  const long long events = Num(d[0], "events");
  EXPECT_EQ(events, c["sent"].get<long long>() + c["skipped_modem_busy"].get<long long>() +
                        c["skipped_silent"].get<long long>());
  EXPECT_EQ(static_cast<long long>(ReadCsv(csv_dir + "/channel_events.csv").rows.size()), events);
  EXPECT_EQ(Num(d[0], "status0"), analyze["channel_delivered"].get<long long>());

  long long reports = 0;
  std::map<int, long long> by_process;
  for (const auto& h : Lines(decoded, "health")) {
    by_process[std::stoi(h[1])] = Num(h, "reports");
    reports += Num(h, "reports");
  }
  for (const auto& p : analyze["loop"]["processes"]) {
    EXPECT_EQ(by_process[p["id"].get<int>()], p["reports"].get<long long>()) << p;
  }
  EXPECT_EQ(static_cast<long long>(ReadCsv(csv_dir + "/health.csv").rows.size()), reports);
  const auto status = Lines(decoded, "status");
  ASSERT_EQ(status.size(), 1u) << decoded;
  EXPECT_GE(Num(status[0], "reports"), 1);
  EXPECT_EQ(Word(status[0], "scenario"), analyze["scenario"].get<std::string>());
  EXPECT_EQ(Num(status[0], "followers"), static_cast<long long>(analyze["followers"].size()));
}

/// Decodes `log` through the jar and checks it against shoal analyze's JSON and CSV.
void CheckLog(const std::string& log, const std::string& tag, Trailer trailer,
              std::string* decoded_out = nullptr) {
  const std::string csv_dir = TmpPath(tag + "_csv");
  const auto ana = RunShoal("analyze " + log + " --json --csv " + csv_dir, tag + "_analyze");
  ASSERT_EQ(ana.status, 0) << ana.err;
  const auto analyze = ParseJson(ana.out);
  const std::string decoded = RunJava(log, tag);
  CheckChannels(decoded, analyze, trailer);
  CheckStates(decoded, analyze, csv_dir);
  CheckDecisionsHealthStatus(decoded, analyze, csv_dir);
  if (decoded_out) *decoded_out = decoded;
  if (!::testing::Test::HasFailure()) std::system(("rm -rf " + log + " " + csv_dir).c_str());
}

// lcm-spy finds a message's class by the fingerprint it starts with: every type's Java
// fingerprint is the C++ one and finds its own class, a type used only inside another
// (channel_event_t in channel_events_t) and the types only older logs hold included.
TEST(JavaDecode, EveryTypeIsFoundByItsFingerprintAsLcmSpyFindsIt) {
  const std::map<std::string, std::int64_t> cpp = {
      {"vehicle_state_t", vehicle_state_t::getHash()}, {"clock_window_t", clock_window_t::getHash()},
      {"clock_tick_t", clock_tick_t::getHash()},       {"channel_event_t", channel_event_t::getHash()},
      {"channel_events_t", channel_events_t::getHash()}, {"health_t", health_t::getHash()},
      {"health2_t", health2_t::getHash()},             {"run_status_t", run_status_t::getHash()}};
  std::vector<std::string> types;
  std::string names;
  std::istringstream list(SHOAL_LCM_TYPE_NAMES);
  for (std::string t; std::getline(list, t, ',');) {
    types.push_back(t);
    names += (names.empty() ? "shoal." : ",shoal.") + t;
  }
  ASSERT_EQ(types.size(), cpp.size()) << "a type of lcmtypes/CMakeLists.txt is not listed here";
  const auto lines = Lines(RunJava("--types " + names, "java_types"), "type");
  ASSERT_EQ(lines.size(), types.size());
  for (std::size_t i = 0; i < types.size(); ++i) {
    ASSERT_TRUE(cpp.count(types[i])) << types[i] << " is not listed here";
    char hex[17];
    std::snprintf(hex, sizeof hex, "%016" PRIx64, static_cast<std::uint64_t>(cpp.at(types[i])));
    EXPECT_EQ(lines[i][1], "shoal." + types[i]);
    EXPECT_EQ(Word(lines[i], "fingerprint"), hex) << types[i];
    EXPECT_EQ(Word(lines[i], "found"), "shoal." + types[i]);
  }
}

// shoal sim of the faults scenario: every kind of channel decision it makes (delivered,
// lost, sender silent, link down, receiver deaf) is counted as shoal analyze counts it.
TEST(JavaDecode, ShoalSimLogDecodesAsShoalAnalyzeReadsIt) {
  const std::string log = TmpPath("java_decode_sim_" + std::to_string(getpid()) + ".lcmlog");
  const auto sim = RunShoal("sim " + SourcePath("scenarios/faults.toml") + " --quiet --out " + log,
                            "java_decode_sim");
  ASSERT_EQ(sim.status, 0) << sim.err;
  std::string decoded;
  CheckLog(log, "java_decode_sim", Trailer::kNone, &decoded);
  const auto d = Lines(decoded, "decisions");
  ASSERT_EQ(d.size(), 1u);
  for (const char* s : {"status0", "status1", "status6", "status7", "status8"}) {
    EXPECT_GT(Num(d[0], s), 0) << s << ": the scenario no longer makes such decisions";
  }
}

// A lockstep run authenticates every message: each carries the 24-byte trailer (SHOALSIP
// and a SipHash tag) after its LCM encoding, which the Java decoders leave unread.
TEST(JavaDecode, SecuredLockstepRunDecodesDespiteItsAuthenticationTrailers) {
  const std::string log = TmpPath("java_decode_sil_" + std::to_string(getpid()) + ".lcmlog");
  const auto run = RunShoal("run " + SourcePath("scenarios/paper_example2.toml") +
                                " --mode lockstep --duration 10 --quiet --json --out " + log,
                            "java_decode_sil");
  // Exit 1: Example 2 has not converged after 10 s; anything else is a failed run.
  ASSERT_TRUE(run.status == 0 || run.status == 1) << run.out << run.err;
  const auto report = ParseJson(run.out);
  ASSERT_EQ(report["bus_authenticated"], true) << run.out;
  ASSERT_EQ(report["log_complete"], true) << run.out;
  CheckLog(log, "java_decode_sil", Trailer::kAuthentication);
  if (!::testing::Test::HasFailure()) std::system(("rm -rf " + log + ".d " + log + ".key").c_str());
}

}  // namespace
}  // namespace shoal
