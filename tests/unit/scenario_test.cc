// Tests of scenario/loader: a complete scenario round-trips, defaults apply, every
// validation rule rejects what it should with a located message, and every file in
// tests/data/bad_scenarios/ fails with the message its first line announces.
#include "scenario/loader.h"

#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#ifndef SHOAL_SOURCE_DIR
#error "SHOAL_SOURCE_DIR must be defined as the repository root (see cmake/shoal_test.cmake)"
#endif

namespace shoal {
namespace {

namespace fs = std::filesystem;

// A valid swarm of three followers in a chain 0 -> 1 -> 2 -> 3.
const char kSwarmAndControl[] = R"(
[swarm]
followers = 3
leader_links = [1]
edges = [[2, 1], [3, 2]]

[control]
k1 = 1.0
k2 = 2.0
)";

/// Writes `text` to `path`; returns the path.
std::string WriteFileAt(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

std::string ReadText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

/// The ScenarioError message for `text`, or "" (and a test failure) if it parses.
std::string ErrorOf(const std::string& text, const std::string& path = "test.toml") {
  try {
    ParseScenario(text, path);
  } catch (const ScenarioError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected a ScenarioError for:\n" << text;
  return "";
}

::testing::AssertionResult Contains(const std::string& text, const std::string& part) {
  if (text.find(part) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure()
         << "\"" << text << "\"\n  does not contain\n\"" << part << "\"";
}

TEST(ScenarioLoaderTest, FullScenarioRoundTripsEveryField) {
  // Given a scenario that sets every key
  const std::string text = R"(
[run]
name = "full"
duration_s = 120.5
control_rate_hz = 100
seed = 42

[swarm]
followers = 3
edges = [[2, 1], [3, 2], [3, 1]]
leader_links = [1, 2]
neighbour_timeout_s = 0.75

[control]
k1 = 1
k2 = 2.5
offsets_m = [[-5, 0, 0], [0, -5, 0], [0, 5, 1.5]]

[leader]
path = "waypoints"
waypoints_m = [[0, 0, 5], [50, 0, 5], [50, 50, 10]]
speed_mps = 1.5
loop = true

[channel.delay]
model = "sinusoid"
base_s = 0.3
amplitude_s = 0.2
omega_rad_s = 0.5

[channel.loss]
model = "bernoulli"
probability = 0.05

[[channel.link]]
from = 0
to = 2
delay = { model = "constant", base_s = 0.8 }
loss = { model = "none" }

[[channel.link]]
from = 1
to = 3
delay = { model = "uniform", base_s = 0.4, amplitude_s = 0.1 }

[disturbance]
model = "ocean_current"
speed_mps = 0.4
min_speed_mps = 0.1
max_speed_mps = 0.9
mu_per_s = 0.02
noise_mps = 0.05
direction_rad = 1.0

[vehicle]
tau_max = [120, 15, 12.5, 8, 7]
integrator_step_s = 0.002

[metrics]
position_tol_m = 0.25
velocity_tol_mps = 0.1

[[follower]]
id = 3
position_m = [1, 2, 3]
pitch_rad = -0.2
heading_rad = 3.0
nu = [1, 0.1, 0.2, 0.01, 0.02]
)";

  // When it is parsed
  const Scenario s = ParseScenario(text, "scenarios/full_example.toml");

  // Then every field holds what the file says
  EXPECT_EQ(s.name, "full");
  EXPECT_EQ(s.source_path, "scenarios/full_example.toml");
  EXPECT_EQ(s.source_text, text);
  EXPECT_DOUBLE_EQ(s.duration_s, 120.5);
  EXPECT_DOUBLE_EQ(s.control_rate_hz, 100.0);
  EXPECT_EQ(s.period_us(), 10000);
  EXPECT_EQ(s.seed, 42u);

  EXPECT_EQ(s.followers, 3);
  const std::vector<std::pair<int, int>> edges = {{2, 1}, {3, 2}, {3, 1}};
  EXPECT_EQ(s.edges, edges);
  EXPECT_EQ(s.leader_links, (std::vector<int>{1, 2}));
  EXPECT_DOUBLE_EQ(s.neighbour_timeout_s, 0.75);

  EXPECT_DOUBLE_EQ(s.k1, 1.0);
  EXPECT_DOUBLE_EQ(s.k2, 2.5);
  ASSERT_EQ(s.offsets_m.size(), 3u);
  EXPECT_EQ(s.offsets_m[0], Vec3(-5, 0, 0));
  EXPECT_EQ(s.offsets_m[1], Vec3(0, -5, 0));
  EXPECT_EQ(s.offsets_m[2], Vec3(0, 5, 1.5));

  EXPECT_EQ(s.leader.path, PathKind::kWaypoints);
  ASSERT_EQ(s.leader.waypoints_m.size(), 3u);
  EXPECT_EQ(s.leader.waypoints_m[2], Vec3(50, 50, 10));
  EXPECT_DOUBLE_EQ(s.leader.speed_mps, 1.5);
  EXPECT_TRUE(s.leader.loop);

  EXPECT_EQ(s.delay.kind, DelayKind::kSinusoid);
  EXPECT_DOUBLE_EQ(s.delay.base_s, 0.3);
  EXPECT_DOUBLE_EQ(s.delay.amplitude_s, 0.2);
  EXPECT_DOUBLE_EQ(s.delay.omega_rad_s, 0.5);
  EXPECT_EQ(s.loss.kind, LossKind::kBernoulli);
  EXPECT_DOUBLE_EQ(s.loss.probability, 0.05);

  ASSERT_EQ(s.links.size(), 2u);
  EXPECT_EQ(s.links[0].from, 0);
  EXPECT_EQ(s.links[0].to, 2);
  ASSERT_TRUE(s.links[0].delay.has_value());
  EXPECT_EQ(s.links[0].delay->kind, DelayKind::kConstant);
  EXPECT_DOUBLE_EQ(s.links[0].delay->base_s, 0.8);
  ASSERT_TRUE(s.links[0].loss.has_value());
  EXPECT_EQ(s.links[0].loss->kind, LossKind::kNone);
  EXPECT_EQ(s.links[1].from, 1);
  EXPECT_EQ(s.links[1].to, 3);
  ASSERT_TRUE(s.links[1].delay.has_value());
  EXPECT_EQ(s.links[1].delay->kind, DelayKind::kUniform);
  EXPECT_DOUBLE_EQ(s.links[1].delay->amplitude_s, 0.1);
  EXPECT_FALSE(s.links[1].loss.has_value());

  EXPECT_EQ(s.disturbance.kind, DisturbanceKind::kOceanCurrent);
  EXPECT_DOUBLE_EQ(s.disturbance.current.speed_mps, 0.4);
  EXPECT_DOUBLE_EQ(s.disturbance.current.min_speed_mps, 0.1);
  EXPECT_DOUBLE_EQ(s.disturbance.current.max_speed_mps, 0.9);
  EXPECT_DOUBLE_EQ(s.disturbance.current.mu_per_s, 0.02);
  EXPECT_DOUBLE_EQ(s.disturbance.current.noise_mps, 0.05);
  EXPECT_DOUBLE_EQ(s.disturbance.current.direction_rad, 1.0);

  EXPECT_EQ(s.vehicle.tau_max, (Vec5() << 120, 15, 12.5, 8, 7).finished());
  EXPECT_DOUBLE_EQ(s.vehicle.integrator_step_s, 0.002);
  EXPECT_DOUBLE_EQ(s.metrics.position_tol_m, 0.25);
  EXPECT_DOUBLE_EQ(s.metrics.velocity_tol_mps, 0.1);

  ASSERT_EQ(s.initial.size(), 3u);
  EXPECT_FALSE(s.initial[0].given);
  EXPECT_FALSE(s.initial[1].given);
  EXPECT_TRUE(s.initial[2].given);
  EXPECT_EQ(s.initial[2].eta, (Vec5() << 1, 2, 3, -0.2, 3.0).finished());
  EXPECT_EQ(s.initial[2].nu, (Vec5() << 1, 0.1, 0.2, 0.01, 0.02).finished());
}

TEST(ScenarioLoaderTest, DefaultsApplyToAMinimalScenario) {
  // Given only the required keys
  const Scenario s = ParseScenario(kSwarmAndControl, "some/dir/minimal_chain.toml");

  // Then the defaults of core/scenario.h are in place
  const Scenario defaults;
  EXPECT_EQ(s.name, "minimal_chain");
  EXPECT_EQ(s.duration_s, defaults.duration_s);
  EXPECT_EQ(s.control_rate_hz, defaults.control_rate_hz);
  EXPECT_EQ(s.seed, defaults.seed);
  EXPECT_EQ(s.neighbour_timeout_s, defaults.neighbour_timeout_s);
  ASSERT_EQ(s.offsets_m.size(), 3u);
  for (const Vec3& d : s.offsets_m) EXPECT_EQ(d, Vec3::Zero());
  EXPECT_EQ(s.leader.path, PathKind::kPaperHelix);
  EXPECT_EQ(s.delay.kind, DelayKind::kNone);
  EXPECT_EQ(s.loss.kind, LossKind::kNone);
  EXPECT_TRUE(s.links.empty());
  EXPECT_EQ(s.disturbance.kind, DisturbanceKind::kNone);
  EXPECT_EQ(s.vehicle.tau_max, defaults.vehicle.tau_max);
  EXPECT_EQ(s.vehicle.integrator_step_s, defaults.vehicle.integrator_step_s);
  EXPECT_EQ(s.metrics.position_tol_m, defaults.metrics.position_tol_m);
  EXPECT_EQ(s.metrics.velocity_tol_mps, defaults.metrics.velocity_tol_mps);
  ASSERT_EQ(s.initial.size(), 3u);
  for (const FollowerInit& init : s.initial) EXPECT_FALSE(init.given);
}

TEST(ScenarioLoaderTest, OceanCurrentDefaultsAndLinePath) {
  const Scenario s = ParseScenario(std::string(kSwarmAndControl) + R"(
[leader]
path = "line"
start_m = [1, 2, 3]

[disturbance]
model = "ocean_current"
)",
                                   "t.toml");
  EXPECT_EQ(s.leader.path, PathKind::kLine);
  EXPECT_EQ(s.leader.start_m, Vec3(1, 2, 3));
  EXPECT_EQ(s.leader.velocity_mps, LeaderConfig().velocity_mps);
  const OceanCurrentConfig defaults;
  EXPECT_EQ(s.disturbance.kind, DisturbanceKind::kOceanCurrent);
  EXPECT_EQ(s.disturbance.current.speed_mps, defaults.speed_mps);
  EXPECT_EQ(s.disturbance.current.direction_rad, defaults.direction_rad);
}

TEST(ScenarioLoaderTest, DefaultIntegratorStepNeverExceedsTheControlPeriod) {
  const Scenario s =
      ParseScenario(std::string("[run]\ncontrol_rate_hz = 1000\n") + kSwarmAndControl, "t.toml");
  EXPECT_DOUBLE_EQ(s.vehicle.integrator_step_s, 0.001);
}

TEST(ScenarioLoaderTest, ControlPeriodMayRoundWithinOnePartPerMillion) {
  // 1e6 / 64 = 15625 us exactly; 1e6 / 3.000003 = 333333.0 us within rounding; 3 Hz is
  // 333333 us at exactly 1e-6 relative error, the inclusive edge of the rule.
  EXPECT_EQ(ParseScenario(std::string("[run]\ncontrol_rate_hz = 64\n") + kSwarmAndControl, "t")
                .period_us(),
            15625);
  EXPECT_EQ(
      ParseScenario(std::string("[run]\ncontrol_rate_hz = 3.000003\n") + kSwarmAndControl, "t")
          .period_us(),
      333333);
  EXPECT_EQ(ParseScenario(std::string("[run]\ncontrol_rate_hz = 3\n") + kSwarmAndControl, "t")
                .period_us(),
            333333);
}

TEST(ScenarioLoaderTest, IntegersAreAcceptedWhereNumbersAreExpected) {
  const Scenario s = ParseScenario(R"(
[run]
duration_s = 30
[swarm]
followers = 1
leader_links = [1]
[control]
k1 = 2
k2 = 3
)",
                                   "t.toml");
  EXPECT_DOUBLE_EQ(s.duration_s, 30.0);
  EXPECT_DOUBLE_EQ(s.k1, 2.0);
  EXPECT_DOUBLE_EQ(s.k2, 3.0);
}

TEST(ScenarioLoaderTest, MessageNamesFileLineKeyValueAndFix) {
  const std::string text =
      "[swarm]\nfollowers = 1\nleader_links = [1]\n\n[control]\nk1 = -1\nk2 = 1\n";
  EXPECT_EQ(ErrorOf(text, "scenarios/x.toml"),
            "scenarios/x.toml:6: control.k1: must be a positive number (got -1); "
            "consensus gains k1, k2 must be > 0");
}

TEST(ScenarioLoaderTest, UnknownKeySuggestsTheClosestValidKey) {
  EXPECT_EQ(ErrorOf(std::string("[run]\ndration_s = 5\n") + kSwarmAndControl, "scenarios/x.toml"),
            "scenarios/x.toml:2: run.dration_s: unknown key 'dration_s' in [run]; "
            "did you mean 'duration_s'?");
}

TEST(ScenarioLoaderTest, UnknownKeyWithoutCloseMatchListsTheValidKeys) {
  EXPECT_TRUE(Contains(ErrorOf(std::string("[run]\nfoo_bar_baz = 5\n") + kSwarmAndControl),
                       "test.toml:2: run.foo_bar_baz: unknown key 'foo_bar_baz' in [run]; valid "
                       "keys in [run]: name, duration_s, control_rate_hz, seed"));
}

TEST(ScenarioLoaderTest, MissingKeyReportsTheLineOfItsTable) {
  EXPECT_EQ(
      ErrorOf("# comment\n\n[swarm]\nfollowers = 1\nleader_links = [1]\n\n[control]\nk2 = 1\n"),
      "test.toml:7: control.k1: missing required key; add k1 to [control] "
      "(consensus gains k1, k2 must be > 0)");
}

TEST(ScenarioLoaderTest, MissingTableReportsLineOne) {
  EXPECT_TRUE(Contains(ErrorOf("[swarm]\nfollowers = 1\nleader_links = [1]\n"),
                       "test.toml:1: control.k1: missing required key"));
}

TEST(ScenarioLoaderTest, UnreachableFollowersAreNamed) {
  const std::string text = R"([swarm]
followers = 4
leader_links = [1]
edges = [[3, 1], [4, 2], [2, 4]]
[control]
k1 = 1
k2 = 1
)";
  EXPECT_EQ(ErrorOf(text),
            "test.toml:4: swarm.edges: followers 2, 4 cannot be reached from the leader "
            "(Assumption 1); add leader_links or edges so every follower has a directed path "
            "from the leader");
}

