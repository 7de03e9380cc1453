// Tests of the scenario timeline ([[event]]) in scenario/loader: every kind loads into the
// expected ScenarioEvent, every validation rule refuses what it should at the line and key
// it names, and a Timeline built from a loaded scenario answers the expected states.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "core/timeline.h"
#include "scenario/loader.h"

#ifndef SHOAL_SOURCE_DIR
#error "SHOAL_SOURCE_DIR must be defined as the repository root (see cmake/shoal_test.cmake)"
#endif

namespace shoal {
namespace {

namespace fs = std::filesystem;

// Three followers in a chain 0 -> 1 -> 2 -> 3; topology events below add the link 1 -> 3.
const char kBase[] = R"([run]
duration_s = 300

[swarm]
followers = 3
leader_links = [1]
edges = [[2, 1], [3, 2]]

[control]
k1 = 1.0
k2 = 2.0
)";

/// The 1-based line of the first occurrence of `marker` in `text` from `from` on (0: absent).
int LineOfText(const std::string& text, const std::string& marker, std::size_t from = 0) {
  const std::size_t at = text.find(marker, from);
  if (at == std::string::npos) return 0;
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + at, '\n'));
}

/// The ScenarioError message for `text`, or "" (and a test failure) if it loads.
std::string ErrorOf(const std::string& text) {
  try {
    ParseScenario(text, "test.toml");
  } catch (const ScenarioError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected a ScenarioError for:\n" << text;
  return "";
}

/// Expects the error of `events` (appended to kBase) to start at the line of `marker`
/// with `key` and to contain `what`.
void ExpectError(const std::string& events, const std::string& marker, const std::string& key,
                 const std::string& what) {
  const std::string text = std::string(kBase) + events;
  const int line = LineOfText(text, marker, sizeof(kBase) - 1);  // in the events
  ASSERT_GT(line, 0) << marker;
  const std::string message = ErrorOf(text);
  const std::string start = "test.toml:" + std::to_string(line) + ": " + key + ": ";
  EXPECT_EQ(message.substr(0, start.size()), start) << message;
  EXPECT_NE(message.find(what), std::string::npos) << message << "\n  lacks: " << what;
}

Scenario Parse(const std::string& events) {
  return ParseScenario(std::string(kBase) + events, "test.toml");
}

const char kEveryKind[] = R"(
[[event]]
at_s = 10
until_s = 20
kind = "link_down"
links = [[0, 1], [2, 3]]

[[event]]
at_s = 30
until_s = 40
kind = "channel"
delay = { model = "constant", base_s = 0.3 }
loss = { model = "bernoulli", probability = 0.2 }

[[event]]
at_s = 50
kind = "topology"
edges = [[2, 1], [3, 1]]
leader_links = [1, 2]

[[event]]
at_s = 60
until_s = 70
kind = "vehicle_silent"
vehicles = [2, 3]

[[event]]
at_s = 60
kind = "vehicle_deaf"
vehicles = [1]

[[event]]
at_s = 80
until_s = 90
kind = "leader_silent"

[[event]]
at_s = 100
kind = "controller_reset"
vehicles = [3]
outage_s = 2.5

[[event]]
at_s = 120
until_s = 150
kind = "topology"
edges = [[2, 1], [3, 2]]
leader_links = [1]

[[event]]
at_s = 500
kind = "link_down"
)";

