// Tests of scenario overrides (scenario/overrides.h and the loader's overloads taking
// them): --set parsing, every kind of path, table replacement, every refusal with its
// origin, and the effective text that a log keeps.
#include "scenario/overrides.h"

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "scenario/loader.h"

#ifndef SHOAL_SOURCE_DIR
#error "SHOAL_SOURCE_DIR must be defined as the repository root (see cmake/shoal_test.cmake)"
#endif

namespace shoal {
namespace {

const std::string kExample2 = std::string(SHOAL_SOURCE_DIR) + "/scenarios/paper_example2.toml";
const std::string kFaults = std::string(SHOAL_SOURCE_DIR) + "/scenarios/faults.toml";

std::vector<ScenarioOverride> Sets(const std::vector<std::string>& flags) {
  std::vector<ScenarioOverride> overrides;
  for (const std::string& flag : flags) overrides.push_back(ParseSetFlag(flag));
  return overrides;
}

/// The ScenarioError message of loading `path` with `flags`, or "" (and a failure).
std::string ErrorOf(const std::string& path, const std::vector<std::string>& flags) {
  try {
    LoadScenario(path, Sets(flags));
  } catch (const ScenarioError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected a ScenarioError";
  return "";
}

std::string SetFlagError(const std::string& text) {
  try {
    ParseSetFlag(text);
  } catch (const ScenarioError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected a ScenarioError for --set " << text;
  return "";
}

::testing::AssertionResult Contains(const std::string& text, const std::string& part) {
  if (text.find(part) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure()
         << "\"" << text << "\"\n  does not contain\n\"" << part << "\"";
}

TEST(ScenarioOverrides, ParseSetFlagSplitsAtTheFirstEquals) {
  const ScenarioOverride o = ParseSetFlag("channel.delay.model = \"a=b\"");
  EXPECT_EQ(o.key, "channel.delay.model");
  EXPECT_EQ(o.value, "\"a=b\"");
  EXPECT_EQ(o.origin, "--set channel.delay.model = \"a=b\"");
}

TEST(ScenarioOverrides, ParseSetFlagRefusesBadSyntaxNamingSet) {
  EXPECT_TRUE(Contains(SetFlagError("run.seed"), "--set run.seed: expected KEY=VALUE"));
  EXPECT_TRUE(Contains(SetFlagError("=3"), "--set =3: empty key"));
  EXPECT_TRUE(Contains(SetFlagError("run.seed="), "--set run.seed=: empty value"));
  EXPECT_TRUE(Contains(SetFlagError("run..seed=1"), "--set run..seed=1: key 'run..seed'"));
  EXPECT_TRUE(Contains(SetFlagError("follower[x].k1=1"), "an index is written [N]"));
  EXPECT_TRUE(Contains(SetFlagError("run.seed]=1"), "unexpected ']'"));
}

TEST(ScenarioOverrides, ScalarSetChangesTheValue) {
  const Scenario s = LoadScenario(kExample2, Sets({"run.seed=42", "control.k1=0.2"}));
  EXPECT_EQ(s.seed, 42u);
  EXPECT_DOUBLE_EQ(s.k1, 0.2);
  EXPECT_DOUBLE_EQ(s.k2, LoadScenario(kExample2).k2);
}

TEST(ScenarioOverrides, WithoutOverridesTheScenarioIsTheFilesOwn) {
  const Scenario plain = LoadScenario(kExample2);
  const Scenario none = LoadScenario(kExample2, {});
  EXPECT_EQ(none.source_text, plain.source_text);
  EXPECT_EQ(ApplyOverridesToText(plain.source_text, kExample2, {}), plain.source_text);
}

TEST(ScenarioOverrides, SettingATableReplacesItWhole) {
  // paper_example2 has a sinusoid delay: amplitude_s and omega_rad_s must go with it.
  const Scenario s =
      LoadScenario(kExample2, Sets({"channel.delay={ model = \"constant\", base_s = 0.3 }"}));
  EXPECT_EQ(s.delay.kind, DelayKind::kConstant);
  EXPECT_DOUBLE_EQ(s.delay.base_s, 0.3);
}

TEST(ScenarioOverrides, SettingOnlyTheSelectorKeepsTheStaleKeysAndSaysSo) {
  const std::string e = ErrorOf(kExample2, {"channel.delay.model=constant"});
  EXPECT_TRUE(Contains(e, "channel.delay.amplitude_s: not used by delay model \"constant\""));
  EXPECT_TRUE(Contains(e, "(scenario changed by --set channel.delay.model=constant)"));
}

TEST(ScenarioOverrides, BareWordsAreStrings) {
  const Scenario s = LoadScenario(kExample2, Sets({"channel.delay={}", "channel.delay.model=none"}));
  EXPECT_EQ(s.delay.kind, DelayKind::kNone);
  // "constant" inside a table is not a bare value: the TOML error names the origin.
  const std::string e = ErrorOf(kExample2, {"channel.delay={ model = constant }"});
  EXPECT_TRUE(Contains(e, "--set channel.delay={ model = constant }: not a TOML value"));
  EXPECT_EQ(LoadScenario(kExample2, Sets({"leader.path=line"})).leader.path, PathKind::kLine);
}

TEST(ScenarioOverrides, IndexPathsChangeArrayElements) {
  const Scenario s = LoadScenario(
      kFaults, Sets({"follower[2].heading_rad=0.25", "event[0].at_s=90", "control.offsets_m[1]=[1, 2, 3]"}));
  EXPECT_DOUBLE_EQ(s.initial[2].eta(4), 0.25);
  EXPECT_DOUBLE_EQ(s.events[0].at_s, 90.0);
  EXPECT_DOUBLE_EQ(s.offsets_m[1](2), 3.0);
}

TEST(ScenarioOverrides, MissingTablesAreCreated) {
  const Scenario s = LoadScenario(
      kExample2, Sets({"channel.loss.model=bernoulli", "channel.loss.probability=0.1",
                       "metrics.position_tol_m=0.7"}));
  EXPECT_EQ(s.loss.kind, LossKind::kBernoulli);
  EXPECT_DOUBLE_EQ(s.loss.probability, 0.1);
  EXPECT_DOUBLE_EQ(s.metrics.position_tol_m, 0.7);
}

TEST(ScenarioOverrides, QuotedKeyComponents) {
  EXPECT_EQ(LoadScenario(kExample2, Sets({"\"run\".'seed'=9"})).seed, 9u);
}

TEST(ScenarioOverrides, IndexPastTheEndIsRefusedNamingTheOrigin) {
  EXPECT_TRUE(Contains(ErrorOf(kExample2, {"follower[5].heading_rad=0"}),
                       "--set follower[5].heading_rad=0: follower[5]: index past the end "
                       "(follower has 5 entries"));
  EXPECT_TRUE(Contains(ErrorOf(kExample2, {"follower[7]={ id = 8 }"}),
                       "--set follower[7]={ id = 8 }: follower[7]: index past the end"));
  EXPECT_TRUE(Contains(ErrorOf(kExample2, {"event[0].at_s=1"}),
                       "--set event[0].at_s=1: event: no such array"));
  EXPECT_TRUE(
      Contains(ErrorOf(kExample2, {"run[0].seed=1"}), "--set run[0].seed=1: run is not an array"));
}

TEST(ScenarioOverrides, DescendingIntoANonTableIsRefused) {
  EXPECT_TRUE(Contains(ErrorOf(kExample2, {"control.k1.x=1"}),
                       "--set control.k1.x=1: control.k1 is a floating-point, not a table"));
}

TEST(ScenarioOverrides, BadValuesAreRefusedNamingTheOrigin) {
  EXPECT_TRUE(Contains(ErrorOf(kExample2, {"control.k1=[1,"}), "--set control.k1=[1,: not a TOML value"));
  EXPECT_TRUE(Contains(ErrorOf(kExample2, {"control.k1=1\nrun.seed = 3"}),
                       "must be one TOML value"));
  EXPECT_TRUE(Contains(ErrorOf(kExample2, {"control.k1=1.2.3"}), "not a TOML value"));
  EXPECT_TRUE(Contains(ErrorOf(kExample2, {"control.k1=" + std::string(2u << 20, '1')}),
                       "value longer than"));
}

TEST(ScenarioOverrides, DeepValuesAreRefusedBeforeParsing) {
  // 200 key components, then an inline table of a 100-component key: deeper than the
  // loader allows in a file.
  std::string key = "a";
  for (int i = 0; i < 199; ++i) key += ".a";
  std::string value = "{ b";
  for (int i = 0; i < 99; ++i) value += ".b";
  value += " = 1 }";
  EXPECT_TRUE(Contains(ErrorOf(kExample2, {key + "=" + value}), "nests tables more than 256"));
  std::string long_key = "a";
  for (int i = 0; i < 300; ++i) long_key += ".a";
  EXPECT_TRUE(Contains(SetFlagError(long_key + "=1"), "nests more than 256 tables deep"));
}

TEST(ScenarioOverrides, ValidationErrorsNameTheOrigin) {
  EXPECT_EQ(ErrorOf(kExample2, {"channel.delay.base_s=-1"}).rfind(
                "--set channel.delay.base_s=-1: channel.delay.base_s: ", 0),
            0u);
  EXPECT_TRUE(Contains(ErrorOf(kExample2, {"control.k1=\"x\""}),
                       "--set control.k1=\"x\": control.k1: must be a number (got \"x\")"));
  EXPECT_TRUE(Contains(ErrorOf(kExample2, {"channel.delay.model=bogus"}),
                       "--set channel.delay.model=bogus: channel.delay.model: unknown delay model"));
  EXPECT_TRUE(Contains(ErrorOf(kExample2, {"nosuch.key=1"}),
                       "--set nosuch.key=1: nosuch: unknown table [nosuch]"));
}

// Checks across keys (reachability, links of the topology, speed ranges, events) name
// the --set that gave the value they fail on too, not a line of the file.
TEST(ScenarioOverrides, CrossKeyChecksNameTheOrigin) {
  EXPECT_EQ(ErrorOf(kFaults, {"swarm.edges=[]"}).rfind("--set swarm.edges=[]: swarm.edges: ", 0), 0u)
      << ErrorOf(kFaults, {"swarm.edges=[]"});
  const std::string link = ErrorOf(kFaults, {"channel.link=[{from=0, to=2}]"});
  EXPECT_EQ(link.rfind("--set channel.link=[{from=0, to=2}]: channel.link[0]: ", 0), 0u) << link;
  const std::string current = ErrorOf(
      kFaults, {"disturbance={model=\"ocean_current\", min_speed_mps=0.9, max_speed_mps=0.5}"});
  EXPECT_EQ(current.rfind("--set disturbance=", 0), 0u) << current;
  const std::string event =
      ErrorOf(kFaults, {"event[1]={at_s=101, kind=\"topology\", leader_links=[2]}"});
  EXPECT_EQ(event.rfind("--set event[1]=", 0), 0u) << event;
}

TEST(ScenarioOverrides, OriginsOfCampaignsAreKept) {
  const std::vector<ScenarioOverride> o = {
      {"channel.delay.base_s", "-1", "sweep.toml:12: axis channel.delay.base_s"}};
  try {
    LoadScenario(kExample2, o);
    ADD_FAILURE() << "expected a ScenarioError";
  } catch (const ScenarioError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("sweep.toml:12: axis channel.delay.base_s: ", 0), 0u);
  }
}

TEST(ScenarioOverrides, BaseFileErrorsAreUnchanged) {
  const std::string path = ::testing::TempDir() + "/overrides_bad.toml";
  FILE* f = std::fopen(path.c_str(), "w");
  ASSERT_NE(f, nullptr);
  std::fputs("[run]\nduration_s = -5\n", f);
  std::fclose(f);
  std::string plain;
  try {
    LoadScenario(path);
  } catch (const ScenarioError& e) {
    plain = e.what();
  }
  EXPECT_EQ(ErrorOf(path, {"run.seed=3"}), plain);
}

void ExpectSameScenario(const Scenario& a, const Scenario& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.source_text, b.source_text);
  EXPECT_EQ(a.duration_s, b.duration_s);
  EXPECT_EQ(a.control_rate_hz, b.control_rate_hz);
  EXPECT_EQ(a.seed, b.seed);
  EXPECT_EQ(a.followers, b.followers);
  EXPECT_EQ(a.edges, b.edges);
  EXPECT_EQ(a.leader_links, b.leader_links);
  EXPECT_EQ(a.k1, b.k1);
  EXPECT_EQ(a.k2, b.k2);
  ASSERT_EQ(a.offsets_m.size(), b.offsets_m.size());
  for (std::size_t i = 0; i < a.offsets_m.size(); ++i) EXPECT_EQ(a.offsets_m[i], b.offsets_m[i]);
  EXPECT_EQ(a.delay.kind, b.delay.kind);
  EXPECT_EQ(a.delay.base_s, b.delay.base_s);
  EXPECT_EQ(a.delay.amplitude_s, b.delay.amplitude_s);
  EXPECT_EQ(a.loss.kind, b.loss.kind);
  EXPECT_EQ(a.loss.probability, b.loss.probability);
  ASSERT_EQ(a.initial.size(), b.initial.size());
  for (std::size_t i = 0; i < a.initial.size(); ++i) {
    EXPECT_EQ(a.initial[i].eta, b.initial[i].eta);
    EXPECT_EQ(a.initial[i].nu, b.initial[i].nu);
  }
  ASSERT_EQ(a.events.size(), b.events.size());
  for (std::size_t i = 0; i < a.events.size(); ++i) {
    EXPECT_EQ(a.events[i].at_s, b.events[i].at_s);
    EXPECT_EQ(a.events[i].until_s, b.events[i].until_s);
    EXPECT_EQ(a.events[i].line, b.events[i].line);
  }
  EXPECT_EQ(a.disturbance.kind, b.disturbance.kind);
  EXPECT_EQ(a.vehicle.tau_max, b.vehicle.tau_max);
}

TEST(ScenarioOverrides, EffectiveTextRoundTrips) {
  const Scenario s = LoadScenario(
      kFaults, Sets({"run.seed=7", "channel.loss={ model = \"bernoulli\", probability = 0.1 }",
                     "control.k1=0.1234567890123", "event[1].at_s=150.5"}));
  // The effective text names the file and each override in order, then the merged tree.
  EXPECT_TRUE(Contains(s.source_text, "# Effective scenario: " + kFaults));
  EXPECT_LT(s.source_text.find("#   --set run.seed=7"),
            s.source_text.find("#   --set event[1].at_s=150.5"));
  EXPECT_EQ(s.seed, 7u);
  EXPECT_EQ(s.k1, 0.1234567890123);
  ExpectSameScenario(ParseScenario(s.source_text, kFaults), s);
  EXPECT_EQ(ApplyOverridesToText(LoadScenario(kFaults).source_text, kFaults, Sets({"run.seed=7",
                "channel.loss={ model = \"bernoulli\", probability = 0.1 }",
                "control.k1=0.1234567890123", "event[1].at_s=150.5"})),
            s.source_text);
}

std::string FileText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

/// What a campaign's plan reads of a scenario, and what a run depends on most.
std::string Summary(const Scenario& s) {
  std::ostringstream o;
  o << s.name << " " << s.duration_s << " " << s.control_rate_hz << " " << s.seed << " "
    << s.followers << " " << s.edges.size() << " " << s.leader_links.size() << " " << s.k1 << " "
    << s.k2 << " " << static_cast<int>(s.delay.kind) << " " << s.delay.base_s << " "
    << s.delay.amplitude_s << " " << s.links.size() << " " << s.modems.size() << " "
    << static_cast<int>(s.disturbance.kind) << " " << s.initial.size() << " " << s.events.size();
  for (const ScenarioEvent& e : s.events) o << " " << static_cast<int>(e.kind) << "@" << e.at_s;
  return o.str();
}

// A campaign checks its points on a template parsed once: each set of overrides gives the
// scenario, or the message, that parsing the file with them does.
TEST(ScenarioOverrides, TemplateReadsAsParseScenario) {
  const std::vector<std::pair<std::string, std::vector<std::string>>> cases = {
      {kExample2, {}},
      {kExample2, {"channel.delay.base_s=0.3", "control.k2=1.7"}},
      {kExample2, {"channel.delay={ model = \"constant\", base_s = 0.2 }", "run.duration_s=30"}},
      {kExample2, {"channel.delay.base_s=-1"}},
      {kExample2, {"nosuch.key=1"}},
      {kFaults, {"swarm.edges=[]"}},
      {kFaults, {"event[1]={at_s=101, kind=\"topology\", leader_links=[2]}"}},
      {kFaults, {"run.seed=7", "run.duration_s=90"}},
  };
  for (const auto& [path, flags] : cases) {
    const std::string text = FileText(path);
    const ScenarioTemplate t(text, path);
    std::string parsed, read;
    try {
      parsed = Summary(ParseScenario(text, path, Sets(flags)));
    } catch (const ScenarioError& e) {
      parsed = std::string("error: ") + e.what();
    }
    try {
      const Scenario s = t.Read(Sets(flags));
      EXPECT_TRUE(s.source_text.empty());
      read = Summary(s);
    } catch (const ScenarioError& e) {
      read = std::string("error: ") + e.what();
    }
    EXPECT_EQ(read, parsed) << path << " with " << flags.size() << " overrides";
  }
}

}  // namespace
}  // namespace shoal
