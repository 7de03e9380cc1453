// design/switching and design/formation_delay: per-topology results of a switching
// timeline, the common Lyapunov certificate (CSDP, then an independent check), the
// acoustic delay the formation produces, and how the report shows them.
#include <gtest/gtest.h>

#include <limits>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <string>

#include "core/topology.h"
#include "design/formation_delay.h"
#include "design/report.h"
#include "design/switching.h"
#include "scenario/loader.h"

namespace shoal {
namespace design {
namespace {

Scenario Load(const std::string& rel) {
  return LoadScenario(std::string(SHOAL_SOURCE_DIR) + "/" + rel);
}

ScenarioEvent TopologyEvent(double at_s, std::vector<std::pair<int, int>> edges,
                            std::vector<int> leader_links) {
  ScenarioEvent e;
  e.kind = EventKind::kTopology;
  e.at_s = at_s;
  e.edges = std::move(edges);
  e.leader_links = std::move(leader_links);
  return e;
}

double MaxRealEigenvalue(const Eigen::MatrixXd& A) {
  Eigen::EigenSolver<Eigen::MatrixXd> es(A, false);
  return es.eigenvalues().real().maxCoeff();
}

// Two chains from the leader over three followers, in opposite orders: each H is
// triangular with every eigenvalue 1, so each error system is stable for any k1, k2 > 0.
const std::vector<std::pair<int, int>> kChainUp = {{2, 1}, {3, 2}};    // 0 -> 1 -> 2 -> 3
const std::vector<std::pair<int, int>> kChainDown = {{1, 3}, {3, 2}};  // 0 -> 2 -> 3 -> 1

TEST(Switching, ErrorSystemMatrixIsTheorem1sClosedLoop) {
  const Eigen::MatrixXd H = Topology::Build(3, kChainUp, {1}).H();
  const Eigen::MatrixXd A = ErrorSystemMatrix(H, 0.5, 2.0);
  const theory::Theorem1 t1 = *theory::ComputeTheorem1(H, 0.5, 2.0, 0.05, 6.4);
  // Theorem 1's P = Q(A+B) + (A+B)^T Q with Q = [k1 W, alpha W; alpha W, W].
  Eigen::MatrixXd Q(6, 6);
  Q << 0.5 * t1.W, 0.05 * t1.W, 0.05 * t1.W, t1.W;
  EXPECT_LT((Q * A + A.transpose() * Q - t1.P).norm(), 1e-12);
}

TEST(Switching, CommonCertificateFoundAndVerifiedForTopologiesSharingOne) {
  // H = I (every follower hears only the leader) and H = 4I - J (the complete graph and
  // every leader link; J all ones): symmetric positive definite, and they commute.
  const Eigen::MatrixXd H1 = Topology::Build(3, {}, {1, 2, 3}).H();
  const Eigen::MatrixXd H2 =
      Topology::Build(3, {{1, 2}, {2, 1}, {2, 3}, {3, 2}, {1, 3}, {3, 1}}, {1, 2, 3}).H();
  const std::vector<Eigen::MatrixXd> A = {ErrorSystemMatrix(H1, 0.18, 1.152),
                                          ErrorSystemMatrix(H2, 0.18, 1.152)};
  const CommonLyapunov c = FindCommonLyapunov(A);
  ASSERT_TRUE(c.attempted);
  EXPECT_EQ(c.csdp_return_code, 0) << c.csdp_status;
  ASSERT_TRUE(c.found());
  // The check, redone here from P alone.
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> p(c.P);
  EXPECT_GE(p.eigenvalues().minCoeff(), 0.5 * c.eps);
  for (const Eigen::MatrixXd& a : A) {
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> l(a.transpose() * c.P + c.P * a);
    EXPECT_LE(l.eigenvalues().maxCoeff(), -0.5 * c.eps);
  }
  ASSERT_EQ(c.check.max_eigenvalues.size(), 2u);
}

TEST(Switching, NoCommonCertificateWhenAConvexCombinationIsUnstable) {
  const double k1 = 1.0, k2 = 0.3;
  const Eigen::MatrixXd H1 = Topology::Build(3, kChainUp, {1}).H();
  const Eigen::MatrixXd H2 = Topology::Build(3, kChainDown, {2}).H();
  const Eigen::MatrixXd A1 = ErrorSystemMatrix(H1, k1, k2), A2 = ErrorSystemMatrix(H2, k1, k2);
  ASSERT_LT(MaxRealEigenvalue(A1), 0.0);
  ASSERT_LT(MaxRealEigenvalue(A2), 0.0);
  // A common P would make every convex combination Hurwitz; the midpoint is not, so no
  // common quadratic Lyapunov function exists and none may be reported.
  ASSERT_GT(MaxRealEigenvalue(0.5 * (A1 + A2)), 0.0);
  const CommonLyapunov c = FindCommonLyapunov({A1, A2});
  EXPECT_TRUE(c.attempted);
  EXPECT_FALSE(c.found()) << "CSDP " << c.csdp_return_code << ": " << c.csdp_status;
  EXPECT_NE(c.csdp_return_code, 0);
}

TEST(Switching, TheCheckRejectsAPThatIsNoCertificate) {
  const Eigen::MatrixXd H1 = Topology::Build(3, {}, {1, 2, 3}).H();
  const Eigen::MatrixXd H2 = Topology::Build(3, kChainUp, {1}).H();
  const std::vector<Eigen::MatrixXd> A = {ErrorSystemMatrix(H1, 0.18, 1.152),
                                          ErrorSystemMatrix(H2, 0.18, 1.152)};
  const CommonLyapunov c = FindCommonLyapunov(A);
  ASSERT_TRUE(c.found());
  // The identity is positive definite but A^T + A has a zero block on its diagonal.
  const LyapunovCheck identity = CheckCommonLyapunov(Eigen::MatrixXd::Identity(6, 6), A, 1.0);
  EXPECT_FALSE(identity.verified);
  EXPECT_GE(identity.max_eigenvalues.at(0), 0.0);
  EXPECT_FALSE(CheckCommonLyapunov(-c.P, A, 1.0).verified);
  // A certificate for one topology only.
  EXPECT_FALSE(CheckCommonLyapunov(c.P, {A[0], ErrorSystemMatrix(H2, 1.0, 0.01)}, 1.0).verified);
  Eigen::MatrixXd nan = c.P;
  nan(0, 0) = std::nan("");
  EXPECT_FALSE(CheckCommonLyapunov(nan, A, 1.0).verified);
  EXPECT_FALSE(CheckCommonLyapunov(c.P.topLeftCorner(4, 4), A, 1.0).verified);
  EXPECT_FALSE(FindCommonLyapunov({A[0], Eigen::MatrixXd::Zero(4, 4)}).attempted);
}

TEST(Switching, ReportGivesEveryTopologyAndTheCommonCertificate) {
  Scenario s = Load("scenarios/paper_example1.toml");
  s.events.push_back(TopologyEvent(100.0, {{2, 1}, {3, 2}, {4, 3}, {5, 4}}, {1}));
  s.events.back().line = 42;
  s.events.push_back(TopologyEvent(200.0, {}, {1, 2, 3, 4, 5}));
  const DesignReport r = BuildDesignReport(s, DesignRequest{});
  ASSERT_TRUE(r.switching.has_value());
  const SwitchingSection& sw = *r.switching;
  ASSERT_EQ(sw.topologies.size(), 3u);
  EXPECT_EQ(sw.topologies[0].event_index, -1);
  EXPECT_EQ(sw.topologies[1].event_line, 42);
  EXPECT_EQ(sw.topologies[2].at_s, 200.0);
  // Topology 0's numbers are the report's own.
  EXPECT_EQ(sw.topologies[0].margin_s(), r.margin.tau_s);
  double smallest = 1e9;
  for (const TopologyResult& t : sw.topologies) {
    EXPECT_TRUE(t.unreachable_followers.empty());
    smallest = std::min(smallest, t.margin_s());
  }
  EXPECT_EQ(sw.min_margin_s, smallest);
  EXPECT_EQ(sw.topologies[static_cast<std::size_t>(sw.critical)].margin_s(), smallest);
  EXPECT_EQ(r.GoverningMarginS(), smallest);
  // The chain's H is triangular with eigenvalue 1 (five times), H = I for the star.
  EXPECT_NEAR(sw.topologies[2].margin_s(),
              theory::EigenDelayMargin(theory::Complex(1.0, 0.0), r.k1, r.k2).tau_s, 1e-12);

  const std::string text = DesignReportText(r);
  EXPECT_NE(text.find("switching topology (3 topologies"), std::string::npos) << text;
  EXPECT_NE(text.find("event 1 (line 42)"), std::string::npos) << text;
  const nlohmann::ordered_json j = DesignReportJson(r);
  ASSERT_TRUE(j.contains("switching"));
  EXPECT_EQ(j["switching"]["topologies"].size(), 3u);
  EXPECT_EQ(j["switching"]["topologies"][1]["event_line"], 42);
  EXPECT_EQ(j["switching"]["common_lyapunov"]["found"], sw.common.found());
  // No delay, no factor: the verdict is the common certificate's.
  EXPECT_EQ(r.verdict.certified, sw.common.found());
  if (sw.common.found()) {
    EXPECT_NE(text.find("common Lyapunov certificate found (min eig of P"), std::string::npos);
    EXPECT_NE(r.verdict.Line().find("arbitrary switching"), std::string::npos);
  }
}

TEST(Switching, WithDelaysTheVerdictIsNotCertifiedAndNamesTheSmallestMargin) {
  Scenario s = Load("scenarios/paper_example1.toml");
  s.events.push_back(TopologyEvent(50.0, {{2, 1}, {3, 2}, {4, 3}, {5, 4}}, {1}));
  DesignRequest q;
  q.h_s = 0.1;
  q.kappa = 0.0;
  const DesignReport r = BuildDesignReport(s, q);
  ASSERT_TRUE(r.switching.has_value());
  EXPECT_FALSE(r.verdict.certified);
  EXPECT_NE(r.verdict.reason.find("smallest exact constant-delay margin"), std::string::npos)
      << r.verdict.Line();
  EXPECT_NE(DesignReportText(r).find("x h; h = 0.1 s is below every topology's margin"),
            std::string::npos)
      << DesignReportText(r);
}

TEST(Switching, TheDelayBoundCoversEveryTopologysLinksAndChannelEvents) {
  Scenario s = Load("scenarios/paper_example1.toml");
  s.delay = DelayConfig(DelayKind::kConstant, 0.1, 0.0, 0.0);
  LinkOverride slow;  // a link only the event's topology has
  slow.from = 2;
  slow.to = 1;
  slow.delay = DelayConfig(DelayKind::kConstant, 0.25, 0.0, 0.0);
  s.links.push_back(slow);
  EXPECT_DOUBLE_EQ(BuildDesignReport(s, DesignRequest{}).delay.h_s, 0.1);
  s.events.push_back(TopologyEvent(50.0, {{1, 2}, {3, 2}, {4, 3}, {5, 4}}, {2}));
  DesignReport r = BuildDesignReport(s, DesignRequest{});
  EXPECT_DOUBLE_EQ(r.delay.h_s, 0.25);
  EXPECT_FALSE(r.delay.constant);  // 0.1 s and 0.25 s
  ScenarioEvent swell;
  swell.kind = EventKind::kChannel;
  swell.at_s = 20.0;
  swell.until_s = 30.0;
  swell.delay = DelayConfig(DelayKind::kSinusoid, 0.3, 0.1, 0.5);
  s.events.push_back(swell);
  r = BuildDesignReport(s, DesignRequest{});
  EXPECT_DOUBLE_EQ(r.delay.h_s, 0.4);
  EXPECT_TRUE(r.delay.time_varying);
  // The swell takes over from 0.1 s at 0.3 s and more: tau jumps up, its rate is unbounded.
  EXPECT_FALSE(r.delay.kappa.has_value());
  EXPECT_NE(r.delay_rate_unbounded_why.find("jump up"), std::string::npos)
      << r.delay_rate_unbounded_why;
  // A dip below every delay it takes over from, to the end of the run, only lowers tau:
  // kappa is its own rate.
  ScenarioEvent dip = swell;
  dip.delay = DelayConfig(DelayKind::kSinusoid, 0.05, 0.01, 0.5);
  dip.until_s = std::numeric_limits<double>::infinity();
  s.events.back() = dip;
  r = BuildDesignReport(s, DesignRequest{});
  EXPECT_DOUBLE_EQ(r.delay.h_s, 0.25);
  ASSERT_TRUE(r.delay.kappa.has_value());
  EXPECT_DOUBLE_EQ(*r.delay.kappa, 0.005);
}

// A jump is judged where it can happen: on the event's own links, within the run, and not
// at t = 0, where there is nothing to take over from.
TEST(Switching, OnlyAHandOverThatCanHappenMakesTauJump) {
  Scenario s = Load("scenarios/paper_example1.toml");  // 300 s; the leader talks to 1, 3, 5
  s.delay = DelayConfig(DelayKind::kConstant, 0.2, 0.0, 0.0);
  LinkOverride fast;  // faster than the event's delay, but not on its link
  fast.from = 0;
  fast.to = 3;
  fast.delay = DelayConfig(DelayKind::kConstant, 0.05, 0.0, 0.0);
  s.links.push_back(fast);
  ScenarioEvent lower;
  lower.kind = EventKind::kChannel;
  lower.at_s = 10.0;
  lower.links = {{0, 1}};
  lower.delay = DelayConfig(DelayKind::kConstant, 0.1, 0.0, 0.0);
  s.events = {lower};
  EXPECT_TRUE(BuildDesignReport(s, DesignRequest{}).delay.kappa.has_value());
  s.events[0].until_s = 400.0;  // hands back after the run's end
  EXPECT_TRUE(BuildDesignReport(s, DesignRequest{}).delay.kappa.has_value());
  s.events[0].until_s = 20.0;  // hands back 0.2 s after 0.1 s: up
  EXPECT_FALSE(BuildDesignReport(s, DesignRequest{}).delay.kappa.has_value());
  s.events[0].links.clear();  // every link, the fast one too: up at the start as well
  s.events[0].until_s = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(BuildDesignReport(s, DesignRequest{}).delay.kappa.has_value());
  ScenarioEvent from_start = lower;  // above the default, but from t = 0
  from_start.at_s = 0.0;
  from_start.links.clear();
  from_start.delay = DelayConfig(DelayKind::kConstant, 0.3, 0.0, 0.0);
  s.events = {from_start};
  EXPECT_TRUE(BuildDesignReport(s, DesignRequest{}).delay.kappa.has_value());
}

TEST(Switching, ATopologyWithoutASpanningTreeIsNamedAndNothingIsCertified) {
  Scenario s = Load("scenarios/paper_example1.toml");
  s.events.push_back(TopologyEvent(30.0, {{2, 1}, {3, 2}, {4, 3}}, {1}));  // 5 hears nobody
  s.events.back().line = 7;
  const DesignReport r = BuildDesignReport(s, DesignRequest{});
  ASSERT_TRUE(r.switching.has_value());
  const TopologyResult& t = r.switching->topologies.at(1);
  EXPECT_EQ(t.unreachable_followers, std::vector<int>{5});
  EXPECT_FALSE(t.margin.stable_at_zero);
  EXPECT_EQ(r.switching->critical, 1);
  EXPECT_EQ(r.switching->min_margin_s, 0.0);
  EXPECT_FALSE(r.switching->common.attempted);
  EXPECT_FALSE(r.verdict.certified);
  EXPECT_NE(r.verdict.reason.find("topology 1 (event 1 (line 7)) is unstable"), std::string::npos)
      << r.verdict.Line();
  const std::string text = DesignReportText(r);
  EXPECT_NE(text.find("FAILS"), std::string::npos) << text;
  EXPECT_NE(text.find("common Lyapunov certificate not sought"), std::string::npos) << text;
}

TEST(Switching, WithoutEventsTheReportHasNoSwitchingSection) {
  const Scenario s = Load("scenarios/paper_example1.toml");
  const DesignReport r = BuildDesignReport(s, DesignRequest{});
  EXPECT_FALSE(r.switching.has_value());
  EXPECT_FALSE(r.formation_delay.has_value());
  EXPECT_FALSE(DesignReportJson(r).contains("switching"));
  EXPECT_EQ(DesignReportText(r).find("switching"), std::string::npos);
}

TEST(FormationDelay, LongestLinkOfTheWedgeAndTheModelBound) {
  // acoustic_survey: offsets (-10, -10), (-10, 10), (-20, -20), (-20, 20); the longest
  // link is 3 <-> 4, 40 m; tau = 40 / 1500 + 0.25 + 0.05.
  Scenario s = Load("scenarios/acoustic_survey.toml");
  FormationDelay f = FormationAcousticDelay(s);
  ASSERT_TRUE(f.applicable);
  EXPECT_EQ(f.acoustic_links, 8);  // 6 edges and 2 leader links
  EXPECT_NEAR(f.range_m, 40.0, 1e-12);
  EXPECT_NEAR(f.in_formation_s, 40.0 / 1500.0 + 0.3, 1e-12);
  EXPECT_NEAR(f.model_bound_s, 500.0 / 1500.0 + 0.3, 1e-12);
  EXPECT_EQ(f.beyond_range_links, 0);

  // A topology event adds the leader -> 4 link (|d_4| = 28.3 m) and a channel event gives
  // link 2 -> 1 a slow modem.
  s.events.push_back(TopologyEvent(100.0, {{3, 4}}, {4, 1, 2, 3}));
  ScenarioEvent slow;
  slow.kind = EventKind::kChannel;
  slow.at_s = 10.0;
  slow.links = {{2, 1}};
  slow.delay = s.delay;
  slow.delay->processing_s = 1.0;
  s.events.push_back(slow);
  f = FormationAcousticDelay(s);
  EXPECT_EQ(f.acoustic_links, 8 + 2 + 1);
  EXPECT_EQ(f.from, 2);
  EXPECT_EQ(f.to, 1);
  EXPECT_NEAR(f.in_formation_s, 20.0 / 1500.0 + 1.05, 1e-12);
  EXPECT_NEAR(f.model_bound_s, 500.0 / 1500.0 + 1.05, 1e-12);
}

TEST(FormationDelay, LinksBeyondMaxRangeAreCountedAtMaxRange) {
  Scenario s = Load("scenarios/acoustic_survey.toml");
  s.delay.max_range_m = 30.0;
  const FormationDelay f = FormationAcousticDelay(s);
  EXPECT_EQ(f.beyond_range_links, 2);  // 3 -> 4 and 4 -> 3
  EXPECT_NEAR(f.in_formation_s, 30.0 / 1500.0 + 0.3, 1e-12);
  EXPECT_NEAR(f.model_bound_s, f.in_formation_s, 1e-12);
}

TEST(FormationDelay, ReportComparesBothWithTheMargin) {
  const Scenario s = Load("scenarios/acoustic_survey.toml");
  const DesignReport r = BuildDesignReport(s, DesignRequest{});
  ASSERT_TRUE(r.formation_delay.has_value());
  const std::string text = DesignReportText(r);
  // Links 3 -> 4 and 4 -> 3 tie at 40 m: the first in the union's link order is named.
  EXPECT_NE(text.find("in formation the delay is at most 0.3267 s (link 4 -> 3, 40 m)"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("worst case (at max_range_m) 0.6333 s"), std::string::npos) << text;
  const nlohmann::ordered_json j = DesignReportJson(r)["acoustic_formation_delay"];
  EXPECT_EQ(j["in_formation_below_margin"], 0.3267 < r.GoverningMarginS());
  EXPECT_EQ(j["margin_s"], r.GoverningMarginS());
}

}  // namespace
}  // namespace design
}  // namespace shoal