TEST(ScenarioEventsTest, EveryKindLoadsIntoItsFields) {
  const std::string text = std::string(kBase) + kEveryKind;
  const Scenario s = ParseScenario(text, "test.toml");
  ASSERT_EQ(s.events.size(), 9u);
  const double inf = std::numeric_limits<double>::infinity();

  const ScenarioEvent& down = s.events[0];
  EXPECT_EQ(down.kind, EventKind::kLinkDown);
  EXPECT_EQ(down.at_s, 10.0);
  EXPECT_EQ(down.until_s, 20.0);
  EXPECT_EQ(down.line, LineOfText(text, "[[event]]"));
  EXPECT_EQ(down.links, (std::vector<std::pair<int, int>>{{0, 1}, {2, 3}}));

  const ScenarioEvent& channel = s.events[1];
  EXPECT_EQ(channel.kind, EventKind::kChannel);
  EXPECT_EQ(channel.line, LineOfText(text, "at_s = 30") - 1);
  EXPECT_TRUE(channel.links.empty());
  ASSERT_TRUE(channel.delay.has_value());
  EXPECT_EQ(channel.delay->kind, DelayKind::kConstant);
  EXPECT_EQ(channel.delay->base_s, 0.3);
  ASSERT_TRUE(channel.loss.has_value());
  EXPECT_EQ(channel.loss->kind, LossKind::kBernoulli);
  EXPECT_EQ(channel.loss->probability, 0.2);

  const ScenarioEvent& topology = s.events[2];
  EXPECT_EQ(topology.kind, EventKind::kTopology);
  EXPECT_EQ(topology.until_s, inf);
  EXPECT_EQ(topology.edges, (std::vector<std::pair<int, int>>{{2, 1}, {3, 1}}));
  EXPECT_EQ(topology.leader_links, (std::vector<int>{1, 2}));

  EXPECT_EQ(s.events[3].kind, EventKind::kVehicleSilent);
  EXPECT_EQ(s.events[3].vehicles, (std::vector<int>{2, 3}));
  EXPECT_EQ(s.events[4].kind, EventKind::kVehicleDeaf);
  EXPECT_EQ(s.events[4].vehicles, (std::vector<int>{1}));
  EXPECT_EQ(s.events[4].until_s, inf);
  EXPECT_EQ(s.events[5].kind, EventKind::kLeaderSilent);
  EXPECT_EQ(s.events[5].end_s(), 90.0);

  const ScenarioEvent& reset = s.events[6];
  EXPECT_EQ(reset.kind, EventKind::kControllerReset);
  EXPECT_EQ(reset.vehicles, (std::vector<int>{3}));
  EXPECT_EQ(reset.outage_s, 2.5);
  EXPECT_EQ(reset.end_s(), 102.5);
  EXPECT_EQ(reset.line, LineOfText(text, "at_s = 100") - 1);

  // Beyond duration_s = 300 is allowed: it never takes effect unless the run is longer.
  EXPECT_EQ(s.events[8].at_s, 500.0);
  EXPECT_TRUE(s.events[8].links.empty());
}

TEST(ScenarioEventsTest, NoEventsLeavesTheTimelineEmpty) { EXPECT_TRUE(Parse("").events.empty()); }

TEST(ScenarioEventsTest, SubTablesAndATraceRelativeToTheScenarioFile) {
  const fs::path dir = fs::path(::testing::TempDir()) / "shoal_events_trace";
  fs::remove_all(dir);
  fs::create_directories(dir / "traces");
  std::ofstream(dir / "traces/t.csv") << "t_s, delay_s\n0, 0.5\n10, 0.7\n";
  const std::string path = (dir / "s.toml").string();
  std::ofstream(path) << kBase << R"(
[[event]]
at_s = 5
kind = "channel"
links = [[1, 2]]

[event.delay]
model = "trace"
file = "traces/t.csv"

[event.loss]
model = "gilbert_elliott"
p_good_to_bad = 0.1
p_bad_to_good = 0.5
loss_good = 0.0
loss_bad = 0.9
)";
  const Scenario s = LoadScenario(path);
  ASSERT_EQ(s.events.size(), 1u);
  const ScenarioEvent& e = s.events[0];
  ASSERT_TRUE(e.delay.has_value());
  ASSERT_EQ(e.delay->kind, DelayKind::kTrace);
  ASSERT_TRUE(e.delay->trace);
  EXPECT_EQ(e.delay->trace->file, "traces/t.csv");
  EXPECT_EQ(e.delay->trace->delay_s, (std::vector<double>{0.5, 0.7}));
  ASSERT_TRUE(e.loss.has_value());
  EXPECT_EQ(e.loss->kind, LossKind::kGilbertElliott);
  EXPECT_EQ(e.loss->loss_bad, 0.9);
  EXPECT_EQ(e.links, (std::vector<std::pair<int, int>>{{1, 2}}));
  fs::remove_all(dir);
}

