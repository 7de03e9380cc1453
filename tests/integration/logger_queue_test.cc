// The run's lcm-logger keeps bursts far beyond LCM's 30-message subscription queue
// (runtime/lcm_queue_shim.c, preloaded by shoal run), so that the states of many vehicles
// stepping the same tick are all logged, and lockstep windows are no longer cut to 20
// logger messages (docs/run.md, "The logger's queue").
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "channel_emulator/recorder_gate.h"
#include "runtime/lcm_bus.h"
#include "runtime/log_reader.h"
#include "tests/integration/test_util.h"

namespace shoal {
namespace {

using testing::ParseJson;
using testing::ReadFile;
using testing::RunShoal;
using testing::SourcePath;
using testing::TmpPath;

int ProbeKept(const std::string& preload, int burst) {
  const std::string url = PrivateLcmUrl(RandomPrivatePort(1));
  const std::string cmd = (preload.empty() ? "" : "LD_PRELOAD=" + preload + " ") +
                          std::string(SHOAL_BINARY_DIR) + "/tests/lcm_queue_probe '" + url +
                          "' " + std::to_string(burst);
  FILE* p = popen(cmd.c_str(), "r");
  if (p == nullptr) return -1;
  int kept = -1;
  if (std::fscanf(p, "%d", &kept) != 1) kept = -1;
  pclose(p);
  return kept;
}

TEST(LoggerQueue, ThePreloadedLibraryKeepsABurstThatLcmsQueueDrops) {
  const std::string shim = std::string(SHOAL_BINARY_DIR) + "/runtime/libshoal_lcm_queue.so";
  const int burst = 400;
  // Without the library LCM keeps its queue of 30 (plus the one being dispatched).
  const int plain = ProbeKept("", burst);
  ASSERT_GT(plain, 0);
  EXPECT_LE(plain, 31);
  EXPECT_EQ(ProbeKept(shim, burst), burst);
}

TEST(LoggerQueue, FortyFollowersInLockstepLogEveryStateInWindowsOfTheChannelsLag) {
  const std::string scenario = TmpPath("logger_queue_40.toml");
  ASSERT_EQ(std::system(("'" + SourcePath("bench/scale_scenario.sh") + "' 40 4 > '" +
                         scenario + "'").c_str()),
            0);
  const std::string log = TmpPath("logger_queue_40.lcmlog");
  const auto r = RunShoal("run '" + scenario + "' --out '" + log + "' --json",
                          "logger_queue_40");
  ASSERT_LE(r.status, 1) << r.err;  // 1: 4 s do not let the chain converge
  const auto j = ParseJson(r.out);
  EXPECT_EQ(j["log_complete"], true) << r.out;
  EXPECT_EQ(j["log_states"], j["log_states_expected"]) << r.out;
  // The channel's lag at the window's ticks alone bounds the window (tau(t) = 0.1 + 0.05
  // cos(t): 3 to 8 ticks): 41 vehicles' states per tick would cut it to 1 tick with LCM's
  // queue of 30.
  const std::string emulator = ReadFile(log + ".d/emulator.txt");
  EXPECT_NE(emulator.find("lockstep, at least 3 tick(s) per round trip"), std::string::npos)
      << emulator;
  const std::size_t w = emulator.find("lockstep, ", emulator.find("at least") + 1);
  ASSERT_NE(w, std::string::npos) << emulator;
  long long windows = 0, shortest = 0, longest = 0;
  ASSERT_EQ(std::sscanf(emulator.c_str() + w, "lockstep, %lld windows of %lld to %lld", &windows,
                        &shortest, &longest),
            3)
      << emulator;
  EXPECT_GE(shortest, 3) << emulator;
  EXPECT_EQ(longest, 8) << emulator;
  EXPECT_LT(windows, 201 / 3) << emulator;  // fewer than with 3 ticks throughout
  // The vehicles publish on the uplink, so the clock master is the logger's only sender and
  // waits by the logger's count, which at the end covers everything it was sent.
  const std::size_t at = emulator.find("; it handled ");
  ASSERT_NE(at, std::string::npos) << emulator;
  long long handled = -1, sent = -1;
  ASSERT_EQ(std::sscanf(emulator.c_str() + at, "; it handled %lld of the %lld", &handled, &sent),
            2)
      << emulator;
  EXPECT_GT(sent, windows) << emulator;  // every window sends the logger states
  EXPECT_GE(handled, sent) << emulator;
}

// Given lcm-logger with the preloaded library, when a process publishes a recordable
// bundle (its lockstep window's states and health) and then a message alone, then the log
// holds each part as a message of its own, on its channel, byte for byte what it would be
// had it been published alone (trailer included), in order; a malformed recordable bundle
// is recorded as it came, on the bundle channel. With SHOAL_LOGGER_PROGRESS=1 it counts
// each message it handled, a bundle once, where the clock master reads it.
/// Starts the real lcm-logger on `url` writing `log`, with the run's library preloaded and
/// its count kept (as shoal run starts it); returns once it has subscribed (its pid), or
/// -1 if it did not start.
pid_t StartLogger(const std::string& url, const std::string& log) {
  const std::string shim = std::string(SHOAL_BINARY_DIR) + "/runtime/libshoal_lcm_queue.so";
  const std::string preload = "LD_PRELOAD=" + shim;
  const std::string url_arg = "--lcm-url=" + url;
  std::vector<char*> argv = {const_cast<char*>("/usr/bin/lcm-logger"),
                             const_cast<char*>(url_arg.c_str()), const_cast<char*>("-f"),
                             const_cast<char*>("-q"), const_cast<char*>("--"),
                             const_cast<char*>(log.c_str()), nullptr};
  std::vector<char*> envp = {const_cast<char*>(preload.c_str()),
                             const_cast<char*>("SHOAL_LOGGER_PROGRESS=1"), nullptr};
  pid_t pid = 0;
  if (posix_spawn(&pid, argv[0], nullptr, nullptr, argv.data(), envp.data()) != 0) return -1;
  for (int i = 0; i < 100 && access(log.c_str(), F_OK) != 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // subscribed
  return pid;
}

TEST(LoggerQueue, TheLoggerRecordsARecordableBundleAsItsMessages) {
  const std::string url = PrivateLcmUrl(RandomPrivatePort(1));
  const std::string log = TmpPath("recordable_bundle.lcmlog");
  std::remove(log.c_str());
  const pid_t pid = StartLogger(url, log);
  ASSERT_GT(pid, 0);
  RecorderProgress progress(pid);
  ASSERT_TRUE(progress.Attach());  // made at its subscription
  // LCM's own self-test message, when it came after the subscription, is counted too.
  const std::uint64_t before = progress.handled();
  EXPECT_LE(before, 1u);
  bus_auth::Key key;
  key.fill(4);
  LcmBus bus(url, key);
  bus.BeginBundle(/*recordable=*/true);
  ASSERT_TRUE(bus.PublishRaw("SHOAL_STATE_4", "tick0", 5));
  ASSERT_TRUE(bus.PublishRaw("SHOAL_STATE_4", "tick1", 5));
  ASSERT_TRUE(bus.PublishRaw("SHOAL_HEALTH_4", "health", 6));
  ASSERT_TRUE(bus.EndBundle());
  ASSERT_TRUE(bus.PublishRaw("SHOAL_STATUS", "alone", 5));
  const unsigned char bad[] = {'S', 'H', 'B', '2', 3, 'A', 'B', 'C', 0, 0, 0, 9, 'x'};
  LcmBus plain(url);
  ASSERT_TRUE(plain.PublishRaw(bundle_wire::kChannel, bad, sizeof(bad)));
  // Three messages: the bundle, the one alone and the malformed bundle.
  EXPECT_TRUE(progress.WaitFor(before + 3, 5000000000LL));
  EXPECT_EQ(progress.timeouts(), 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EXPECT_EQ(progress.handled(), before + 3);
  kill(pid, SIGINT);
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);

  LcmLogReader reader;
  std::string error;
  ASSERT_TRUE(reader.Open(log, &error)) << error;
  std::vector<std::pair<std::string, std::string>> events;
  LogEventView ev;
  while (reader.Next(&ev)) {
    events.emplace_back(std::string(ev.channel),
                        std::string(reinterpret_cast<const char*>(ev.data),
                                    static_cast<std::size_t>(ev.size)));
  }
  const std::vector<std::pair<std::string, std::string>> sent = {
      {"SHOAL_STATE_4", "tick0"}, {"SHOAL_STATE_4", "tick1"}, {"SHOAL_HEALTH_4", "health"},
      {"SHOAL_STATUS", "alone"}};
  ASSERT_EQ(events.size(), sent.size() + 1);
  for (std::size_t k = 0; k < sent.size(); ++k) {
    const std::string& text = sent[k].second;
    std::string alone = text + std::string(bus_auth::kTrailerBytes, '\0');
    bus_auth::Sign(key, sent[k].first, text.data(), static_cast<int>(text.size()),
                   reinterpret_cast<unsigned char*>(&alone[text.size()]));
    EXPECT_EQ(events[k].first, sent[k].first) << k;
    EXPECT_EQ(events[k].second, alone) << k;
  }
  EXPECT_EQ(events.back().first, bundle_wire::kChannel);
  EXPECT_EQ(events.back().second, std::string(reinterpret_cast<const char*>(bad), sizeof(bad)));
}

// Datagrams whose LCM header does not add up made LCM 1.3.1's receive thread write outside
// its buffers: one forged fragment from any user of the host killed the run's logger
// (SIGSEGV). The preloaded library refuses them before LCM reads them; a bundle naming a
// channel that is not the run's is logged as it came, not unpacked into that name.
TEST(LoggerQueue, ForgedFragmentsDoNotCrashTheLoggerNorBundlesNameOtherChannels) {
  const std::string url = PrivateLcmUrl(RandomPrivatePort(1));
  const std::string log = TmpPath("forged_fragments.lcmlog");
  std::remove(log.c_str());
  const pid_t pid = StartLogger(url, log);
  ASSERT_GT(pid, 0);
  RecorderProgress progress(pid);
  ASSERT_TRUE(progress.Attach());
  const std::uint64_t before = progress.handled();
  for (const auto& d : testing::ForgedLcmDatagrams()) testing::SendUdpDatagram(url, d);
  const unsigned char foreign[] = {'S', 'H', 'B', '2', 2, 1, 2, 0, 0, 0, 1, 'x'};
  LcmBus plain(url);
  ASSERT_TRUE(plain.PublishRaw(bundle_wire::kChannel, foreign, sizeof(foreign)));
  ASSERT_TRUE(plain.PublishRaw("SHOAL_STATUS", "alone", 5));
  EXPECT_TRUE(progress.WaitFor(before + 2, 5000000000LL));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  kill(pid, SIGINT);
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  EXPECT_TRUE(WIFEXITED(status)) << "lcm-logger ended by signal " << WTERMSIG(status);
  LcmLogReader reader;
  std::string error;
  ASSERT_TRUE(reader.Open(log, &error)) << error;
  std::vector<std::pair<std::string, std::string>> events;
  LogEventView ev;
  while (reader.Next(&ev)) {
    events.emplace_back(std::string(ev.channel),
                        std::string(reinterpret_cast<const char*>(ev.data),
                                    static_cast<std::size_t>(ev.size)));
  }
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].first, bundle_wire::kChannel);
  EXPECT_EQ(events[0].second,
            std::string(reinterpret_cast<const char*>(foreign), sizeof(foreign)));
  EXPECT_EQ(events[1].first, "SHOAL_STATUS");
  EXPECT_EQ(events[1].second, "alone");
}

// lcm-logger creates its log before it subscribes. A run that started its processes once
// the log existed lost what they sent before the subscription: with the logger 600 ms
// late, every message of a short lockstep run; with it a little late, the processes'
// ready statuses, after which the clock master waited its limit for them at every window
// (a run at 1x real time). shoal run starts the processes once the logger has subscribed:
// on the default URLs, and on one bus for all (--shared-url, or a user's --lcm-url), where
// the clock master does not read the logger's count and only the launcher waits for it.
int LoggerCountsInDevShm() {
  int n = 0;
  for (const auto& e : std::filesystem::directory_iterator("/dev/shm")) {
    n += e.path().filename().string().rfind("shoal-logger-", 0) == 0;
  }
  return n;
}

TEST(LoggerQueue, ALoggerSlowToSubscribeStillRecordsTheWholeRunWithoutWaits) {
  const std::string lib = std::string(SHOAL_BINARY_DIR) + "/tests/libslow_logger_subscribe.so";
  ASSERT_EQ(access(lib.c_str(), R_OK), 0) << lib;
  const std::string user_url = " --lcm-url '" + PrivateLcmUrl(RandomPrivatePort(5)) + "'";
  for (const std::string& how : {std::string(), std::string(" --shared-url"), user_url}) {
    const std::string log = TmpPath("slow_subscribe.lcmlog");
    const int counts_before = LoggerCountsInDevShm();
    setenv("LD_PRELOAD", lib.c_str(), 1);
    setenv("SHOAL_TEST_SUBSCRIBE_DELAY_MS", "600", 1);
    const auto r = RunShoal("run " + SourcePath("scenarios/paper_example2.toml") +
                                " --mode lockstep --duration 20 --json --out " + log + how,
                            "slow_subscribe");
    unsetenv("LD_PRELOAD");
    unsetenv("SHOAL_TEST_SUBSCRIBE_DELAY_MS");
    const auto j = ParseJson(r.out);
    EXPECT_EQ(j["log_complete"], true) << how << "\n" << r.out << r.err;
    EXPECT_EQ(j["log_states"], j["log_states_expected"]) << how << "\n" << r.out;
    EXPECT_GT(j["log_states"].get<double>(), 0) << how << "\n" << r.out;
    // The logger's count, read by no one on one bus, is not left behind.
    EXPECT_LE(LoggerCountsInDevShm(), counts_before) << how;
    if (!how.empty()) continue;  // the clock master waits for the logger on an uplink only
    // Not a wait of the limit at every window (a machine stalled for 100 ms may cost one).
    const std::string emulator = ReadFile(log + ".d/emulator.txt");
    const std::size_t at = emulator.find(" gave up; it handled ");
    ASSERT_NE(at, std::string::npos) << emulator;
    const std::size_t from = emulator.rfind(' ', at - 1) + 1;
    EXPECT_LT(std::stoi(emulator.substr(from, at - from)), 5) << emulator;
  }
}

// lcm-logger's writer, stopped by SIGINT, drops what it has not written yet. A writer far
// behind at the end (a slow disk: 100 us more per event) still writes the whole run: the
// clock master waits for it on an uplink, shoal run itself on one bus for all.
TEST(LoggerQueue, ALoggerBehindAtTheEndWritesTheWholeRunBeforeItIsStopped) {
  const std::string lib = std::string(SHOAL_BINARY_DIR) + "/tests/libslow_logger_subscribe.so";
  ASSERT_EQ(access(lib.c_str(), R_OK), 0) << lib;
  for (const std::string how : {"", " --shared-url"}) {
    const std::string log = TmpPath("slow_writer.lcmlog");
    setenv("LD_PRELOAD", lib.c_str(), 1);
    setenv("SHOAL_TEST_WRITE_DELAY_US", "100", 1);
    const auto r = RunShoal("run " + SourcePath("scenarios/paper_example2.toml") +
                                " --mode lockstep --duration 20 --json --out " + log + how,
                            "slow_writer");
    unsetenv("LD_PRELOAD");
    unsetenv("SHOAL_TEST_WRITE_DELAY_US");
    const auto j = ParseJson(r.out);
    EXPECT_EQ(j["log_complete"], true) << how << "\n" << r.out << r.err;
    EXPECT_EQ(j["log_states"], j["log_states_expected"]) << how << "\n" << r.out;
    const auto a = RunShoal("analyze " + log + " --json", "slow_writer_analyze");
    EXPECT_EQ(ParseJson(a.out)["scenario_source"], "log") << how << "\n" << a.err;
  }
}

// Ctrl-C while shoal run waits for the logger to subscribe: nothing else is started (nor,
// behind ssh, logged in to), and the run says it was interrupted.
TEST(LoggerQueue, CtrlCWhileTheLoggerSubscribesStartsNothingElse) {
  const std::string lib = std::string(SHOAL_BINARY_DIR) + "/tests/libslow_logger_subscribe.so";
  ASSERT_EQ(access(lib.c_str(), R_OK), 0) << lib;
  for (const std::string mode : {"lockstep", "realtime"}) {
    const std::string log = TmpPath("slow_subscribe_stop.lcmlog");
    std::system(("rm -rf '" + log + ".d'").c_str());
    setenv("LD_PRELOAD", lib.c_str(), 1);
    setenv("SHOAL_TEST_SUBSCRIBE_DELAY_MS", "5000", 1);
    const std::string out = TmpPath("slow_subscribe_stop.out");
    const pid_t run = testing::StartShoal("run " + SourcePath("scenarios/paper_example2.toml") +
                                              " --mode " + mode + " --duration 20 --out " + log,
                                          out);
    unsetenv("LD_PRELOAD");
    unsetenv("SHOAL_TEST_SUBSCRIBE_DELAY_MS");
    std::this_thread::sleep_for(std::chrono::milliseconds(1500));
    kill(run, SIGINT);
    EXPECT_EQ(testing::WaitExit(run, 30, nullptr), 130) << mode << "\n" << ReadFile(out);
    for (const char* tag : {"emulator", "leader", "vehicle1"}) {
      EXPECT_FALSE(std::filesystem::exists(log + ".d/" + tag + ".txt"))
          << mode << " " << tag << "\n" << ReadFile(out);
    }
    EXPECT_TRUE(std::filesystem::exists(log + ".d/logger.txt")) << mode << "\n" << ReadFile(out);
    // A run that never began lasted no wall time (not the machine's uptime).
    const std::string said = ReadFile(out);
    const std::size_t wall = said.find(" s wall");
    ASSERT_NE(wall, std::string::npos) << said;
    const std::size_t from = said.rfind(' ', wall - 1) + 1;
    EXPECT_LT(std::stod(said.substr(from, wall - from)), 10.0) << mode << "\n" << said;
  }
}

// Real time has no ready handshake: the channel emulator sends its first status, the one
// that carries the scenario's text, as soon as it starts. A logger subscribing after that
// left a log that no analysis could judge ("the log holds no scenario"). shoal run starts
// the processes once the logger has subscribed, in real time as in lockstep.
TEST(LoggerQueue, ALoggerSlowToSubscribeInRealTimeStillRecordsTheScenario) {
  const std::string lib = std::string(SHOAL_BINARY_DIR) + "/tests/libslow_logger_subscribe.so";
  ASSERT_EQ(access(lib.c_str(), R_OK), 0) << lib;
  const std::string log = TmpPath("slow_subscribe_rt.lcmlog");
  setenv("LD_PRELOAD", lib.c_str(), 1);
  setenv("SHOAL_TEST_SUBSCRIBE_DELAY_MS", "1500", 1);
  const auto r = RunShoal("run " + SourcePath("scenarios/paper_example2.toml") +
                              " --mode realtime --duration 3 --json --out " + log,
                          "slow_subscribe_rt");
  unsetenv("LD_PRELOAD");
  unsetenv("SHOAL_TEST_SUBSCRIBE_DELAY_MS");
  const auto j = ParseJson(r.out);
  EXPECT_EQ(j["log_complete"], true) << r.out << r.err;
  EXPECT_GT(j["log_states"].get<double>(), 0) << r.out;
  const auto a = RunShoal("analyze " + log + " --json", "slow_subscribe_rt_analyze");
  const auto aj = ParseJson(a.out);
  EXPECT_EQ(aj["scenario_source"], "log") << a.err;
}

}  // namespace
}  // namespace shoal