TEST(ScenarioLoaderTest, SyntaxErrorReportsFileLineAndDescription) {
  const std::string message = ErrorOf("[swarm]\nfollowers = 1\nleader_links = [1,,]\n");
  EXPECT_TRUE(Contains(message, "test.toml:3: TOML syntax error: "));
}

TEST(ScenarioLoaderTest, LoadScenarioReadsTheFileVerbatim) {
  const fs::path path = fs::temp_directory_path() / "shoal_loader_test_verbatim.toml";
  const std::string text = std::string("# a comment that must survive\r\n") + kSwarmAndControl;
  std::ofstream(path, std::ios::binary) << text;
  const Scenario s = LoadScenario(path.string());
  fs::remove(path);
  EXPECT_EQ(s.source_text, text);
  EXPECT_EQ(s.source_path, path.string());
  EXPECT_EQ(s.name, "shoal_loader_test_verbatim");
}

TEST(ScenarioLoaderTest, MissingFileCannotBeRead) {
  try {
    LoadScenario("/nonexistent/dir/nothing.toml");
    FAIL() << "expected a ScenarioError";
  } catch (const ScenarioError& e) {
    EXPECT_STREQ(e.what(),
                 "/nonexistent/dir/nothing.toml: cannot read scenario file (No such file or "
                 "directory)");
  }
}