TEST(ScenarioEventsTest, ATimelineOfALoadedScenarioAnswersItsStates) {
  const Scenario s = Parse(kEveryKind);
  const Timeline tl(s);
  const auto at = [](double t) { return TimelineMicros(t); };
  const int l01 = tl.LinkIndex(0, 1);
  const int l23 = tl.LinkIndex(2, 3);
  const int l13 = tl.LinkIndex(1, 3);
  ASSERT_GE(l01, 0);
  ASSERT_GE(l23, 0);
  ASSERT_GE(l13, 0);  // only in the topology events: in the union
  const auto k01 = static_cast<std::size_t>(l01);
  // link_down [10, 20) on 0 -> 1.
  EXPECT_FALSE(tl.LinkDown(k01, at(9.99)));
  EXPECT_TRUE(tl.LinkDown(k01, at(10)));
  EXPECT_TRUE(tl.LinkDown(k01, at(19.99)));
  EXPECT_FALSE(tl.LinkDown(k01, at(20)));
  EXPECT_FALSE(tl.LinkDown(static_cast<std::size_t>(tl.LinkIndex(1, 2)), at(15)));
  // channel [30, 40) on every link.
  EXPECT_EQ(tl.ChannelChange(k01, at(29)), nullptr);
  ASSERT_NE(tl.ChannelChange(k01, at(30)), nullptr);
  EXPECT_EQ(tl.ChannelChange(k01, at(30))->loss->probability, 0.2);
  EXPECT_EQ(tl.ChannelChange(k01, at(40)), nullptr);
  // topology 1 from 50 until the next topology event at 120, which holds until 150.
  EXPECT_EQ(tl.TopologyAt(at(49.99)), 0);
  EXPECT_EQ(tl.TopologyAt(at(50)), 1);
  EXPECT_TRUE(tl.LinkActive(static_cast<std::size_t>(l13), at(60)));
  EXPECT_FALSE(tl.LinkActive(static_cast<std::size_t>(l23), at(60)));
  EXPECT_EQ(tl.TopologyAt(at(120)), 2);
  EXPECT_EQ(tl.TopologyAt(at(150)), 0);  // back to [swarm] at until_s
  EXPECT_TRUE(tl.LinkActive(static_cast<std::size_t>(l23), at(150)));
  // vehicles.
  EXPECT_TRUE(tl.Silent(2, at(65)));
  EXPECT_FALSE(tl.Silent(2, at(70)));
  EXPECT_FALSE(tl.Silent(1, at(65)));
  EXPECT_TRUE(tl.Deaf(1, at(1000)));
  EXPECT_TRUE(tl.Silent(0, at(80)));
  EXPECT_FALSE(tl.Silent(0, at(90)));
  EXPECT_TRUE(tl.InReset(3, at(102.4)));
  EXPECT_FALSE(tl.InReset(3, at(102.5)));
  EXPECT_FALSE(tl.InReset(2, at(101)));
}

