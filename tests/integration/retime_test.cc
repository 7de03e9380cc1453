// shoal retime (docs/analyze.md, "Mission-time logs"): a lockstep run's log, whose
// lcm-logger stamps span a fraction of the mission, retimed to mission time, replays at
// the mission's pace with the real lcm-logplayer and analyses exactly as the original.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <random>
#include <string>

#include "runtime/lcm_bus.h"
#include "runtime/log_reader.h"
#include "runtime/log_writer.h"
#include "tests/integration/test_util.h"

namespace shoal {
namespace {

using shoal::testing::ParseJson;
using shoal::testing::ReadFile;
using shoal::testing::RunShoal;
using shoal::testing::SourcePath;
using shoal::testing::TmpPath;
using shoal::testing::WaitExit;

constexpr double kMissionS = 6.0;

std::string Url(int port) { return "udpm://239.255.76.67:" + std::to_string(port) + "?ttl=0"; }
int RandomEvenPort() {
  std::random_device rd;
  return 20000 + static_cast<int>(rd() % 20000) * 2;
}

/// A lockstep shoal run of Example 2 for kMissionS s (its key next to it), and a retimed
/// copy of its log.
struct Logs {
  std::string run, retimed;
  int run_status = -1, retime_status = -1;
  std::string retime_err;
};
const Logs& TheLogs() {
  static const Logs l = [] {
    Logs r;
    std::string err;
    if (!shoal::EnsureLoopbackMulticast(&err)) ADD_FAILURE() << err;
    r.run = TmpPath("retime_run.lcmlog");
    r.retimed = TmpPath("retime_out.lcmlog");
    std::remove(r.retimed.c_str());
    std::remove((r.retimed + ".key").c_str());
    r.run_status = RunShoal("run " + SourcePath("scenarios/paper_example2.toml") +
                                " --duration " + std::to_string(kMissionS) + " --quiet --out " +
                                r.run + " --lcm-url '" + Url(RandomEvenPort()) + "'",
                            "retime_run")
                       .status;
    const auto rt = RunShoal("retime " + r.run + " --out " + r.retimed, "retime");
    r.retime_status = rt.status;
    r.retime_err = rt.err;
    return r;
  }();
  return l;
}

/// Seconds lcm-logplayer takes to play `log` at speed 1 (the subscriber is none: the
/// player paces by the stamps alone).
double PlaySeconds(const std::string& log) {
  const std::string cmd = "lcm-logplayer --lcm-url='" + Url(RandomEvenPort()) + "' " + log +
                          " >/dev/null 2>&1";
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_EQ(std::system(cmd.c_str()), 0);
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

class Retime : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_EQ(std::system("command -v lcm-logplayer >/dev/null"), 0)
        << "lcm-logplayer missing (Debian package liblcm-bin)";
    // 1: Example 2 does not converge in a few seconds; the run itself went to its end.
    ASSERT_EQ(TheLogs().run_status, 1);
    ASSERT_EQ(TheLogs().retime_status, 0) << TheLogs().retime_err;
  }
};

// The metrics of the retimed log are those of the original, key for key, but for where
// the log came from; the wall time is the original recording's, and the text says which
// log it is.
TEST_F(Retime, AnalysesTheSameAsTheOriginal) {
  const auto a = RunShoal("analyze " + TheLogs().run + " --json", "retime_ana_a");
  const auto b = RunShoal("analyze " + TheLogs().retimed + " --json", "retime_ana_b");
  ASSERT_EQ(a.status, 0) << a.err;
  ASSERT_EQ(b.status, 0) << b.err;
  auto ja = ParseJson(a.out), jb = ParseJson(b.out);
  EXPECT_EQ(ja["bus_authenticated"], true) << "the key is the run's";
  EXPECT_EQ(jb["bus_authenticated"], true) << "the key copied alongside verifies every message";
  EXPECT_EQ(jb["authentication"]["unauthenticated"], 0);
  EXPECT_TRUE(ja["retimed_from"].is_null());
  EXPECT_EQ(jb["retimed_from"]["log"], "retime_run.lcmlog") << jb;
  EXPECT_GT(ja["wall_time_s"].get<double>(), 0.0);
  for (auto* j : {&ja, &jb}) {
    j->erase("log");
    j->erase("retimed_from");
    j->erase("authentication");  // the key file's name
  }
  EXPECT_EQ(ja.dump(), jb.dump());
  const auto text = RunShoal("analyze " + TheLogs().retimed, "retime_ana_text");
  EXPECT_NE(text.out.find("RETIMED log (event times in mission time) of retime_run.lcmlog"),
            std::string::npos)
      << text.out;
}

// lcm-logplayer at speed 1 takes about the mission time for the retimed log; the
// original (a lockstep run, much faster than real time) plays in its own, shorter span.
TEST_F(Retime, PlaysAtTheMissionsPace) {
  const double retimed = PlaySeconds(TheLogs().retimed);
  EXPECT_GT(retimed, kMissionS - 0.5);
  EXPECT_LT(retimed, kMissionS + 2.0);
  const auto j = ParseJson(RunShoal("analyze " + TheLogs().run + " --json", "retime_wall").out);
  EXPECT_LT(j["wall_time_s"].get<double>(), kMissionS - 1.0) << "lockstep ran faster than real time";
}

// Same events, same bytes, same order; stamps never go back; the marker first.
TEST_F(Retime, KeepsEveryEventAndItsBytes) {
  LcmLogReader a, b;
  std::string err;
  ASSERT_TRUE(a.Open(TheLogs().run, &err)) << err;
  ASSERT_TRUE(b.Open(TheLogs().retimed, &err)) << err;
  LogEventView ea, eb;
  ASSERT_TRUE(b.Next(&eb));
  EXPECT_EQ(eb.channel, "SHOAL-RETIMED");
  std::int64_t n = 0, last = eb.timestamp;
  while (a.Next(&ea)) {
    ASSERT_TRUE(b.Next(&eb));
    ASSERT_EQ(ea.channel, eb.channel) << n;
    ASSERT_EQ(std::string(ea.data, ea.data + ea.size), std::string(eb.data, eb.data + eb.size));
    EXPECT_GE(eb.timestamp, last);
    last = eb.timestamp;
    ++n;
  }
  EXPECT_FALSE(b.Next(&eb));
  EXPECT_GT(n, 1000);
  struct stat st {};
  ASSERT_EQ(stat((TheLogs().retimed + ".key").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  EXPECT_EQ(ReadFile(TheLogs().retimed + ".key"), ReadFile(TheLogs().run + ".key"));
}

// A retimed log played back (lcm-logplayer) and recorded again (lcm-logger) has the
// recorder's wall-clock stamps, its replayed marker among them: it is no retimed log, and
// its wall time and real-time factor are the new recording's.
TEST_F(Retime, ARecordingOfAReplayIsNoRetimedLog) {
  const std::string copy = TmpPath("retime_rerecorded.lcmlog");
  {
    LcmLogReader in;
    std::string err;
    ASSERT_TRUE(in.Open(TheLogs().retimed, &err)) << err;
    LogWriter out(copy);
    LogEventView ev;
    // The recorder's clock: a later day, and the playback at half the mission's pace.
    std::int64_t first = -1;
    while (in.Next(&ev)) {
      if (first < 0) first = ev.timestamp;
      out.WriteRaw(std::string(ev.channel), 86'400'000'000 + first + 2 * (ev.timestamp - first),
                   ev.data, ev.size);
    }
    out.Close();
  }
  const auto r = RunShoal("analyze " + copy + " --json --key " + TheLogs().retimed + ".key",
                          "retime_rerecorded");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = ParseJson(r.out);
  EXPECT_TRUE(j["retimed_from"].is_null()) << j["retimed_from"];
  EXPECT_NEAR(j["realtime_factor"].get<double>(), 0.5, 0.05);
  EXPECT_EQ(RunShoal("retime " + copy + " --out " + TmpPath("retime_rerecorded_out.lcmlog") +
                         " --force --quiet",
                     "retime_rerecorded_again")
                .status,
            0)
      << "a recording of a replay can be retimed";
}

// --force over a log that had a key, with an input that has none, removes the old key:
// left there it would be taken as the new log's; without --force it is refused. The
// summary gives the mission time written, not the scenario's.
TEST_F(Retime, ReplacesTheOldKeyAndCountsTheMissionWritten) {
  const std::string keyless = TmpPath("retime_keyless.lcmlog");
  std::remove((keyless + ".key").c_str());
  const std::string all = ReadFile(TheLogs().run);
  {
    FILE* f = std::fopen(keyless.c_str(), "wb");
    ASSERT_NE(f, nullptr);
    std::fwrite(all.data(), 1, all.size() / 3, f);  // a third: a recording cut short
    std::fclose(f);
  }
  const std::string out = TmpPath("retime_rekeyed.lcmlog");
  std::remove(out.c_str());
  ASSERT_EQ(RunShoal("retime " + TheLogs().run + " --out " + out + " --quiet", "retime_k1").status, 0);
  ASSERT_EQ(access((out + ".key").c_str(), F_OK), 0);
  std::remove(out.c_str());
  auto r = RunShoal("retime " + keyless + " --out " + out, "retime_k2");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find(".key: exists"), std::string::npos) << r.err;
  r = RunShoal("retime " + keyless + " --out " + out + " --force", "retime_k3");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(access((out + ".key").c_str(), F_OK), 0) << "the old key was left beside the new log";
  const auto at = r.err.find(" s of mission");
  ASSERT_NE(at, std::string::npos) << r.err;
  const auto from = r.err.rfind(' ', at - 1);
  const double mission = std::stod(r.err.substr(from + 1, at - from - 1));
  EXPECT_GT(mission, 0.5) << r.err;
  EXPECT_LT(mission, kMissionS - 1.0) << r.err;
  EXPECT_EQ(RunShoal("analyze " + out, "retime_k4").status, 0);
}

// With the log's key, a message that does not verify (here one state's time moved near
// the end of the mission, its trailer no longer matching) sets no mission time: the events
// after it keep their own, as the analysis, which drops it, sees them.
// A state whose time is forged (with the key: it does not verify) or that does not decode
// (without a key: its fingerprint damaged) sets no mission time: the analysis drops it,
// and it must not carry every later event to its time.
TEST_F(Retime, AMessageThatDoesNotVerifyOrDecodeSetsNoTime) {
  for (const bool keyed : {true, false}) {
    const std::string forged = TmpPath(keyed ? "retime_forged.lcmlog" : "retime_undecodable.lcmlog");
    {
      LcmLogReader in;
      std::string err;
      ASSERT_TRUE(in.Open(TheLogs().run, &err)) << err;
      LogWriter out(forged);
      LogEventView ev;
      int states = 0;
      while (in.Next(&ev)) {
        std::string data(reinterpret_cast<const char*>(ev.data), static_cast<std::size_t>(ev.size));
        if (ev.channel == "SHOAL_STATE_2" && ++states == 4 && data.size() >= 16) {
          const std::uint64_t late = static_cast<std::uint64_t>((kMissionS - 0.1) * 1e6);
          for (int k = 0; k < 8; ++k) data[8 + k] = static_cast<char>(late >> (8 * (7 - k)));
          if (!keyed) data[0] = static_cast<char>(data[0] ^ 0x5a);
        }
        out.WriteRaw(std::string(ev.channel), ev.timestamp, data.data(),
                     static_cast<int>(data.size()));
      }
      out.Close();
    }
    std::remove((forged + ".key").c_str());
    if (keyed) {
      ASSERT_EQ(std::system(("cp '" + TheLogs().run + ".key' '" + forged + ".key'").c_str()), 0);
    }
    const std::string out = TmpPath("retime_forged_out.lcmlog");
    std::remove(out.c_str());
    std::remove((out + ".key").c_str());
    ASSERT_EQ(RunShoal("retime " + forged + " --out " + out + " --quiet", "retime_forged").status,
              0);
    LcmLogReader r;
    std::string err;
    ASSERT_TRUE(r.Open(out, &err)) << err;
    LogEventView ev;
    std::int64_t first = -1, events = 0, late = 0;
    while (r.Next(&ev) && events < 300) {
      if (first < 0) first = ev.timestamp;
      late += ev.timestamp - first > 1000000;  // the first 300 events lie in the first second
      ++events;
    }
    EXPECT_EQ(events, 300);
    EXPECT_EQ(late, 0) << "events stamped at the forged time, " << (keyed ? "keyed" : "no key");
  }
}

// Receive times so large that adding the mission time would pass the largest stamp: not a
// recording's clock. Refused (exit 2) rather than written with stamps that wrap around.
TEST_F(Retime, StampsThatWouldPassTheLargestAreRefused) {
  const std::string huge = TmpPath("retime_huge.lcmlog");
  {
    LcmLogReader in;
    std::string err;
    ASSERT_TRUE(in.Open(TheLogs().run, &err)) << err;
    LogWriter out(huge);
    LogEventView ev;
    std::int64_t first = -1;
    while (in.Next(&ev)) {
      if (first < 0) first = ev.timestamp;
      // 3 s of room above the first stamp, for a 6 s mission.
      constexpr std::int64_t kMax = std::numeric_limits<std::int64_t>::max();
      const std::int64_t after = std::min<std::int64_t>(ev.timestamp - first, 2000000);
      out.WriteRaw(std::string(ev.channel), kMax - 3000000 + after, ev.data, ev.size);
    }
    out.Close();
  }
  ASSERT_EQ(std::system(("cp '" + TheLogs().run + ".key' '" + huge + ".key'").c_str()), 0);
  const std::string out = TmpPath("retime_huge_out.lcmlog");
  std::remove(out.c_str());
  std::remove((out + ".key").c_str());
  const auto r = RunShoal("retime " + huge + " --out " + out, "retime_huge");
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_NE(r.err.find("passes the largest stamp"), std::string::npos) << r.err;
  EXPECT_NE(access(out.c_str(), F_OK), 0) << "a retimed log was written";
}

TEST_F(Retime, RefusesToOverwriteAndSaysWhy) {
  const std::string before = ReadFile(TheLogs().run);
  auto r = RunShoal("retime " + TheLogs().run + " --out " + TheLogs().run, "retime_self");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("is the input log"), std::string::npos) << r.err;
  r = RunShoal("retime " + TheLogs().run + " --out " + TheLogs().run + " --force", "retime_self_f");
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(ReadFile(TheLogs().run), before) << "the input is never written";
  r = RunShoal("retime " + TheLogs().run + " --out " + TheLogs().retimed, "retime_exists");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("exists; give --force"), std::string::npos) << r.err;
  r = RunShoal("retime " + TheLogs().retimed + " --out " + TmpPath("retime_twice.lcmlog") +
                   " --force", "retime_twice");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("already retimed"), std::string::npos) << r.err;
  r = RunShoal("retime " + TmpPath("no_such.lcmlog") + " --out " + TmpPath("x.lcmlog"), "retime_missing");
  EXPECT_EQ(r.status, 2);
  const std::string junk = TmpPath("retime_junk.txt");
  std::system(("echo not a log > " + junk).c_str());
  r = RunShoal("retime " + junk + " --out " + TmpPath("retime_junk_out.lcmlog"), "retime_junk");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("not an LCM log"), std::string::npos) << r.err;
  r = RunShoal("retime " + TheLogs().run, "retime_noout");
  EXPECT_EQ(r.status, 2);
  r = RunShoal("retime " + TheLogs().run + " --out /proc/retime.lcmlog", "retime_unwritable");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("/proc/retime.lcmlog"), std::string::npos) << r.err;
  EXPECT_EQ(RunShoal("retime --help", "retime_help").status, 0);
}

}  // namespace
}  // namespace shoal