TEST(ScenarioLoaderTest, DirectoryCannotBeRead) {
  const std::string dir = fs::temp_directory_path().string();
  try {
    LoadScenario(dir);
    FAIL() << "expected a ScenarioError";
  } catch (const ScenarioError& e) {
    EXPECT_TRUE(Contains(e.what(), dir + ": cannot read scenario file: it is a directory, "
                                         "not a regular file"));
  }
}

/// The message LoadScenario gives for `path`, or "" if it loads.
std::string LoadError(const std::string& path) {
  try {
    LoadScenario(path);
  } catch (const ScenarioError& e) {
    return e.what();
  }
  return "";
}

// A FIFO would block forever, /dev/zero never ends: neither is opened for reading as a
// scenario, nor is a socket, a symbolic link loop or a file above 16 MiB read at all.
TEST(ScenarioLoaderTest, OnlyRegularFilesOfAtMost16MiBAreRead) {
  const fs::path dir = fs::temp_directory_path() / ("shoal_special_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string fifo = (dir / "fifo.toml").string(), loop = (dir / "loop.toml").string();
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  ASSERT_EQ(symlink(loop.c_str(), loop.c_str()), 0);
  const std::string big = (dir / "big.toml").string();
  fs::resize_file(WriteFileAt(big, ""), (16u << 20) + 1);
  const int sock = socket(AF_UNIX, SOCK_STREAM, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  const std::string sock_path = (dir / "sock.toml").string();
  std::snprintf(addr.sun_path, sizeof(addr.sun_path), "%s", sock_path.c_str());
  ASSERT_EQ(bind(sock, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
  const std::vector<std::pair<std::string, std::string>> cases = {
      {fifo, ": cannot read scenario file: it is a FIFO (named pipe), not a regular file"},
      {"/dev/zero", ": cannot read scenario file: it is a character device, not a regular file"},
      {sock_path, ": cannot read scenario file: it is a socket, not a regular file"},
      {loop, ": cannot read scenario file (Too many levels of symbolic links)"},
      {big, ": cannot read scenario file: 16777217 bytes, larger than the limit of 16777216"}};
  for (const auto& [path, message] : cases) {
    const auto t0 = std::chrono::steady_clock::now();
    EXPECT_TRUE(Contains(LoadError(path), path + message)) << LoadError(path);
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 5.0);
  }
  close(sock);
  fs::remove_all(dir);
}

TEST(ScenarioLoaderTest, UnreadableFileIsRefused) {
  if (geteuid() == 0) GTEST_SKIP() << "root reads files whatever their mode";
  const std::string path = WriteFileAt(
      (fs::temp_directory_path() / ("shoal_unreadable_" + std::to_string(getpid()) + ".toml"))
          .string(),
      "[swarm]\n");
  fs::permissions(path, fs::perms::none);
  EXPECT_TRUE(Contains(LoadError(path), path + ": cannot read scenario file (Permission denied)"));
  fs::remove(path);
}

// A file written by an editor that puts a UTF-8 byte order mark first reads as without it.
TEST(ScenarioLoaderTest, ByteOrderMarkIsSkipped) {
  const std::string text =
      "[swarm]\nfollowers = 1\nleader_links = [1]\n[control]\nk1 = 1\nk2 = 2\n";
  EXPECT_EQ(ParseScenario("\xEF\xBB\xBF" + text, "bom.toml").followers, 1);
  EXPECT_TRUE(Contains(ErrorOf("\xEF\xBB\xBF[run]\nduration_s = -1\n" + text, "bom.toml"),
                       "bom.toml:2: run.duration_s: must be a positive number"));
}

TEST(ScenarioLoaderTest, RunNameIsAPlainFileName) {
  const std::string rest =
      "[swarm]\nfollowers = 1\nleader_links = [1]\n[control]\nk1 = 1\nk2 = 2\n";
  for (const std::string& name :
       std::vector<std::string>{"helix_4", "a.b-c", "X", std::string(100, 'n')}) {
    EXPECT_EQ(ParseScenario("[run]\nname = \"" + name + "\"\n" + rest, "t.toml").name, name);
  }
  for (const std::string& name : std::vector<std::string>
       {"../x", "/tmp/x", "a/b", ".", "..", ".x", "a b", "a\\\\b", "a:b", std::string(101, 'n')}) {
    EXPECT_TRUE(Contains(ErrorOf("[run]\nname = \"" + name + "\"\n" + rest, "t.toml"),
                         "t.toml:2: run.name: must be a plain file name"))
        << name;
  }
  // Without run.name, the file's name (which holds no '/') is the scenario's name.
  EXPECT_EQ(ParseScenario(rest, "/some/dir/my run.toml").name, "my run");
}

TEST(ScenarioLoaderTest, ExampleInTheDocumentationIsValid) {
  // The first ```toml block of docs/scenario.md is the complete example users copy.
  const std::string doc = ReadText(fs::path(SHOAL_SOURCE_DIR) / "docs" / "scenario.md");
  const std::string fence = "```toml\n";
  const std::size_t begin = doc.find(fence);
  ASSERT_NE(begin, std::string::npos);
  const std::size_t end = doc.find("```", begin + fence.size());
  ASSERT_NE(end, std::string::npos);
  const Scenario s = ParseScenario(doc.substr(begin + fence.size(), end - begin - fence.size()),
                                   "docs/scenario.md");
  EXPECT_GT(s.followers, 0);
}

// Acoustic, trace, Gilbert-Elliott and modem keys load as written.
TEST(ScenarioLoaderTest, AcousticTraceGilbertElliottAndModemsLoad) {
  const fs::path dir = fs::path(::testing::TempDir()) / "shoal_trace_ok";
  fs::remove_all(dir);  // what an earlier run left
  fs::create_directories(dir / "traces");
  WriteFileAt((dir / "traces/trial.csv").string(),
              "# from a sea trial\nt_s, delay_s\n0, 0.8\n10.5, 1.2\n\n20,0.9\n");
  const std::string text = std::string(kSwarmAndControl) +
                           "[channel]\nmodem_min_interval_s = 1.5\n"
                           "[channel.delay]\nmodel = \"acoustic\"\nmax_range_m = 2000\n"
                           "processing_s = 0.2\njitter_s = 0.05\nloss_at_max_range = 0.3\n"
                           "[channel.loss]\nmodel = \"gilbert_elliott\"\np_good_to_bad = 0.05\n"
                           "p_bad_to_good = 0.3\nloss_good = 0.01\nloss_bad = 1\n"
                           "[[channel.link]]\nfrom = 0\nto = 1\n"
                           "delay = { model = \"trace\", file = \"traces/trial.csv\", "
                           "interpolation = \"hold\" }\n"
                           "[[channel.modem]]\nid = 2\nmin_interval_s = 0\n";
  const Scenario s = LoadScenario(WriteFileAt((dir / "s.toml").string(), text));
  EXPECT_EQ(s.delay.kind, DelayKind::kAcoustic);
  EXPECT_EQ(s.delay.sound_speed_mps, 1500.0);  // default
  EXPECT_EQ(s.delay.max_range_m, 2000.0);
  EXPECT_EQ(s.delay.processing_s, 0.2);
  EXPECT_EQ(s.delay.jitter_s, 0.05);
  EXPECT_EQ(s.delay.loss_at_max_range, 0.3);
  EXPECT_EQ(s.loss.kind, LossKind::kGilbertElliott);
  EXPECT_EQ(s.loss.p_good_to_bad, 0.05);
  EXPECT_EQ(s.loss.p_bad_to_good, 0.3);
  EXPECT_EQ(s.loss.loss_good, 0.01);
  EXPECT_EQ(s.loss.loss_bad, 1.0);
  EXPECT_EQ(s.modem_min_interval_s, 1.5);
  ASSERT_EQ(s.modems.size(), 1u);
  EXPECT_EQ(s.modems[0].id, 2);
  EXPECT_EQ(s.modems[0].min_interval_s, 0.0);
  ASSERT_EQ(s.links.size(), 1u);
  const DelayConfig& trace = *s.links[0].delay;
  ASSERT_EQ(trace.kind, DelayKind::kTrace);
  ASSERT_TRUE(trace.trace);
  EXPECT_TRUE(trace.trace->hold);
  EXPECT_EQ(trace.trace->file, "traces/trial.csv");
  EXPECT_EQ(trace.trace->t_s, (std::vector<double>{0.0, 10.5, 20.0}));
  EXPECT_EQ(trace.trace->delay_s, (std::vector<double>{0.8, 1.2, 0.9}));
  // The path is relative to the scenario file, not to the working directory.
  EXPECT_FALSE(fs::exists("traces/trial.csv"));
}

// Text that does not come from a file (a log's copy) resolves a trace in the working
// directory.
TEST(ScenarioLoaderTest, TraceOfTextWithoutAFileIsReadFromTheWorkingDirectory) {
  const fs::path dir = fs::path(::testing::TempDir()) / "shoal_trace_cwd";
  fs::remove_all(dir);
  fs::create_directories(dir);
  WriteFileAt((dir / "cwd_trace.csv").string(), "0, 0.4\n");
  const std::string text = std::string(kSwarmAndControl) +
                           "[channel.delay]\nmodel = \"trace\"\nfile = \"cwd_trace.csv\"\n";
  const fs::path before = fs::current_path();
  fs::current_path(dir);
  Scenario s;
  std::string error;
  try {
    s = ParseScenario(text, "scenario text in x.lcmlog (SHOAL_STATUS)");
  } catch (const ScenarioError& e) {
    error = e.what();
  }
  fs::current_path(before);
  ASSERT_EQ(error, "");
  ASSERT_TRUE(s.delay.trace);
  EXPECT_EQ(s.delay.trace->delay_s, std::vector<double>{0.4});
}

// A bad trace is refused with the CSV's file and line, inside the scenario's located message.
TEST(ScenarioLoaderTest, BadTraceRowsAreRefusedAtTheirCsvLine) {
  const fs::path dir = fs::path(::testing::TempDir()) / "shoal_trace_bad";
  fs::remove_all(dir);  // what an earlier run left
  fs::create_directories(dir);
  const std::string scenario = std::string(kSwarmAndControl) +
                               "[channel.delay]\nmodel = \"trace\"\nfile = \"t.csv\"\n";
  const std::string path = WriteFileAt((dir / "s.toml").string(), scenario);
  const std::string csv = (dir / "t.csv").string();
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"0, 0.1\n1, -0.5\n", csv + ":2: delay_s must be a number of seconds in [0, 1e9]"},
      {"0, 0.1\n1, nan\n", csv + ":2: delay_s must be"},
      {"0, 0.1\n\n0, 0.2\n", csv + ":3: t_s must increase strictly"},
      {"0, 0.1\n2, 0.2\n1, 0.2\n", csv + ":3: t_s must increase strictly"},
      {"0, 0.1, 3\n", csv + ":1: a trace row needs exactly two fields"},
      {"x, 0.1\n", csv + ":1: t_s must be a number"},
      {"# only a comment\nt_s,delay_s\n", csv + ":1: the trace has no rows"},
      {"0, 1e308\n", csv + ":1: delay_s must be"},
      {"0, 0.1\nt_s, delay_s\n", csv + ":2: t_s must be"},  // a header only comes first
  };
  for (const auto& [rows, expected] : cases) {
    WriteFileAt(csv, rows);
    std::string message;
    try {
      LoadScenario(path);
    } catch (const ScenarioError& e) {
      message = e.what();
    }
    EXPECT_EQ(message.rfind(path + ":12: channel.delay.file: " + expected, 0), 0u)
        << rows << "\n" << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
  fs::remove(csv);
  fs::create_directory(csv);  // not a regular file
  const std::string message = ErrorOf(scenario, path);
  EXPECT_TRUE(Contains(message, "it is a directory, not a regular file")) << message;
}

// ---------------------------------------------------------------------------------------
// One rule, one snippet.

struct RuleCase {
  const char* name;
  std::string text;
  std::string expected;  // a substring of the message
};

std::ostream& operator<<(std::ostream& os, const RuleCase& c) { return os << c.name; }

std::vector<RuleCase> RuleCases() {
  const std::string base = kSwarmAndControl;
  const std::string chain =
      "[swarm]\nfollowers = 3\nleader_links = [1]\nedges = [[2, 1], [3, 2]]\n";
  const std::string gains = "[control]\nk1 = 1\nk2 = 1\n";
  return {
      // Top level.
      {"UnknownTableSuggestion", base + "[contrl]\nk1 = 1\n",
       "test.toml:10: contrl: unknown table [contrl]; did you mean [control]?"},
      {"RunNotATable", "run = 5\n" + base, "test.toml:1: run: must be a table (got 5)"},
      {"KeyInWrongTable", "[run]\nk1 = 1\n" + base,
       "run.k1: unknown key 'k1' in [run]; 'k1' belongs in [control]"},
      // [run]
      {"NameNotString", "[run]\nname = 5\n" + base, "run.name: must be a string (got 5)"},
      {"NameEmpty", "[run]\nname = \"\"\n" + base, "run.name: must not be empty"},
      {"DurationNegative", "[run]\nduration_s = -1\n" + base,
       "run.duration_s: must be a positive number of seconds"},
      {"DurationInfinite", "[run]\nduration_s = inf\n" + base,
       "run.duration_s: must be a finite number (got inf)"},
      {"RateTooHigh", "[run]\ncontrol_rate_hz = 20000\n" + base,
       "run.control_rate_hz: must be a positive number <= 10000 (got 20000)"},
      {"RateNotWholeMicros", "[run]\ncontrol_rate_hz = 30\n" + base,
       "run.control_rate_hz: the control period 1e6/rate must be a whole number of "
       "microseconds (got 30, a period of 33333.333"},
      {"RateJustOffWholeMicros", "[run]\ncontrol_rate_hz = 3.1\n" + base,
       "run.control_rate_hz: the control period"},
      {"SeedFloat", "[run]\nseed = 1.0\n" + base, "run.seed: must be an integer (got 1.0)"},
      {"SeedNegative", "[run]\nseed = -1\n" + base, "run.seed: must be an integer >= 0 (got -1)"},
      // [swarm]
      {"FollowersZero", "[swarm]\nfollowers = 0\nleader_links = [1]\n" + gains,
       "swarm.followers: must be an integer in 1..1000 (got 0)"},
      {"FollowersString", "[swarm]\nfollowers = \"3\"\nleader_links = [1]\n" + gains,
       "swarm.followers: must be an integer (got \"3\")"},
      {"FollowersFloat", "[swarm]\nfollowers = 2.5\nleader_links = [1]\n" + gains,
       "swarm.followers: must be an integer (got 2.5)"},
      {"EdgeNotAPair", "[swarm]\nfollowers = 2\nleader_links = [1]\nedges = [[2]]\n" + gains,
       "swarm.edges[0]: must be a pair [i, j] of follower ids (got [2])"},
      {"EdgeFloatId", "[swarm]\nfollowers = 2\nleader_links = [1]\nedges = [[2, 1.0]]\n" + gains,
       "swarm.edges[0][1]: must be an integer (got 1.0)"},
      {"EdgeIdZero", "[swarm]\nfollowers = 2\nleader_links = [1]\nedges = [[0, 1]]\n" + gains,
       "swarm.edges[0][0]: follower ids must be in 1..2 (got 0)"},
      {"EdgesNotArray", "[swarm]\nfollowers = 2\nleader_links = [1]\nedges = 3\n" + gains,
       "swarm.edges: must be an array of [i, j] pairs (got 3)"},
      {"SelfEdge", "[swarm]\nfollowers = 2\nleader_links = [1]\nedges = [[1, 1]]\n" + gains,
       "swarm.edges[0]: a follower cannot receive from itself (got [1, 1])"},
      {"DuplicateEdge",
       "[swarm]\nfollowers = 2\nleader_links = [1]\nedges = [[2, 1], [2, 1]]\n" + gains,
       "swarm.edges[1]: duplicate edge (got [2, 1])"},
      {"LeaderLinksMissing", "[swarm]\nfollowers = 1\n" + gains,
       "test.toml:1: swarm.leader_links: missing required key"},
      {"LeaderLinksEmpty", "[swarm]\nfollowers = 1\nleader_links = []\n" + gains,
       "swarm.leader_links: must list at least one follower (got [])"},
      {"LeaderLinksNotArray", "[swarm]\nfollowers = 1\nleader_links = 1\n" + gains,
       "swarm.leader_links: must be an array of follower ids (got 1)"},
      {"LeaderLinkOutOfRange", "[swarm]\nfollowers = 1\nleader_links = [2]\n" + gains,
       "swarm.leader_links[0]: follower ids must be in 1..1 (got 2)"},
      {"LeaderLinkDuplicate", "[swarm]\nfollowers = 2\nleader_links = [1, 2, 1]\n" + gains,
       "swarm.leader_links[2]: duplicate follower id (got 1)"},
      {"TimeoutZero",
       "[swarm]\nfollowers = 1\nleader_links = [1]\nneighbour_timeout_s = 0\n" + gains,
       "swarm.neighbour_timeout_s: must be a positive number of seconds"},
      {"OneUnreachableFollower",
       "[swarm]\nfollowers = 3\nleader_links = [1]\nedges = [[2, 1]]\n" + gains,
       "test.toml:4: swarm.edges: follower 3 cannot be reached from the leader (Assumption 1)"},
      {"UnreachableWithoutEdges", "[swarm]\nfollowers = 2\nleader_links = [2]\n" + gains,
       "test.toml:1: swarm.edges: follower 1 cannot be reached from the leader"},
      // [control]
      {"K1Missing", chain + "[control]\nk2 = 1\n", "control.k1: missing required key"},
      {"K2Zero", chain + "[control]\nk1 = 1\nk2 = 0\n",
       "control.k2: must be a positive number (got 0)"},
      {"K1Nan", chain + "[control]\nk1 = nan\nk2 = 1\n",
       "control.k1: must be a finite number (got nan)"},
      {"OffsetsWrongCount", chain + gains + "offsets_m = [[0, 0, 0]]\n",
       "control.offsets_m: must have exactly 3 entries, one [x, y, z] per follower"},
      {"OffsetsNotArray", chain + gains + "offsets_m = 5\n",
       "control.offsets_m: must have exactly 3 entries"},
      {"OffsetWithTwoNumbers", chain + gains + "offsets_m = [[0, 0, 0], [1, 2], [0, 0, 0]]\n",
       "control.offsets_m[1]: must be an array of 3 numbers (got [1, 2])"},
      {"OffsetString", chain + gains + "offsets_m = [[0, 0, 0], [1, 2, \"x\"], [0, 0, 0]]\n",
       "control.offsets_m[1][2]: must be a number (got \"x\")"},
      // [leader]
      {"UnknownPath", base + "[leader]\npath = \"circle\"\n",
       "leader.path: unknown leader path (got \"circle\"); use one of \"paper_helix\", \"line\", "
       "\"waypoints\""},
      {"PathTypoSuggestion", base + "[leader]\npath = \"lin\"\n", "did you mean \"line\"?"},
      {"PathNotString", base + "[leader]\npath = 1\n", "leader.path: must be a string (got 1)"},
      {"HelixWithLineKey", base + "[leader]\nstart_m = [0, 0, 0]\n",
       "leader.start_m: not used by leader path \"paper_helix\" (got [0, 0, 0]); remove it, or "
       "set path = \"line\""},
      {"LineVelocityTwoNumbers", base + "[leader]\npath = \"line\"\nvelocity_mps = [1, 0]\n",
       "leader.velocity_mps: must be an array of 3 numbers (got [1, 0])"},
      // The followers start at the leader's attitude, which its path sets.
      {"LineTooSteep", base + "[leader]\npath = \"line\"\nvelocity_mps = [0, 0, 1]\n",
       "leader.velocity_mps: the path climbs or dives at 90.0 deg (got [0, 0, 1]); a REMUS "
       "100 pitches at most 30 deg (0.5236 rad)"},
      {"WaypointLegTooSteep",
       base + "[leader]\npath = \"waypoints\"\nwaypoints_m = [[0, 0, 0], [10, 0, 0], [11, 0, 10]]\n",
       "leader.waypoints_m[2]: the leg to this waypoint climbs or dives at 84.3 deg"},
      {"LoopClosingLegTooSteep",
       base + "[leader]\npath = \"waypoints\"\nloop = true\n"
              "waypoints_m = [[0, 0, 0], [20, 0, 5], [1, 0, 10]]\n",
       "leader.waypoints_m: the leg back to the first waypoint (loop = true) climbs or dives at "
       "84.3 deg"},
      {"WaypointsMissing", base + "[leader]\npath = \"waypoints\"\n",
       "test.toml:10: leader.waypoints_m: missing required key"},
      {"WaypointsOnePoint", base + "[leader]\npath = \"waypoints\"\nwaypoints_m = [[0, 0, 0]]\n",
       "leader.waypoints_m: must have at least 2 points"},
      {"WaypointRepeated",
       base + "[leader]\npath = \"waypoints\"\nwaypoints_m = [[0, 0, 0], [1, 0, 0], [1, 0, 0]]\n",
       "leader.waypoints_m[2]: repeats the previous waypoint"},
      {"LoopRepeatsFirst",
       base + "[leader]\npath = \"waypoints\"\nloop = true\nwaypoints_m = [[0, 0, 0], [1, 0, 0], "
              "[0, 0, 0]]\n",
       "leader.waypoints_m[2]: repeats the first waypoint while loop = true"},
      {"WaypointSpeedZero",
       base +
           "[leader]\npath = \"waypoints\"\nwaypoints_m = [[0, 0, 0], [1, 0, 0]]\nspeed_mps = 0\n",
       "leader.speed_mps: must be a positive number (got 0)"},
      // [channel.delay] and [channel.loss]
      {"DelayKeyWithDefaultModel", base + "[channel.delay]\nbase_s = 0.1\n",
       "channel.delay.base_s: not used by delay model \"none\" (got 0.1); remove it, or set model "
       "= \"constant\""},
      {"ConstantWithoutBase", base + "[channel.delay]\nmodel = \"constant\"\n",
       "test.toml:10: channel.delay.base_s: missing required key"},
      {"NegativeBase", base + "[channel.delay]\nmodel = \"constant\"\nbase_s = -0.1\n",
       "channel.delay.base_s: must be a number of seconds in [0, 1e9] (got -0.1)"},
      {"SinusoidWithoutOmega",
       base + "[channel.delay]\nmodel = \"sinusoid\"\nbase_s = 0.2\namplitude_s = 0.1\n",
       "channel.delay.omega_rad_s: missing required key"},
      {"SinusoidTooFast",
       base + "[channel.delay]\nmodel = \"sinusoid\"\nbase_s = 2\namplitude_s = 2\nomega_rad_s = "
              "0.5\n",
       "test.toml:14: channel.delay.omega_rad_s: amplitude_s * omega_rad_s must be < 1 "
       "(Assumption 3: d tau/dt < 1) (got 2 * 0.5 = 1)"},
      {"UniformWithOmega",
       base + "[channel.delay]\nmodel = \"uniform\"\nbase_s = 0.2\namplitude_s = 0.1\nomega_rad_s "
              "= 1\n",
       "channel.delay.omega_rad_s: not used by delay model \"uniform\" (got 1); remove it, or set "
       "model = \"sinusoid\""},
      {"DelayModelNotString", base + "[channel.delay]\nmodel = 3\n",
       "channel.delay.model: must be a string (got 3)"},
      {"DelayModelTypo", base + "[channel.delay]\nmodel = \"constnt\"\nbase_s = 1\n",
       "did you mean \"constant\"?"},
      {"DelayKeyTypo", base + "[channel.delay]\nmodel = \"constant\"\nbase = 1\n",
       "channel.delay.base: unknown key 'base' in [channel.delay]; did you mean 'base_s'?"},
      {"DelayTableTypo", base + "[channel.dealy]\nmodel = \"none\"\n",
       "channel.dealy: unknown table [channel.dealy]; did you mean [channel.delay]?"},
      {"UnknownLossModel", base + "[channel.loss]\nmodel = \"gilbert\"\n",
       "channel.loss.model: unknown loss model (got \"gilbert\"); use one of \"none\", "
       "\"bernoulli\""},
      {"NegativeProbability", base + "[channel.loss]\nmodel = \"bernoulli\"\nprobability = -0.1\n",
       "channel.loss.probability: must be in [0, 1) (got -0.1)"},
      {"ProbabilityOne", base + "[channel.loss]\nmodel = \"bernoulli\"\nprobability = 1\n",
       "channel.loss.probability: must be in [0, 1) (got 1)"},
      {"ProbabilityWithoutModel", base + "[channel.loss]\nprobability = 0.1\n",
       "channel.loss.probability: not used by loss model \"none\""},
      {"UnknownChannelKey", base + "[channel]\nfoo = 1\n",
       "channel.foo: unknown key 'foo' in [channel]; valid keys in [channel]: delay, loss, link"},
      // [[channel.link]]
      {"LinkNotArrayOfTables", base + "[channel.link]\nfrom = 0\nto = 1\n",
       "channel.link: must be an array of tables"},
      {"LinkFromOutOfRange", base + "[[channel.link]]\nfrom = 5\nto = 1\n",
       "channel.link[0].from: must be 0 (the leader) or a follower id in 1..3 (got 5)"},
      {"LinkToLeader", base + "[[channel.link]]\nfrom = 1\nto = 0\n",
       "channel.link[0].to: must be a follower id in 1..3 (got 0)"},
      {"LinkMissingTo", base + "[[channel.link]]\nfrom = 1\n",
       "test.toml:10: channel.link[0].to: missing required key"},
      {"LinkFromLeaderNotPinned", base + "[[channel.link]]\nfrom = 0\nto = 2\n",
       "test.toml:11: channel.link[0]: the link from the leader to follower 2 is not a link of the "
       "topology (got from = 0, to = 2); overrides apply to existing links only: add 2 to "
       "swarm.leader_links, or fix from/to"},
      {"LinkReversed", base + "[[channel.link]]\nfrom = 2\nto = 1\n", "add [1, 2] to swarm.edges"},
      {"LinkDuplicate",
       base + "[[channel.link]]\nfrom = 1\nto = 2\n[[channel.link]]\nfrom = 1\nto = 2\n",
       "channel.link[1]: duplicate override of the link from follower 1 to follower 2"},
      {"LinkDelayTooFast",
       base + "[[channel.link]]\nfrom = 1\nto = 2\ndelay = { model = \"sinusoid\", base_s = 1, "
              "amplitude_s = 1, omega_rad_s = 2 }\n",
       "channel.link[0].delay.omega_rad_s: amplitude_s * omega_rad_s must be < 1"},
      {"LinkLossNotTable", base + "[[channel.link]]\nfrom = 1\nto = 2\nloss = 0.5\n",
       "channel.link[0].loss: must be a table (got 0.5)"},
      {"LinkLossInvalid",
       base + "[[channel.link]]\nfrom = 1\nto = 2\nloss = { model = \"bernoulli\", probability = 2 "
              "}\n",
       "channel.link[0].loss.probability: must be in [0, 1) (got 2)"},
      {"LinkKeyTypo", base + "[[channel.link]]\nfrom = 1\nto = 2\ndealy = { model = \"none\" }\n",
       "channel.link[0].dealy: unknown key 'dealy' in [[channel.link]]; did you mean 'delay'?"},
      {"LinkInlineKeyTypo",
       base + "[[channel.link]]\nfrom = 1\nto = 2\nloss = { model = \"none\", probabilty = 0 }\n",
       "channel.link[0].loss.probabilty: unknown key 'probabilty' in channel.link[0].loss; did "
       "you mean 'probability'?"},
      // [disturbance]
      {"UnknownDisturbance", base + "[disturbance]\nmodel = \"storm\"\n",
       "disturbance.model: unknown disturbance model (got \"storm\")"},
      {"PaperExampleWithCurrentKey",
       base + "[disturbance]\nmodel = \"paper_example2\"\nspeed_mps = 1\n",
       "disturbance.speed_mps: not used by disturbance model \"paper_example2\""},
      {"CurrentMuZero", base + "[disturbance]\nmodel = \"ocean_current\"\nmu_per_s = 0\n",
       "disturbance.mu_per_s: must be a positive number (got 0)"},
      {"CurrentNoiseNegative", base + "[disturbance]\nmodel = \"ocean_current\"\nnoise_mps = -1\n",
       "disturbance.noise_mps: must be a number >= 0 (got -1)"},
      {"CurrentMinAboveMax",
       base + "[disturbance]\nmodel = \"ocean_current\"\nmin_speed_mps = 2\nmax_speed_mps = 1\n",
       "test.toml:12: disturbance.min_speed_mps: must not exceed max_speed_mps (got "
       "min_speed_mps = 2, max_speed_mps = 1)"},
      {"CurrentSpeedBelowMin",
       base + "[disturbance]\nmodel = \"ocean_current\"\nmin_speed_mps = 0.6\n",
       "disturbance.speed_mps: must lie in [min_speed_mps, max_speed_mps] (got 0.5 outside [0.6, "
       "1])"},
      // [vehicle] and [metrics]
      {"TauMaxZeroEntry", base + "[vehicle]\ntau_max = [100, 10, 0, 6, 6]\n",
       "vehicle.tau_max[2]: must be a positive number (got 0)"},
      {"TauMaxSixEntries", base + "[vehicle]\ntau_max = [100, 10, 10, 6, 6, 1]\n",
       "vehicle.tau_max: must be an array of 5 numbers"},
      {"StepZero", base + "[vehicle]\nintegrator_step_s = 0\n",
       "vehicle.integrator_step_s: must be a positive number (got 0)"},
      {"StepAboveHighRatePeriod",
       "[run]\ncontrol_rate_hz = 1000\n" + base + "[vehicle]\nintegrator_step_s = 0.002\n",
       "vehicle.integrator_step_s: must not exceed the control period (got 0.002); the RK4 step "
       "must fit in one control period (0.001 s at 1000 Hz)"},
      {"StepFarBelowThePeriod", base + "[vehicle]\nintegrator_step_s = 1e-9\n",
       "vehicle.integrator_step_s: must be at least 1/100000 of the control period (2e-07 s)"},
      {"DefaultStepFarBelowASlowPeriod", "[run]\ncontrol_rate_hz = 0.0001\nduration_s = 1e6\n" + base,
       "vehicle.integrator_step_s: the default RK4 step (0.01 s) is less than 1/100000 of the "
       "control period (10000 s)"},
      {"RateSlowerThanTheDefaultRun", "[run]\ncontrol_rate_hz = 1e-6\n" + base,
       "run.control_rate_hz: its control period (1000000 s) is longer than the run (duration_s, "
       "default 600 s)"},
      {"PositionTolZero", base + "[metrics]\nposition_tol_m = 0\n",
       "metrics.position_tol_m: must be a positive number (got 0)"},
      {"VelocityTolNegative", base + "[metrics]\nvelocity_tol_mps = -1\n",
       "metrics.velocity_tol_mps: must be a positive number (got -1)"},
      // Acoustic delay, trace delay, Gilbert-Elliott loss, modems.
      {"AcousticWithoutMaxRange", base + "[channel.delay]\nmodel = \"acoustic\"\n",
       "test.toml:10: channel.delay.max_range_m: missing required key"},
      {"AcousticSoundSpeedZero",
       base + "[channel.delay]\nmodel = \"acoustic\"\nmax_range_m = 100\nsound_speed_mps = 0\n",
       "channel.delay.sound_speed_mps: must be a speed in [1, 1e5] m/s (got 0)"},
      {"AcousticSoundFarTooSlow",
       base + "[channel.delay]\nmodel = \"acoustic\"\nmax_range_m = 100\nsound_speed_mps = 1e-12\n",
       "channel.delay.sound_speed_mps: must be a speed in [1, 1e5] m/s (got 1e-12)"},
      {"AcousticLossAboveOne",
       base + "[channel.delay]\nmodel = \"acoustic\"\nmax_range_m = 100\nloss_at_max_range = 1.5\n",
       "channel.delay.loss_at_max_range: must be in [0, 1] (got 1.5)"},
      {"AcousticKeyUnderConstant",
       base + "[channel.delay]\nmodel = \"constant\"\nbase_s = 1\nmax_range_m = 100\n",
       "channel.delay.max_range_m: not used by delay model \"constant\" (got 100); remove it, or "
       "set model = \"acoustic\""},
      {"AcousticKeyTypo",
       base + "[channel.delay]\nmodel = \"acoustic\"\nmax_range_m = 100\nproccessing_s = 1\n",
       "did you mean 'processing_s'?"},
      {"TraceWithoutFile", base + "[channel.delay]\nmodel = \"trace\"\n",
       "channel.delay.file: missing required key"},
      {"TraceMissingFile", base + "[channel.delay]\nmodel = \"trace\"\nfile = \"no_such.csv\"\n",
       "test.toml:12: channel.delay.file: no_such.csv: cannot read delay trace (No such file"},
      {"TraceBadInterpolation",
       base + "[channel.delay]\nmodel = \"trace\"\nfile = \"x.csv\"\ninterpolation = \"cubic\"\n",
       "channel.delay.interpolation: unknown interpolation (got \"cubic\")"},
      {"GilbertElliottMissingKey",
       base + "[channel.loss]\nmodel = \"gilbert_elliott\"\np_good_to_bad = 0.1\n",
       "channel.loss.p_bad_to_good: missing required key"},
      {"GilbertElliottZeroTransition",
       base + "[channel.loss]\nmodel = \"gilbert_elliott\"\np_good_to_bad = 0\n",
       "channel.loss.p_good_to_bad: must be in (0, 1] (got 0)"},
      {"GilbertElliottLossGoodOne",
       base + "[channel.loss]\nmodel = \"gilbert_elliott\"\np_good_to_bad = 0.1\n"
              "p_bad_to_good = 0.1\nloss_good = 1\nloss_bad = 1\n",
       "channel.loss.loss_good: must be in [0, 1) (got 1)"},
      {"GilbertElliottKeyUnderBernoulli",
       base + "[channel.loss]\nmodel = \"bernoulli\"\nprobability = 0.1\nloss_bad = 1\n",
       "channel.loss.loss_bad: not used by loss model \"bernoulli\""},
      {"ModemIntervalNegative", base + "[channel]\nmodem_min_interval_s = -1\n",
       "channel.modem_min_interval_s: must be a number of seconds in [0, 1e9] (got -1)"},
      {"ModemUnknownVehicle", base + "[[channel.modem]]\nid = 4\nmin_interval_s = 1\n",
       "channel.modem[0].id: must be 0 (the leader) or a follower id in 1..3 (got 4)"},
      {"ModemDuplicate",
       base + "[[channel.modem]]\nid = 1\nmin_interval_s = 1\n[[channel.modem]]\nid = 1\n"
              "min_interval_s = 2\n",
       "test.toml:14: channel.modem[1].id: duplicate modem id (got 1)"},
      {"ModemMissingInterval", base + "[[channel.modem]]\nid = 1\n",
       "channel.modem[0].min_interval_s: missing required key"},
      {"ModemKeyTypo", base + "[[channel.modem]]\nid = 1\nmin_interval = 1\n",
       "did you mean 'min_interval_s'?"},
      // [[follower]]
      {"FollowerKeyTypo", base + "[[follower]]\nid = 1\npositon_m = [0, 0, 0]\n",
       "follower[0].positon_m: unknown key 'positon_m' in [[follower]]; did you mean "
       "'position_m'?"},
      {"FollowerMissingId", base + "[[follower]]\nposition_m = [0, 0, 0]\n",
       "test.toml:10: follower[0].id: missing required key"},
      {"FollowerIdOutOfRange", base + "[[follower]]\nid = 4\n",
       "follower[0].id: must be a follower id in 1..3 (got 4)"},
      {"FollowerDuplicate", base + "[[follower]]\nid = 2\n[[follower]]\nid = 2\n",
       "test.toml:13: follower[1].id: duplicate follower id (got 2)"},
      {"FollowerNuThreeEntries", base + "[[follower]]\nid = 1\nnu = [1, 0, 0]\n",
       "follower[0].nu: must be an array of 5 numbers (got [1, 0, 0])"},
      {"FollowerPitchNegative", base + "[[follower]]\nid = 1\npitch_rad = -0.6\n",
       "follower[0].pitch_rad: must satisfy |pitch_rad| < 0.5236 (30 deg) (got -0.6)"},
      {"FollowerPitchExactlyThirtyDegrees",
       base + "[[follower]]\nid = 1\npitch_rad = 0.5235987755982988\n",
       "follower[0].pitch_rad: must satisfy |pitch_rad| < 0.5236"},
      {"FollowerHeadingInf", base + "[[follower]]\nid = 1\nheading_rad = -inf\n",
       "follower[0].heading_rad: must be a finite number (got -inf)"},
      {"FollowerPlainTable", base + "[follower]\nid = 1\n", "follower: must be an array of tables"},
  };
}

class ScenarioRuleTest : public ::testing::TestWithParam<RuleCase> {};

TEST_P(ScenarioRuleTest, IsRejectedWithLocatedMessage) {
  const RuleCase& c = GetParam();
  const std::string message = ErrorOf(c.text);
  EXPECT_TRUE(Contains(message, c.expected)) << "scenario:\n" << c.text;
  EXPECT_TRUE(std::regex_search(message, std::regex("^test\\.toml:[0-9]+: "))) << message;
}

INSTANTIATE_TEST_SUITE_P(Rules, ScenarioRuleTest, ::testing::ValuesIn(RuleCases()),
                         [](const ::testing::TestParamInfo<RuleCase>& info) {
                           return std::string(info.param.name);
                         });

// ---------------------------------------------------------------------------------------
// tests/data/bad_scenarios/*.toml: the first line of each is "# expect: <substring>", the
// second "# at: line <n>, key <dotted key>": where the message must point. (For the TOML
// syntax error, whose message names no key, "TOML syntax error" stands in its place.)

fs::path BadScenarioDir() { return fs::path(SHOAL_SOURCE_DIR) / "tests/data/bad_scenarios"; }

std::vector<std::string> BadScenarioFiles() {
  std::vector<std::string> files;
  std::error_code error;
  for (const auto& entry : fs::directory_iterator(BadScenarioDir(), error)) {
    if (entry.path().extension() == ".toml") files.push_back(entry.path().filename().string());
  }
  std::sort(files.begin(), files.end());
  return files;
}

/// The second line of a fixture, "# at: line <n>, key <key>", as "<n>: <key>: ".
std::string DeclaredPlace(const std::string& text) {
  static const std::regex at("^# expect: [^\n]*\n# at: line ([0-9]+), key ([^\n]+)\n");
  std::smatch m;
  if (!std::regex_search(text, m, at)) return "";
  return m[1].str() + ": " + m[2].str() + ": ";
}

// Every fixture is refused the way a command refuses it before exiting with status 2: one
// line on stderr, "<who>: <file>:<line>: <key>: ...", naming exactly the line and the key
// the fixture declares. A loader that accepted the file, pointed at the table instead of
// the value (or at a line off by one), or spelled the key path differently fails here.
TEST(BadScenarioFilesTest, EachIsRefusedAtTheLineAndKeyItDeclares) {
  const std::vector<std::string> files = BadScenarioFiles();
  ASSERT_GE(files.size(), 20u) << "no fixtures found in " << BadScenarioDir();
  for (const std::string& name : files) {
    SCOPED_TRACE(name);
    const std::string path = (BadScenarioDir() / name).string();
    const std::string place = DeclaredPlace(ReadText(path));
    ASSERT_FALSE(place.empty()) << "second line must be \"# at: line <n>, key <key>\"";
    Scenario s;
    ::testing::internal::CaptureStderr();
    const bool loaded = LoadScenarioOrReport("shoal test", path, &s);
    const std::string err = ::testing::internal::GetCapturedStderr();
    EXPECT_FALSE(loaded);
    const std::string expected_start = "shoal test: " + path + ":" + place;
    EXPECT_EQ(err.substr(0, expected_start.size()), expected_start) << err;
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;  // one line
    EXPECT_TRUE(!err.empty() && err.back() == '\n') << err;
  }
}

class BadScenarioFileTest : public ::testing::TestWithParam<std::string> {};

TEST_P(BadScenarioFileTest, FailsWithTheExpectedMessage) {
  const fs::path path = BadScenarioDir() / GetParam();
  const std::string text = ReadText(path);
  const std::string prefix = "# expect: ";
  ASSERT_EQ(text.rfind(prefix, 0), 0u) << path << " must start with \"" << prefix << "...\"";
  const std::string expected = text.substr(prefix.size(), text.find('\n') - prefix.size());
  ASSERT_FALSE(expected.empty());

  try {
    LoadScenario(path.string());
    FAIL() << path << " loaded without error";
  } catch (const ScenarioError& e) {
    const std::string message = e.what();
    EXPECT_TRUE(Contains(message, GetParam()));
    EXPECT_TRUE(std::regex_search(message, std::regex("\\.toml:[0-9]+: "))) << message;
    EXPECT_TRUE(Contains(message, expected));
  }
}

INSTANTIATE_TEST_SUITE_P(Files, BadScenarioFileTest, ::testing::ValuesIn(BadScenarioFiles()),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           std::string name = fs::path(info.param).stem().string();
                           for (char& c : name) {
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           }
                           return name;
                         });

}  // namespace
}  // namespace shoal