TEST(ScenarioEventsTest, ExampleInTheDocumentationIsValid) {
  std::ifstream in(fs::path(SHOAL_SOURCE_DIR) / "docs" / "scenario.md", std::ios::binary);
  const std::string doc((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::size_t section = doc.find("## Events");
  ASSERT_NE(section, std::string::npos);
  const std::string fence = "```toml\n";
  const std::size_t begin = doc.find(fence, doc.find("Complete example", section));
  ASSERT_NE(begin, std::string::npos);
  const std::size_t end = doc.find("```", begin + fence.size());
  ASSERT_NE(end, std::string::npos);
  const Scenario s = ParseScenario(doc.substr(begin + fence.size(), end - begin - fence.size()),
                                   "docs/scenario.md");
  ASSERT_EQ(s.events.size(), 6u);
  const Timeline tl(s);
  EXPECT_TRUE(tl.LinkDown(static_cast<std::size_t>(tl.LinkIndex(0, 1)), TimelineMicros(70)));
  EXPECT_EQ(tl.TopologyAt(TimelineMicros(199)), 1);
  EXPECT_EQ(tl.TopologyAt(TimelineMicros(200)), 2);
  EXPECT_TRUE(tl.InReset(3, TimelineMicros(181)));
}

TEST(ScenarioEventsTest, OverlapsThatAgreeAreAllowed) {
  const Scenario s = Parse(R"(
[[event]]
at_s = 10
until_s = 30
kind = "link_down"

[[event]]
at_s = 20
kind = "link_down"
links = [[0, 1]]

[[event]]
at_s = 20
until_s = 40
kind = "channel"
links = [[0, 1]]
loss = { model = "bernoulli", probability = 0.5 }

[[event]]
at_s = 25
kind = "channel"
links = [[1, 2]]
delay = { model = "constant", base_s = 1 }

[[event]]
at_s = 40
kind = "channel"
links = [[0, 1]]
delay = { model = "none" }

[[event]]
at_s = 40
kind = "controller_reset"
vehicles = [1]
outage_s = 5

[[event]]
at_s = 42
kind = "controller_reset"
vehicles = [2]
outage_s = 5

[[event]]
at_s = 45
kind = "controller_reset"
vehicles = [1]
outage_s = 5

[[event]]
at_s = 50
until_s = 60
kind = "topology"
leader_links = [1, 2, 3]

[[event]]
at_s = 60
kind = "topology"
edges = [[2, 1], [3, 1]]
leader_links = [1]
)");
  EXPECT_EQ(s.events.size(), 10u);
}

// ---------------------------------------------------------------------------------------
// Each rule, at the line and key it names.

TEST(ScenarioEventsTest, KindIsRequiredAndKnown) {
  ExpectError("\n[[event]]\nat_s = 1\nkind = \"link_dwn\"\n", "kind = ", "event[0].kind",
              "unknown event kind (got \"link_dwn\"); use one of \"link_down\"");
  ExpectError("\n[[event]]\nat_s = 1\n", "[[event]]", "event[0].kind", "missing required key");
}

TEST(ScenarioEventsTest, KeysOfAnotherKindOrUnknownAreRefused) {
  ExpectError("\n[[event]]\nat_s = 1\nkind = \"link_down\"\nvehicles = [1]\n", "vehicles",
              "event[0].vehicles", "not used by event kind \"link_down\"");
  ExpectError("\n[[event]]\nat_s = 1\nkind = \"leader_silent\"\nlinks = [[0, 1]]\n", "links",
              "event[0].links", "not used by event kind \"leader_silent\"");
  ExpectError("\n[[event]]\nat_s = 1\nkind = \"link_down\"\nat = 3\n", "at = 3", "event[0].at",
              "unknown key 'at' in [[event]]");
  ExpectError(
      "\n[[event]]\nat_s = 1\nkind = \"controller_reset\"\nvehicles = [1]\n"
      "outage_s = 1\nuntil_s = 5\n",
      "until_s", "event[0].until_s", "not used by event kind \"controller_reset\"");
}

TEST(ScenarioEventsTest, TimesAreCheckedAndInOrder) {
  ExpectError("\n[[event]]\nkind = \"leader_silent\"\n", "[[event]]", "event[0].at_s",
              "missing required key");
  ExpectError("\n[[event]]\nkind = \"leader_silent\"\nat_s = -1\n", "at_s", "event[0].at_s",
              "must be a number of seconds in [0, 1e9]");
  ExpectError("\n[[event]]\nkind = \"leader_silent\"\nat_s = nan\n", "at_s", "event[0].at_s",
              "must be a finite number");
  ExpectError("\n[[event]]\nkind = \"leader_silent\"\nat_s = inf\n", "at_s", "event[0].at_s",
              "must be a finite number");
  ExpectError("\n[[event]]\nkind = \"leader_silent\"\nat_s = 5\nuntil_s = 5\n", "until_s",
              "event[0].until_s", "must be later than at_s = 5");
  ExpectError("\n[[event]]\nkind = \"leader_silent\"\nat_s = 5\nuntil_s = 4\n", "until_s",
              "event[0].until_s", "must be later than at_s = 5");
  ExpectError(
      "\n[[event]]\nkind = \"leader_silent\"\nat_s = 5\n"
      "\n[[event]]\nkind = \"leader_silent\"\nat_s = 4\n",
      "at_s = 4", "event[1].at_s", "is earlier than the previous event's at_s = 5 (line 13)");
}

TEST(ScenarioEventsTest, VehiclesAreKnownDistinctFollowers) {
  const std::string head = "\n[[event]]\nat_s = 1\nkind = \"vehicle_silent\"\n";
  ExpectError(head + "vehicles = [1, 4]\n", "vehicles", "event[0].vehicles[1]",
              "must be a follower id in 1..3 (got 4)");
  ExpectError(head + "vehicles = [0]\n", "vehicles", "event[0].vehicles[0]",
              "must be a follower id in 1..3 (got 0)");
  ExpectError(head + "vehicles = [2, 2]\n", "vehicles", "event[0].vehicles[1]",
              "duplicate follower id");
  ExpectError(head + "vehicles = []\n", "vehicles", "event[0].vehicles",
              "must list at least one follower");
  ExpectError(head, "[[event]]", "event[0].vehicles", "missing required key");
  ExpectError("\n[[event]]\nat_s = 1\nkind = \"vehicle_deaf\"\nvehicles = [9]\n", "vehicles",
              "event[0].vehicles[0]", "must be a follower id in 1..3 (got 9)");
}

TEST(ScenarioEventsTest, LinksAreDistinctLinksOfSomeTopology) {
  const std::string head = "\n[[event]]\nat_s = 1\nkind = \"link_down\"\n";
  ExpectError(head + "links = [[0, 1],\n  [1, 3]]\n", "[1, 3]", "event[0].links[1]",
              "the link from follower 1 to follower 3 is not a link of any topology");
  ExpectError(head + "links = [[0, 2]]\n", "links", "event[0].links[0]",
              "the link from the leader to follower 2 is not a link of any topology");
  ExpectError(head + "links = [[0, 1], [0, 1]]\n", "links", "event[0].links[1]", "duplicate link");
  ExpectError(head + "links = []\n", "links", "event[0].links", "must list at least one link");
  ExpectError(head + "links = [[0, 0]]\n", "links", "event[0].links[0][1]",
              "must be a follower id in 1..3");
  ExpectError(head + "links = [[0, 1, 2]]\n", "links", "event[0].links[0]",
              "must be a pair [from, to]");
  // A link of a topology event is a link of the union: it may be listed before that event.
  EXPECT_NO_THROW(Parse(head +
                        "links = [[1, 3]]\n"
                        "\n[[event]]\nat_s = 5\nkind = \"topology\"\nedges = [[2, 1], [3, 1]]\n"
                        "leader_links = [1]\n"));
}

TEST(ScenarioEventsTest, ChannelEventNeedsAModelWithTheChannelRules) {
  const std::string head = "\n[[event]]\nat_s = 1\nkind = \"channel\"\n";
  ExpectError(head, "[[event]]", "event[0].delay", "a channel event needs a delay or a loss table");
  ExpectError(head + "loss = { model = \"bernoulli\", probability = 1 }\n", "loss",
              "event[0].loss.probability", "must be in [0, 1)");
  ExpectError(head + "delay = { model = \"constant\", base_s = 1, amplitude_s = 1 }\n", "delay",
              "event[0].delay.amplitude_s", "not used by delay model \"constant\"");
  ExpectError(head +
                  "\n[event.delay]\nmodel = \"sinusoid\"\nbase_s = 1\namplitude_s = 0.5\n"
                  "omega_rad_s = 3\n",
              "omega_rad_s", "event[0].delay.omega_rad_s", "Assumption 3");
  ExpectError(head + "delay = { model = \"trace\", file = \"no/such.csv\" }\n", "delay",
              "event[0].delay.file", "cannot read delay trace");
}

TEST(ScenarioEventsTest, ResetNeedsAPositiveOutage) {
  const std::string head = "\n[[event]]\nat_s = 1\nkind = \"controller_reset\"\nvehicles = [1]\n";
  ExpectError(head, "[[event]]", "event[0].outage_s", "missing required key");
  ExpectError(head + "outage_s = 0\n", "outage_s", "event[0].outage_s",
              "must be a positive number of seconds");
  ExpectError(head + "outage_s = 1e-9\n", "outage_s", "event[0].outage_s",
              "must be at least a microsecond");
}

// A reset acts at the ticks of its window (50 Hz here): a window between two ticks would
// do nothing in shoal sim and restart the process in shoal run.
TEST(ScenarioEventsTest, ResetWindowMustHoldAControlTick) {
  const std::string at = "\n[[event]]\nat_s = 1.001\nkind = \"controller_reset\"\nvehicles = [1]\n";
  ExpectError(at + "outage_s = 0.01\n", "outage_s", "event[0].outage_s",
              "the window [1.001, 1.011) s holds no control tick (ticks every 0.02 s; the next "
              "at 1.02 s), so the reset would do nothing");
  EXPECT_EQ(Parse(at + "outage_s = 0.0195\n").events.size(), 1u);  // holds the tick at 1.02
  EXPECT_EQ(Parse("\n[[event]]\nat_s = 1.02\nkind = \"controller_reset\"\nvehicles = [1]\n"
                  "outage_s = 1e-6\n")
                .events.size(),
            1u);  // starts at a tick
}

TEST(ScenarioEventsTest, TopologyEventsKeepAssumption1) {
  ExpectError(
      "\n[[event]]\nat_s = 100\nkind = \"topology\"\nedges = [[2, 1]]\n"
      "leader_links = [1]\n",
      "[[event]]", "event[0]",
      "follower 3 cannot be reached from the leader (Assumption 1) in the topology "
      "from t = 100 s");
  ExpectError("\n[[event]]\nat_s = 100\nkind = \"topology\"\nedges = [[2, 1]]\n", "[[event]]",
              "event[0].leader_links", "missing required key");
  ExpectError(
      "\n[[event]]\nat_s = 100\nkind = \"topology\"\nedges = [[2, 2]]\n"
      "leader_links = [1]\n",
      "edges", "event[0].edges[0]", "a follower cannot receive from itself");
}

TEST(ScenarioEventsTest, ContradictoryOverlapsNameBothEvents) {
  // Two channel changes of the link 0 -> 1.
  ExpectError(
      "\n[[event]]\nat_s = 10\nuntil_s = 30\nkind = \"channel\"\nlinks = [[0, 1]]\n"
      "loss = { model = \"bernoulli\", probability = 0.5 }\n"
      "\n[[event]] # second\nat_s = 20\nkind = \"channel\"\nlinks = [[1, 2], [0, 1]]\n"
      "delay = { model = \"constant\", base_s = 1 }\n",
      "[[event]] # second", "event[1]",
      "channel window [20, end of run) overlaps the window [10, 30) of event[0] "
      "(line 13) on the link from the leader to follower 1");
  // A channel change of every link overlaps one of any link.
  ExpectError(
      "\n[[event]]\nat_s = 10\nuntil_s = 30\nkind = \"channel\"\nlinks = [[2, 3]]\n"
      "loss = { model = \"bernoulli\", probability = 0.5 }\n"
      "\n[[event]] # second\nat_s = 29\nkind = \"channel\"\n"
      "delay = { model = \"constant\", base_s = 1 }\n",
      "[[event]] # second", "event[1]",
      "of event[0] (line 13) on the link from follower 2 to follower 3");
  ExpectError(
      "\n[[event]]\nat_s = 10\nkind = \"channel\"\n"
      "loss = { model = \"bernoulli\", probability = 0.5 }\n"
      "\n[[event]] # second\nat_s = 29\nkind = \"channel\"\nlinks = [[2, 3]]\n"
      "delay = { model = \"constant\", base_s = 1 }\n",
      "[[event]] # second", "event[1]",
      "of event[0] (line 13) on the link from follower 2 to follower 3");
  // A topology with until_s beyond the next one's start.
  ExpectError(
      "\n[[event]]\nat_s = 10\nuntil_s = 30\nkind = \"topology\"\nleader_links = [1, 2, 3]\n"
      "\n[[event]] # second\nat_s = 20\nkind = \"topology\"\nleader_links = [1, 2, 3]\n",
      "[[event]] # second", "event[1]",
      "topology window [20, end of run) overlaps the window [10, 30) of event[0] (line 13)");
  ExpectError(
      "\n[[event]]\nat_s = 10\nkind = \"topology\"\nleader_links = [1, 2, 3]\n"
      "\n[[event]] # second\nat_s = 10\nkind = \"topology\"\nleader_links = [1, 2, 3]\n",
      "[[event]] # second", "event[1]", "(two topologies from the same at_s)");
  // Two resets of follower 2.
  ExpectError(
      "\n[[event]]\nat_s = 10\nkind = \"controller_reset\"\nvehicles = [1, 2]\n"
      "outage_s = 5\n"
      "\n[[event]] # second\nat_s = 14.5\nkind = \"controller_reset\"\nvehicles = [2]\n"
      "outage_s = 1\n",
      "[[event]] # second", "event[1]",
      "controller_reset window [14.5, 15.5) overlaps the window [10, 15) of event[0] "
      "(line 13) for follower 2");
}

TEST(ScenarioEventsTest, HostileTimelinesAreRefused) {
  // More than 10000 events: refused at the first one too many.
  std::string many;
  for (int k = 0; k <= 10000; ++k) many += "[[event]]\nat_s = 1\nkind = \"leader_silent\"\n";
  const std::string text = std::string(kBase) + "\n" + many;
  const std::string message = ErrorOf(text);
  const int line = LineOfText(text, "[[event]]") + 3 * 10000;
  EXPECT_EQ(message.rfind("test.toml:" + std::to_string(line) +
                              ": event[10000]: more than "
                              "10000 events",
                          0),
            0u)
      << message;

  // 60 followers all linked to each other and to the leader (3600 links), and 7000 events
  // of distinct start and end times: 14001 segments of 3600 links, above 5e7.
  std::string dense = "[swarm]\nfollowers = 60\nleader_links = [";
  for (int i = 1; i <= 60; ++i) dense += (i > 1 ? ", " : "") + std::to_string(i);
  dense += "]\nedges = [";
  for (int i = 1; i <= 60; ++i) {
    for (int j = 1; j <= 60; ++j) {
      if (i != j) dense += "[" + std::to_string(i) + ", " + std::to_string(j) + "], ";
    }
  }
  dense += "]\n\n[control]\nk1 = 1\nk2 = 2\n\n";
  std::string timeline;
  for (int k = 0; k < 7000; ++k) {
    timeline += "[[event]]\nat_s = " + std::to_string(k) + "\nuntil_s = " + std::to_string(k) +
                ".5\nkind = \"leader_silent\"\n";
  }
  const std::string big = ErrorOf(dense + timeline);
  const std::string start =
      "test.toml:" + std::to_string(LineOfText(dense + timeline, "[[event]]")) +
      ": event: the timeline is too large: 14000 distinct change times and "
      "3600 links";
  EXPECT_EQ(big.rfind(start, 0), 0u) << big;
  // The same timeline on the three-follower chain (3 links) loads.
  EXPECT_EQ(Parse("\n" + timeline).events.size(), 7000u);
}

/// 30 followers linked to each other and to the leader (900 links), and `count` link_down
/// events for every link (omitted `links`), all in force from the last start on.
std::string DenseLinkEvents(int count) {
  std::string text = "[swarm]\nfollowers = 30\nleader_links = [";
  for (int i = 1; i <= 30; ++i) {
    text += (i > 1 ? ", " : "") + std::to_string(i);
  }
  text += "]\nedges = [";
  for (int i = 1; i <= 30; ++i) {
    for (int j = 1; j <= 30; ++j) {
      if (i == j) continue;
      text += "[" + std::to_string(i) + ", " + std::to_string(j) + "], ";
    }
  }
  text += "]\n\n[control]\nk1 = 1\nk2 = 2\n\n";
  for (int k = 0; k < count; ++k) {
    text += "[[event]]\nat_s = " + std::to_string(k) + "\nuntil_s = " + std::to_string(k + 100000) +
            "\nkind = \"link_down\"\n";
  }
  return text;
}

TEST(ScenarioEventsTest, TimelinesTooCostlyToBuildAreRefused) {
  // Each of 1100 events spans 1100 of the 2201 segments and marks 900 links in each, and
  // each segment checks every event: 1100 * 1100 * 900 + 2201 * 1100 = 1.091e9, above 1e9.
  const std::string text = DenseLinkEvents(1100);
  const std::string message = ErrorOf(text);
  const std::string start = "test.toml:" + std::to_string(LineOfText(text, "[[event]]")) +
                            ": event: the timeline is too costly to build";
  EXPECT_EQ(message.rfind(start, 0), 0u) << message;
  EXPECT_NE(message.find("make 1091421100 checks, more than 1e9"), std::string::npos) << message;
  // 1000 such events: 1000 * 1000 * 900 + 2001 * 1000 = 9.02e8 checks, accepted.
  EXPECT_EQ(ParseScenario(DenseLinkEvents(1000), "test.toml").events.size(), 1000u);
}

// Every topology is held as dense n x n matrices: 51 topologies of 1000 followers
// (5.1e7 entries, about 400 MB in each process) are refused, 49 load.
TEST(ScenarioEventsTest, TooManyLargeTopologiesAreRefused) {
  auto text = [](int events) {
    std::string all;
    for (int i = 1; i <= 1000; ++i) all += (i > 1 ? ", " : "") + std::to_string(i);
    std::string t = "[swarm]\nfollowers = 1000\nleader_links = [" + all +
                    "]\n\n[control]\nk1 = 1\nk2 = 2\n\n";
    for (int k = 0; k < events; ++k) {
      t += "[[event]]\nat_s = " + std::to_string(k + 1) + "\nkind = \"topology\"\nleader_links = [" +
           all + "]\n";
    }
    return t;
  };
  const std::string message = ErrorOf(text(50));
  EXPECT_NE(message.find("too many topologies for its size: 51 topologies of 1000 followers"),
            std::string::npos)
      << message;
  EXPECT_EQ(ParseScenario(text(48), "test.toml").events.size(), 48u);
}

}  // namespace
}  // namespace shoal
