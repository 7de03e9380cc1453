// `shoal design` as a user runs it: bad input (exit 2, clear messages), the JSON keys and
// the paper's numbers, the verdict and its exit status, and advice that really works (--advise,
// --write-scenario and the scenario it writes).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "tests/integration/test_util.h"

namespace shoal {
namespace {

using Json = nlohmann::ordered_json;
using shoal::testing::ParseJson;
using shoal::testing::ReadFile;
using shoal::testing::RunShoal;
using shoal::testing::SourcePath;
using shoal::testing::TmpPath;

std::string Example(int n) {
  return SourcePath("scenarios/paper_example" + std::to_string(n) + ".toml");
}

/// Paper Example 2 with the absolute factor f(x_i) (relative_to_leader = false), which
/// Theorem 3 does not cover, written to the test directory; returns its path.
std::string AbsoluteFactorScenario(const std::string& name) {
  std::string text = ReadFile(Example(2));
  const std::string from = "relative_to_leader = true", to = "relative_to_leader = false";
  const std::size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos);
  if (at != std::string::npos) text.replace(at, from.size(), to);
  const std::string path = TmpPath(name);
  FILE* f = std::fopen(path.c_str(), "w");
  EXPECT_NE(f, nullptr) << path;
  if (f) {
    std::fputs(text.c_str(), f);
    std::fclose(f);
  }
  return path;
}

/// j at the JSON pointer `path` as a double; fails the test (and gives NaN) where it is
/// missing or not a number.
double Num(const Json& j, const std::string& path) {
  const Json::json_pointer ptr(path);
  if (!j.contains(ptr) || !j.at(ptr).is_number()) {
    ADD_FAILURE() << path << " is missing or not a number";
    return std::nan("");
  }
  return j.at(ptr).get<double>();
}

TEST(DesignCli, AssumptionOneViolationNamesTheUnreachableFollowers) {
  const auto r = RunShoal(
      "design " + SourcePath("tests/data/bad_scenarios/unreachable_followers.toml"), "d_a1");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("shoal design:"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("followers 2, 4 cannot be reached from the leader (Assumption 1)"),
            std::string::npos)
      << r.err;
  EXPECT_TRUE(r.out.empty()) << r.out;
}

TEST(DesignCli, NonPositiveGainsAndDelaysExitTwoNamingTheFlag) {
  const struct {
    std::string args, expect;
  } cases[] = {
      {"--k1 0", "--k1 must be a positive number (got 0)"},
      {"--k1 -0.5", "--k1 must be a positive number (got -0.5)"},
      {"--k2 0", "--k2 must be a positive number (got 0)"},
      {"--k2 -1", "--k2 must be a positive number (got -1)"},
      {"--k1 nan", "--k1 must be a positive number"},
      {"--h 0", "--h must be a positive number (got 0)"},
      {"--h -0.1", "--h must be a positive number (got -0.1)"},
      {"--k1 1e300 --k2 1e300", "--k1 must be at most 1e+06 (got 1e+300)"},
      {"--h 1e300", "--h must be at most 1e+09 (got 1e+300)"},
      {"--kappa 1", "--kappa must be in [0, 1) (got 1)"},
      {"--kappa -0.2", "--kappa must be in [0, 1)"},
      {"--alpha 0", "--alpha must be a positive number"},
      {"--beta -2", "--beta must be a positive number"},
      {"--rho0 -1", "--rho0 must be a number in [0, 1e6]"},
      {"--rho0 1e300", "--rho0 must be a number in [0, 1e6] (got 1e+300)"},
      {"--safety 0.5", "--safety must be a number >= 1"},
      {"--tune-horizon 0", "--tune-horizon must be a positive number"},
      {"--rho0 0.1", "--rho0 0.1 is below the uncertain factor's own Lipschitz constant 0.5"},
      {"--certificate /nonexistent-dir/c.json", "--certificate: /nonexistent-dir/c.json: cannot write"},
      {"--empirical --empirical-duration -1", "--empirical-duration must be a positive number"},
  };
  for (const auto& c : cases) {
    const auto r = RunShoal("design " + Example(2) + " " + c.args, "d_bad");
    EXPECT_EQ(r.status, 2) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find("shoal design: " + c.expect), std::string::npos) << c.args << "\n"
                                                                          << r.err;
    EXPECT_TRUE(r.out.empty()) << c.args << "\n" << r.out;
  }
}

