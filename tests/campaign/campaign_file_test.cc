#include "campaign/campaign_file.h"

#include <gtest/gtest.h>

#include <string>

namespace shoal {
namespace {

/// The message of the CampaignError that parsing `text` throws ("" if none).
std::string ErrorOf(const std::string& text) {
  try {
    ParseCampaign(text, "dir/sweep.toml");
  } catch (const CampaignError& e) {
    return e.what();
  }
  return "";
}

constexpr const char* kHead = "[campaign]\nscenario = \"../s.toml\"\n";

TEST(CampaignFile, ReadsEveryKey) {
  const Campaign c = ParseCampaign(
      std::string(kHead) +
          "engine = \"lockstep\"\nduration_s = 20\ntimeout_s = 30\nworkers = 3\n"
          "set = [\"control.k1=0.3\"]\n"
          "[[axis]]\nkey = \"channel.delay.base_s\"\nvalues = [0.1, { a = \"x\" }]\n"
          "[[axis]]\nkey = \"control.k2\"\nfrom = 1\nto = 4\nsteps = 4\nlog = true\n"
          "[[axis]]\nkey = \"run.seed\"\nrange = [1, 3]\n"
          "[pass]\nconverged = true\nfinal_position_error_m = { max = 0.5 }\n"
          "\"channel.delay_error_p99_s\" = { min = 0, max = 0.001 }\n"
          "[map]\nx = \"control.k2\"\ny = \"channel.delay.base_s\"\n",
      "dir/sweep.toml");
  EXPECT_EQ(c.scenario, "s.toml");  // relative to the campaign file's directory
  EXPECT_EQ(c.engine, CampaignEngine::kLockstep);
  EXPECT_EQ(c.duration_s, 20);
  EXPECT_EQ(c.timeout_s, 30);
  EXPECT_EQ(c.workers, 3);
  ASSERT_EQ(c.set.size(), 1u);
  EXPECT_EQ(c.set[0].text, "control.k1=0.3");
  EXPECT_EQ(c.set[0].line, 7);
  ASSERT_EQ(c.axes.size(), 3u);
  EXPECT_EQ(c.axes[0].line, 8);
  EXPECT_EQ(c.axes[0].values[0], "0.1");
  EXPECT_EQ(c.axes[0].values[1], "{ a = \"x\" }");
  EXPECT_EQ(c.axes[0].json_values[1]["a"], "x");
  EXPECT_EQ(c.axes[1].kind, CampaignAxis::Kind::kFromTo);
  EXPECT_TRUE(c.axes[1].log);
  EXPECT_EQ(c.axes[2].GridCount(), 3);
  EXPECT_EQ(PointCount(c), 2 * 4 * 3);
  ASSERT_EQ(c.pass.size(), 3u);
  EXPECT_EQ(c.pass[0].key, "converged");
  EXPECT_EQ(*c.pass[0].equals, true);
  EXPECT_EQ(*c.pass[1].max, 0.5);
  EXPECT_FALSE(c.pass[1].min.has_value());
  EXPECT_EQ(c.pass[2].key, "channel.delay_error_p99_s");
  EXPECT_EQ(c.map_x, "control.k2");
}

TEST(CampaignFile, DottedPassKeysWalkDown) {
  const Campaign c = ParseCampaign(std::string(kHead) + "[pass]\nchannel.p99 = { max = 1 }\n"
                                   "[pass.a]\nb = \"x\"\n", "c.toml");
  ASSERT_EQ(c.pass.size(), 2u);
  EXPECT_EQ(c.pass[0].key + c.pass[1].key, "channel.p99a.b");
}

TEST(CampaignFile, UnknownKeysSuggestTheClosest) {
  EXPECT_EQ(ErrorOf(std::string(kHead) + "engin = \"sim\"\n"),
            "dir/sweep.toml:3: campaign.engin: unknown key \"engin\" in [campaign]; did you "
            "mean 'engine'?");
  EXPECT_NE(ErrorOf(std::string(kHead) + "[[axis]]\nkey = \"a\"\nvalue = [1]\n")
                .find("dir/sweep.toml:5: axis[0].value: unknown key \"value\" in [[axis]]; did "
                      "you mean 'values'?"),
            std::string::npos);
  EXPECT_NE(ErrorOf(std::string(kHead) + "engine = \"simm\"\n").find("did you mean \"sim\"?"),
            std::string::npos);
  EXPECT_NE(ErrorOf(std::string(kHead) + "[pass]\nx = { mx = 1 }\n").find("did you mean 'max'?"),
            std::string::npos);
}

TEST(CampaignFile, RefusesBadInput) {
  EXPECT_NE(ErrorOf("[campaign]\nengine = \"sim\"\n").find("campaign.scenario: missing"),
            std::string::npos);
  EXPECT_NE(ErrorOf("x = [").find("TOML syntax error"), std::string::npos);
  EXPECT_NE(ErrorOf(std::string(kHead) + "[[axis]]\nkey = \"a\"\n").find("has no values"),
            std::string::npos);
  EXPECT_NE(ErrorOf(std::string(kHead) + "[[axis]]\nkey = \"a\"\nvalues = [1]\nrange = [1, 2]\n")
                .find("more than one kind"),
            std::string::npos);
  EXPECT_NE(ErrorOf(std::string(kHead) + "[[axis]]\nkey = \"a\"\nfrom = 0\nto = 1\n")
                .find("axis[0].steps: missing"),
            std::string::npos);
  EXPECT_NE(ErrorOf(std::string(kHead) + "[[axis]]\nkey = \"a\"\nfrom = 0\nto = 1\nsteps = 3\n"
                                         "log = true\n").find("needs from and to both positive"),
            std::string::npos);
  EXPECT_NE(ErrorOf(std::string(kHead) + "[[axis]]\nkey = \"a\"\nvalues = [1]\n"
                                         "[[axis]]\nkey = \"a\"\nvalues = [2]\n")
                .find("the key of another axis"),
            std::string::npos);
  EXPECT_NE(ErrorOf(std::string(kHead) + "sampling = \"lhs\"\n").find("campaign.samples: missing"),
            std::string::npos);
  EXPECT_NE(ErrorOf(std::string(kHead) + "samples = 3\n").find("only used with sampling"),
            std::string::npos);
  // Settings a grid does not use are refused, not ignored.
  EXPECT_NE(ErrorOf(std::string(kHead) + "seed = 7\n").find("campaign.seed: only used with sampling"),
            std::string::npos);
  EXPECT_NE(ErrorOf(std::string(kHead) + "sampling = \"lhs\"\nsamples = 4\n"
                    "[[axis]]\nkey = \"a\"\nfrom = 0\nto = 1\nsteps = 7\n")
                .find("axis[0].steps: only used with sampling = \"grid\""),
            std::string::npos);
  EXPECT_NE(ErrorOf(std::string(kHead) + "[pass]\nx = { min = 2, max = 1 }\n").find("min is above max"),
            std::string::npos);
  EXPECT_NE(ErrorOf(std::string(kHead) + "[pass]\nx = [1]\n").find("pass.x: must be"),
            std::string::npos);
  EXPECT_NE(ErrorOf(std::string(kHead) + "[[axis]]\nkey = \"a\"\nvalues = [1]\n[map]\nx = \"b\"\n")
                .find("map.x: not the key of an axis"),
            std::string::npos);
  EXPECT_NE(ErrorOf(std::string(kHead) + "set = [\"novalue\"]\n").find("must be KEY=VALUE"),
            std::string::npos);
}

TEST(CampaignFile, LimitsAgainstHostileFiles) {
  std::string many = kHead;
  for (int i = 0; i < 17; ++i) many += "[[axis]]\nkey = \"k" + std::to_string(i) + "\"\nvalues = [1]\n";
  EXPECT_NE(ErrorOf(many).find("more than 16 axes"), std::string::npos);
  // 1000 x 1000 x 2 values: over a million points, refused at the axis that crosses it.
  std::string big = kHead;
  for (int i = 0; i < 3; ++i) {
    big += "[[axis]]\nkey = \"k" + std::to_string(i) + "\"\nrange = [1, " +
           (i < 2 ? "1000" : "2") + "]\n";
  }
  const std::string error = ErrorOf(big);
  EXPECT_NE(error.find("dir/sweep.toml:9: axis k2: the grid has more than 1000000 points"),
            std::string::npos) << error;
  EXPECT_NE(ErrorOf(std::string(kHead) + "[[axis]]\nkey = \"a\"\nrange = [0, 5000000]\n")
                .find("spans more than 1000000"),
            std::string::npos);
  EXPECT_NE(ErrorOf(std::string(kHead) + "sampling = \"lhs\"\nsamples = 1000001\n")
                .find("campaign.samples"),
            std::string::npos);
  EXPECT_NE(ErrorOf(std::string(kMaxCampaignBytes + 1, '#')).find("larger than"), std::string::npos);
}

TEST(CampaignFile, KeysNestedTooDeepAreRefusedBeforeParsing) {
  // toml++ builds and frees one table per key component recursively: 200000 of them
  // overflowed the stack (a segfault) before the depth was counted first.
  std::string deep;
  for (int i = 0; i < 200000; ++i) deep += "p.";
  const std::string kMessage =
      ": TOML syntax error: a key or table nests more than 256 tables deep";
  EXPECT_EQ(ErrorOf(std::string(kHead) + deep + "q = 1\n"), "dir/sweep.toml:3" + kMessage);
  EXPECT_EQ(ErrorOf(std::string(kHead) + "[pass]\nconverged = true\n" + deep + "q = 1\n"),
            "dir/sweep.toml:5" + kMessage);
  EXPECT_EQ(ErrorOf(std::string(kHead) + "[" + deep + "q]\n"), "dir/sweep.toml:3" + kMessage);
  EXPECT_EQ(ErrorOf(std::string(kHead) + "[pass]\nx = { " + deep + "q = 1 }\n"),
            "dir/sweep.toml:4" + kMessage);
  try {
    ParseCampaign(deep + "q = 1\n", "");
    ADD_FAILURE() << "no error";
  } catch (const CampaignError& e) {
    EXPECT_EQ(std::string(e.what()), "<campaign>:1" + kMessage);
  }
  // 256 tables deep ([campaign] and 255 key components) is within the limit: the file is
  // parsed, and its key is unknown.
  std::string limit;
  for (int i = 0; i < 254; ++i) limit += "p.";
  const std::string error = ErrorOf(std::string(kHead) + limit + "q = 1\n");
  EXPECT_EQ(error.find("nests more than"), std::string::npos) << error;
  EXPECT_NE(error.find("dir/sweep.toml:3:"), std::string::npos) << error;
}

TEST(CampaignFile, LoadReportsUnreadableFiles) {
  try {
    LoadCampaign("/nonexistent/sweep.toml");
    ADD_FAILURE() << "no error";
  } catch (const CampaignError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/sweep.toml: cannot read campaign file"),
              std::string::npos) << e.what();
  }
}

TEST(CampaignFile, FloatTextReadsBackExactly) {
  EXPECT_EQ(TomlFloatText(2.0), "2.0");
  EXPECT_EQ(TomlFloatText(0.1), "0.1");
  EXPECT_EQ(TomlFloatText(1e20), "1e+20");
  EXPECT_EQ(std::stod(TomlFloatText(0.1 + 0.2)), 0.1 + 0.2);
}

}  // namespace
}  // namespace shoal