TEST(DesignCli, RhoZeroWithAnOceanCurrentIsRefused) {
  const std::string scen = SourcePath("scenarios/remus_realistic.toml") +
                           " --set disturbance.model=ocean_current";
  const auto r = RunShoal("design " + scen + " --rho0 0", "d_rho0_current");
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_NE(r.err.find("shoal design: --rho0 0 says there is no uncertain factor, but the "
                       "scenario's ocean current flows at up to 1 m/s"),
            std::string::npos)
      << r.err;
  EXPECT_TRUE(r.out.empty()) << r.out;
  const auto still =
      RunShoal("design " + scen + " --rho0 0 --set disturbance.max_speed_mps=0 "
               "--set disturbance.speed_mps=0", "d_rho0_still");
  EXPECT_NE(still.status, 2) << still.err;
}

// Theorem 1 certifies the delay-free continuous-time loop, but a run uses each state at the
// first control tick after it arrives: gains whose exact margin (7.7 ms here) is below one
// control period (20 ms) do not converge in shoal sim and are not certified.
TEST(DesignCli, AMarginBelowOneControlPeriodIsNotCertified) {
  const std::string path = TmpPath("d_fast_gains.toml");
  std::ofstream(path) << "[run]\nduration_s = 60\n[swarm]\nfollowers = 1\nleader_links = [1]\n"
                         "[control]\nk1 = 1000.0\nk2 = 200.0\n"
                         "[vehicle]\ntau_max = [10000, 10000, 10000, 5000, 5000]\n";
  const auto r = RunShoal("design " + path, "d_fast_gains");
  EXPECT_EQ(r.status, 1) << r.out << r.err;
  EXPECT_NE(r.out.find("NOT CERTIFIED"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("the delay acts as up to 0.02 s"), std::string::npos) << r.out;
  EXPECT_EQ(RunShoal("sim " + path + " --quiet", "d_fast_gains_sim").status, 1);
  // Gains with room for the period stay certified.
  const auto slow = RunShoal("design " + path + " --k1 1 --k2 2", "d_fast_gains_slow");
  EXPECT_EQ(slow.status, 0) << slow.out << slow.err;
}

TEST(DesignCli, BadScenarioFilesAndFlagsExitTwo) {
  for (const std::string& args :
       {"design " + SourcePath("tests/data/bad_scenarios/k1_zero.toml"),
        "design " + SourcePath("tests/data/bad_scenarios/k2_negative.toml"),
        std::string("design /nonexistent/scenario.toml"), "design " + Example(2) + " --k1 abc",
        "design " + Example(2) + " --no-such-flag", "design " + Example(2) + " --tune-cost foo",
        std::string("design")}) {
    const auto r = RunShoal(args, "d_badfile");
    EXPECT_EQ(r.status, 2) << args << "\n" << r.err;
    EXPECT_FALSE(r.err.empty()) << args;
  }
  const auto help = RunShoal("design --help", "d_help");
  EXPECT_EQ(help.status, 0);
  EXPECT_NE(help.out.find("--empirical"), std::string::npos);
}

// The JSON object has the documented keys (docs/theory.md), each where it belongs, and the
// paper's numbers.
TEST(DesignCli, JsonHasThePaperNumbers) {
  const auto r = RunShoal("design " + Example(2) + " --json", "d_json");
  ASSERT_TRUE(r.status == 0 || r.status == 1) << r.err;
  ASSERT_EQ(r.out.front(), '{');
  ASSERT_EQ(r.out.substr(r.out.size() - 2), "}\n");
  Json j = ParseJson(r.out);
  for (const char* path :
       {"/H_eigenvalues", "/assumption1", "/theorem1", "/theorem1/W", "/theorem1/W_eigenvalues",
        "/theorem1/M2_eigenvalues", "/theorem1/k1_min", "/theorem1/k2_min",
        "/theorem1/k1_min_corrected", "/theorem1/k2_min_corrected",
        "/theorem1/P_max_eigenvalue", "/theorem2", "/delay_margin_s", "/verdict",
        "/uncertain_factor/lambda_max_G2", "/uncertain_factor/lambda_max_J2",
        "/uncertain_factor/rho0"}) {
    EXPECT_TRUE(j.contains(Json::json_pointer(path))) << path;
  }
  EXPECT_EQ(j["assumption1"], Json::parse(R"({"holds":true,"unreachable_followers":[]})"));
  EXPECT_NEAR(Num(j, "/theorem1/k1_min"), 0.1286, 1e-4);
  EXPECT_NEAR(Num(j, "/theorem1/k1_min_corrected"), 0.1754, 1e-4);
  EXPECT_NEAR(Num(j, "/theorem1/P_max_eigenvalue"), -7.3e-4, 0.05e-4);
  EXPECT_NEAR(Num(j, "/delay_margin_s"), 0.3435, 1e-4);
  EXPECT_NEAR(Num(j, "/delay/h_s"), 0.15, 1e-12);
  EXPECT_NEAR(Num(j, "/delay/kappa"), 0.05, 1e-12);
  EXPECT_NEAR(Num(j, "/uncertain_factor/lambda_max_G2"), 0.0004, 1e-12);
  EXPECT_NEAR(Num(j, "/uncertain_factor/lambda_max_J2"), 0.25, 1e-12);
  // Exit status follows the verdict.
  ASSERT_TRUE(j["verdict"]["certified"].is_boolean()) << j["verdict"];
  EXPECT_EQ(r.status, j["verdict"]["certified"].get<bool>() ? 0 : 1);
}

// The --json output is one JSON document (nlohmann parses it), in the report's order, with
// numbers at full precision: the margin is exactly the smallest per-eigenvalue margin.
TEST(DesignCli, JsonParsesAndKeepsTheReportOrder) {
  const auto r = RunShoal("design " + Example(2) + " --json", "d_json_parse");
  ASSERT_EQ(r.status, 1) << r.err;
  Json j = ParseJson(r.out);
  std::vector<std::string> keys;
  for (auto it = j.begin(); it != j.end(); ++it) keys.push_back(it.key());
  ASSERT_GE(keys.size(), 3u);
  EXPECT_EQ(keys.front(), "scenario");
  EXPECT_EQ(keys.back(), "verdict");
  EXPECT_EQ(j["verdict"]["certified"], false);
  EXPECT_EQ(j["theorem3"]["evaluated"], true);
  EXPECT_EQ(j["delay"]["time_varying"], true);
  const double margin = Num(j, "/delay_margin_s");
  EXPECT_NEAR(margin, 0.3435, 5e-5);
  double smallest = 1e9;
  ASSERT_FALSE(j["delay_margin"]["per_eigenvalue"].empty());
  for (const auto& e : j["delay_margin"]["per_eigenvalue"]) {
    smallest = std::min(smallest, e["tau_s"].get<double>());
  }
  EXPECT_EQ(margin, smallest);  // the same double, written twice without rounding
}

// Theorem 3 through the CLI: without an uncertain factor the corrected LMI certifies a
// time-varying delay of 0.15 s at the scenario's gains, up to max_delay_s below the exact
// constant-delay margin; with paper Example 2's factor it is infeasible (the necessary
// condition k2 lambda_min(H) > sqrt(2 lambda_max(J^2)) fails: 0.539 < 0.707), so the
// verdict is "not certified" and the certificate file says so.
TEST(DesignCli, Theorem3CertifiesWithoutTheFactorAndNotWithIt) {
  const auto ok = RunShoal("design " + Example(1) + " --h 0.15 --kappa 0.05 --json", "d_t3a");
  EXPECT_EQ(ok.status, 0) << ok.out << ok.err;
  Json a = ParseJson(ok.out);
  EXPECT_EQ(a["theorem3"]["evaluated"], true) << a["theorem3"];
  EXPECT_EQ(a["theorem3"]["feasible"], true) << a["theorem3"];
  const double max_delay = Num(a, "/theorem3/max_delay_s");
  EXPECT_GT(max_delay, 0.15);
  EXPECT_LT(max_delay, Num(a, "/delay_margin_s"));  // the LMI is only sufficient
  ASSERT_TRUE(a["verdict"]["by"].is_string()) << a["verdict"];
  EXPECT_EQ(a["verdict"]["by"].get<std::string>().rfind("Theorem 3", 0), 0u) << a["verdict"];

  const std::string cert = TmpPath("d_t3_cert.json");
  const auto no = RunShoal("design " + Example(2) + " --json --certificate " + cert, "d_t3b");
  EXPECT_EQ(no.status, 1) << no.out << no.err;
  Json b = ParseJson(no.out);
  EXPECT_EQ(b["theorem3"]["feasible"], false) << b["theorem3"];
  EXPECT_EQ(b["theorem3"]["feasible_at_zero_delay"], false) << b["theorem3"];
  EXPECT_GT(Num(b, "/theorem3/paper_multipliers_max_eigenvalue"), 0.0);
  EXPECT_EQ(b["theorem3"]["certificate"], cert);
  Json c = ParseJson(ReadFile(cert));
  EXPECT_EQ(c["certifies"], false);
  for (const char* m : {"Q", "Psi", "Z", "X", "Y", "Phi"}) {
    ASSERT_TRUE(c["matrices"].contains(m)) << m;
    EXPECT_TRUE(c["matrices"][m].is_array() && !c["matrices"][m].empty()) << m;
  }
}

// Theorem 3 covers only factors of the form f(x_i) - f(x_0): with the absolute factor
// (relative_to_leader = false) it is not evaluated, and says why, whatever the LMI would give.
TEST(DesignCli, Theorem3IsNotEvaluatedForAFactorItDoesNotCover) {
  const std::string path = AbsoluteFactorScenario("d_abs.toml");
  const auto r = RunShoal("design " + path + " --k1 0.5 --k2 2.5 --h 0.05 --kappa 0 --json", "d_abs");
  EXPECT_EQ(r.status, 1) << r.out << r.err;
  Json t3 = ParseJson(r.out)["theorem3"];
  ASSERT_TRUE(t3.is_object()) << r.out;
  EXPECT_EQ(t3.begin().key(), "evaluated") << t3;
  EXPECT_EQ(t3["evaluated"], false) << t3;
  EXPECT_EQ(t3.size(), 2u) << t3;  // evaluated and reason: no feasible, no max_delay_s
  ASSERT_TRUE(t3["reason"].is_string()) << t3;
  EXPECT_NE(t3["reason"].get<std::string>().find("relative_to_leader = false"),
            std::string::npos)
      << t3;
  // No assumed bound makes an absolute factor vanish at consensus: --rho0 certifies nothing.
  const auto rho = RunShoal("design " + path + " --k1 0.5 --k2 2.5 --h 0.05 --kappa 0 --rho0 0.5 --json",
                            "d_abs_rho0");
  EXPECT_EQ(rho.status, 1) << rho.out << rho.err;
  const Json j = ParseJson(rho.out);
  EXPECT_EQ(j["theorem3"]["evaluated"], false) << j["theorem3"];
  EXPECT_EQ(j["uncertain_factor"]["theorems_apply"], false) << j["uncertain_factor"];
}

// A channel event whose delay is larger than the one it takes over from makes tau jump
// up: Assumption 3 (tau' <= kappa < 1) cannot hold, and Theorem 3 says so rather than
// calling the delays "different constants" with kappa = 0. An event that only lowers the
// delay, to the end of the run, keeps kappa = 0.
TEST(DesignCli, ADelayThatJumpsUpAtAnEventHasNoBoundedRate) {
  const std::string base =
      "[run]\nname = \"one\"\nduration_s = 100\ncontrol_rate_hz = 50\n"
      "[swarm]\nfollowers = 1\nleader_links = [1]\nedges = []\n"
      "[control]\nk1 = 0.18\nk2 = 1.152\noffsets_m = [[5.0, 0.0, 0.0]]\n"
      "[leader]\npath = \"line\"\nstart_m = [0.0, 0.0, 10.0]\nvelocity_mps = [1.5, 0.0, 0.0]\n"
      "[channel.delay]\nmodel = \"constant\"\nbase_s = 0.2\n"
      "[disturbance]\nmodel = \"none\"\n"
      "[[follower]]\nid = 1\nposition_m = [0.0, 0.0, 10.0]\n";
  const auto write = [](const std::string& name, const std::string& text) {
    const std::string path = TmpPath(name);
    std::ofstream(path) << text;
    return path;
  };
  const std::string up = write("d_jump_up.toml", base +
      "[[event]]\nat_s = 10\nkind = \"channel\"\ndelay = { model = \"constant\", base_s = 0.5 }\n");
  auto r = RunShoal("design " + up + " --json", "d_jump_up");
  Json j = ParseJson(r.out);
  EXPECT_EQ(j["theorem3"]["evaluated"], false) << r.out << r.err;
  EXPECT_NE(j["theorem3"].value("reason", "").find("jump up"), std::string::npos) << j["theorem3"];
  const std::string down = write("d_jump_down.toml", base +
      "[[event]]\nat_s = 10\nkind = \"channel\"\ndelay = { model = \"constant\", base_s = 0.1 }\n");
  r = RunShoal("design " + down + " --json", "d_jump_down");
  j = ParseJson(r.out);
  EXPECT_EQ(j["theorem3"]["evaluated"], true) << r.out << r.err;
}

TEST(DesignCli, ReadableReportHasEverySectionAndAVerdictLine) {
  const auto r = RunShoal("design " + Example(1), "d_text");
  EXPECT_EQ(r.status, 0) << r.out << r.err;  // no delay, no factor: Theorem 1 certifies
  for (const char* s : {"H eigenvalues: 3.8794, 3, 1.6527, 1, 0.46791", "Assumption 1: holds",
                        "W eigenvalues: 0.1278, 0.1650, 0.2940, 0.5506, 1.1167",
                        "delay_margin_s = 0.3435 s", "verdict: CERTIFIED by Theorem 1"}) {
    EXPECT_NE(r.out.find(s), std::string::npos) << s << "\n" << r.out;
  }
}

// A constant delay above the margin is not certified; the advised gains are (with margin
// exactly safety x h, so a delay of h is certified).
TEST(DesignCli, AdviceForTooLargeADelayWorks) {
  const auto bad = RunShoal("design " + Example(1) + " --h 0.5 --json", "d_adv1");
  EXPECT_EQ(bad.status, 1) << bad.err;
  Json b = ParseJson(bad.out);
  ASSERT_TRUE(b["verdict"]["advice"].is_string()) << b["verdict"];
  const std::string advice = b["verdict"]["advice"].get<std::string>();
  const std::string tag = "scale the gains to k1 = ";
  const std::size_t p = advice.find(tag);
  ASSERT_NE(p, std::string::npos) << advice;
  const double k1 = std::strtod(advice.c_str() + p + tag.size(), nullptr);
  const std::size_t q = advice.find("k2 = ", p);
  ASSERT_NE(q, std::string::npos) << advice;
  const double k2 = std::strtod(advice.c_str() + q + 5, nullptr);
  char args[128];
  std::snprintf(args, sizeof(args), " --h 0.5 --k1 %.6g --k2 %.6g --json", k1, k2);
  const auto good = RunShoal("design " + Example(1) + args, "d_adv2");
  EXPECT_EQ(good.status, 0) << good.out;
  Json g = ParseJson(good.out);
  EXPECT_NEAR(Num(g, "/delay_margin_s"), 1.0, 2e-3);
  EXPECT_EQ(g["verdict"]["by"], "the exact delay margin") << g["verdict"];
}

// --advise on paper Example 2 (docs/theory.md): no scale of the paper's gains is certified
// at h = 0.15 s (exit 1, the verdict of the scenario's own gains), so the advice is the
// scale whose gains Theorem 3 certifies for the largest delay. --write-scenario writes a
// scenario with exactly those gains that `shoal design` and `shoal sim` load, and with
// which the formation converges faster than with the paper's gains.
TEST(DesignCli, AdviseWritesAScenarioThatConverges) {
  const std::string out = TmpPath("d_advise.toml");
  std::remove(out.c_str());
  const auto r = RunShoal(
      "design " + Example(2) + " --advise --write-scenario " + out + " --json", "d_advise");
  EXPECT_EQ(r.status, 1) << r.err;
  Json j = ParseJson(r.out);
  EXPECT_EQ(j["verdict"]["certified"], false);
  ASSERT_TRUE(j.contains("advised_gains")) << r.out;
  Json a = j["advised_gains"];
  EXPECT_EQ(a["evaluated"], true) << a;
  EXPECT_EQ(a["certified_at_h"], false) << a;
  const double k1 = Num(a, "/k1"), k2 = Num(a, "/k2"), c = Num(a, "/scale");
  EXPECT_NEAR(k1, 0.4047, 1e-4);
  EXPECT_NEAR(k2, 1.727, 1e-3);
  EXPECT_NEAR(c, 1.499, 1e-3);
  EXPECT_NEAR(k1, c * c * Num(j, "/gains/k1"), 1e-12);  // along the scale family
  EXPECT_NEAR(k2, c * Num(j, "/gains/k2"), 1e-12);
  EXPECT_NEAR(Num(a, "/theorem3_max_delay_s"), 0.1219, 1e-4);
  EXPECT_NEAR(Num(a, "/delay_margin_s"), 0.2291, 1e-4);
  EXPECT_NEAR(Num(a, "/delay_margin_with_factor_s"), 0.2138, 1e-4);
  EXPECT_EQ(a["scenario_written"], out) << a;

  // The written scenario carries the advised gains to the last bit, and Theorem 3 gives
  // them the same largest delay.
  const auto d = RunShoal("design " + out + " --json", "d_advise_design");
  EXPECT_EQ(d.status, 1) << d.err;
  Json dj = ParseJson(d.out);
  EXPECT_EQ(dj["scenario"], "paper_example2_advised");
  EXPECT_EQ(Num(dj, "/gains/k1"), k1);
  EXPECT_EQ(Num(dj, "/gains/k2"), k2);
  EXPECT_EQ(Num(dj, "/theorem3/max_delay_s"), Num(a, "/theorem3_max_delay_s"));

  const auto sim = RunShoal("sim " + out + " --duration 60 --json", "d_advise_sim");
  EXPECT_EQ(sim.status, 0) << sim.out << sim.err;
  Json s = ParseJson(sim.out);
  EXPECT_EQ(s["converged"], true) << sim.out;
  const auto paper = RunShoal("sim " + Example(2) + " --duration 60 --json", "d_advise_sim0");
  EXPECT_EQ(paper.status, 0) << paper.out << paper.err;
  Json p = ParseJson(paper.out);
  EXPECT_EQ(p["converged"], true) << paper.out;
  EXPECT_NEAR(Num(s, "/convergence_time_s"), 24.52, 0.05);  // docs/theory.md
  EXPECT_NEAR(Num(p, "/convergence_time_s"), 52.54, 0.05);
}

// A --write-scenario path that cannot be written is refused before any solve (exit 2, the
// path named, nothing on stdout); with gains that cannot be advised (Theorem 3 does not
// apply) nothing is written and the exit status is 2.
TEST(DesignCli, WriteScenarioFailuresExitTwo) {
  const auto bad = RunShoal(
      "design " + Example(2) + " --write-scenario /nonexistent-dir/adv.toml --json", "d_ws_bad");
  EXPECT_EQ(bad.status, 2) << bad.err;
  EXPECT_NE(bad.err.find("shoal design: --write-scenario: /nonexistent-dir/adv.toml: cannot "
                         "write there"),
            std::string::npos)
      << bad.err;
  EXPECT_TRUE(bad.out.empty()) << bad.out;

  const std::string out = TmpPath("d_ws_abs_adv.toml");
  std::remove(out.c_str());
  const auto none = RunShoal("design " + AbsoluteFactorScenario("d_ws_abs.toml") +
                                 " --write-scenario " + out + " --json",
                             "d_ws_none");
  EXPECT_EQ(none.status, 2) << none.err;
  EXPECT_NE(none.err.find("shoal design: --write-scenario: no gains were advised (Theorem 3 "
                          "does not apply"),
            std::string::npos)
      << none.err;
  EXPECT_NE(none.err.find("nothing written"), std::string::npos) << none.err;
  EXPECT_EQ(ParseJson(none.out)["advised_gains"]["evaluated"], false) << none.out;
  EXPECT_FALSE(std::ifstream(out).good()) << out << " was written";
  // Advice evaluated but no scale certified, not even at h = 0: nothing to write either.
  const auto uncertified = RunShoal("design " + Example(2) + " --rho0 5 --write-scenario " + out +
                                        " --json", "d_ws_uncertified");
  EXPECT_EQ(uncertified.status, 2) << uncertified.err;
  EXPECT_NE(uncertified.err.find("no gains were advised"), std::string::npos) << uncertified.err;
  EXPECT_FALSE(std::ifstream(out).good()) << out << " was written";
}

// Theorem 3's LMI has 12 n^2 + 5 n variables: its time grows as n^6, its memory as n^4.
// Enormous valid swarms (tests/data/bad_scenarios/large/) are refused with status 2 and
// the estimate in well under a second, naming --allow-large; without them, 100 dense
// followers ran past 20 s (an estimated 5000 h and 119 GiB).
TEST(DesignCli, EnormousSwarmsAreRefusedWithTheirEstimate) {
  const std::string dir = SourcePath("tests/data/bad_scenarios/large");
  for (const char* name : {"hundred_dense_followers_with_long_delays.toml",
                           "thousand_followers_in_a_chain_for_a_day.toml",
                           "four_hundred_dense_followers_for_100_minutes.toml"}) {
    const auto t0 = std::chrono::steady_clock::now();
    const auto r = RunShoal("design '" + dir + "/" + name + "'", "design_large");
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    EXPECT_EQ(r.status, 2) << name << "\n" << r.err;
    EXPECT_NE(r.err.find("refusing a large design (Theorem 3's LMI for "), std::string::npos)
        << r.err;
    EXPECT_NE(r.err.find(" h and "), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("GiB of memory"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("--allow-large"), std::string::npos) << r.err;
    EXPECT_TRUE(r.out.empty()) << r.out.substr(0, 300);
    EXPECT_LT(s, 1.0 * testing::kTimeLimitScale) << name;
  }
  // --empirical runs shoal sim again and again: a run too large for it is refused first.
  const auto t0 = std::chrono::steady_clock::now();
  const auto empirical = RunShoal("design " + Example(1) + " --empirical --empirical-duration 1e9",
                                  "design_large_empirical");
  EXPECT_EQ(empirical.status, 2) << empirical.err;
  EXPECT_NE(empirical.err.find("--empirical: each of its runs is large: refusing a large run"),
            std::string::npos)
      << empirical.err;
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(),
            1.0 * testing::kTimeLimitScale);
  const auto hundred = RunShoal("design '" + dir + "/hundred_dense_followers_with_long_delays.toml'",
                                "design_large_100");
  EXPECT_NE(hundred.err.find("100 followers and 9901 links: 120500 variables"), std::string::npos)
      << hundred.err;
}

// The guard is for Theorem 3's SDP: a swarm as large whose delay Theorem 3 does not cover
// (uniform jitter) solves no SDP and is designed at once; a small one runs as before with
// --allow-large.
TEST(DesignCli, TheSizeGuardOnlyStopsTheSdp) {
  std::string text = ReadFile(SourcePath(
      "tests/data/bad_scenarios/large/hundred_dense_followers_with_long_delays.toml"));
  const std::size_t at = text.find("[channel.delay]");
  ASSERT_NE(at, std::string::npos);
  text = text.substr(0, at) +
         "[channel.delay]\nmodel = \"uniform\"\nbase_s = 0.1\namplitude_s = 0.05\n";
  const std::string path = TmpPath("hundred_dense_jitter.toml");
  {
    std::ofstream out(path);
    out << text;
  }
  const auto r = RunShoal("design '" + path + "'", "design_large_jitter");
  EXPECT_NE(r.status, 2) << r.err;
  EXPECT_NE(r.out.find("verdict:"), std::string::npos) << r.out.substr(0, 500) << r.err;
  const auto a = RunShoal("design " + Example(2) + " --json", "design_small");
  const auto b = RunShoal("design " + Example(2) + " --json --allow-large", "design_small_allow");
  EXPECT_EQ(a.status, 1) << a.err;  // not certified: Example 2's factor
  EXPECT_EQ(b.status, 1) << b.err;
  EXPECT_EQ(ParseJson(a.out)["verdict"], ParseJson(b.out)["verdict"]);
}

// CSDP and Ceres, with the 21 libraries they bring, are in a module that only shoal
// design (and a stability map's theory) loads: every other command, the campaign's points
// above all, starts without mapping them.
TEST(DesignCli, OnlyTheDesignToolsLoadTheDesignModule) {
  const std::string sim_trace = shoal::testing::TmpPath("design_load_sim.ld");
  const std::string design_trace = shoal::testing::TmpPath("design_load_design.ld");
  const auto traced = [](const std::string& args, const std::string& trace) {
    const std::string cmd = "LD_DEBUG=files " + shoal::testing::ShoalBinary() + " " + args +
                            " >/dev/null 2>" + trace + " </dev/null";
    const int status = std::system(cmd.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  };
  ASSERT_EQ(traced("sim " + Example(2) + " --duration 10 --quiet", sim_trace), 1);  // not converged
  ASSERT_EQ(traced("design " + Example(2), design_trace), 1);  // not certified
  const std::string sim = shoal::testing::ReadFile(sim_trace);
  const std::string design = shoal::testing::ReadFile(design_trace);
  EXPECT_NE(sim.find("libstdc++"), std::string::npos) << "no loader trace: " << sim;
  for (const char* lib : {"libshoal_design_module", "libsdp", "libcholmod", "libgfortran",
                          "libglog", "liblapack"}) {
    EXPECT_EQ(sim.find(lib), std::string::npos) << lib;
  }
  for (const char* lib : {"libshoal_design_module", "libsdp", "libcholmod", "libglog"}) {
    EXPECT_NE(design.find(lib), std::string::npos) << lib;
  }
}

// A module that is missing, or not Shoal's: shoal design says which and what to do, exit 2.
TEST(DesignCli, AMissingOrWrongDesignModuleIsAClearError) {
  struct Case {
    std::string module, expected;
  };
  const Case cases[] = {
      {"/nonexistent/libshoal_design_module.so",
       "shoal design: cannot load the design module: /nonexistent/libshoal_design_module.so: "
       "cannot open shared object file"},
      {"libz.so.1", "shoal design: libz.so.1 is not Shoal's design module"},
  };
  for (const Case& c : cases) {
    setenv("SHOAL_DESIGN_MODULE", c.module.c_str(), 1);
    const auto r = RunShoal("design " + Example(2), "d_nomodule");
    unsetenv("SHOAL_DESIGN_MODULE");
    EXPECT_EQ(r.status, 2) << c.module << r.err;
    EXPECT_EQ(r.err.rfind(c.expected, 0), 0u) << r.err;
    EXPECT_EQ(r.out, "") << r.out;
  }
}

}  // namespace
}  // namespace shoal
