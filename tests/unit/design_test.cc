// design/: the verdict's rules, the empirical margin against the exact one, and tuning's
// constraint and improvement.
#include <gtest/gtest.h>

#include <cmath>

#include "core/topology.h"
#include "design/empirical_margin.h"
#include "design/sim_eval.h"
#include "design/tune.h"
#include "design/verdict.h"
#include "scenario/loader.h"

namespace shoal {
namespace design {
namespace {

Scenario Load(const std::string& rel) {
  return LoadScenario(std::string(SHOAL_SOURCE_DIR) + "/" + rel);
}

struct Fixture {
  Eigen::MatrixXd H;
  std::vector<theory::Complex> eig;
  theory::Theorem1 t1;
  theory::DelayMargin margin;
  Fixture(double k1, double k2) {
    H = Topology::Build(5, {{1, 3}, {2, 1}, {2, 5}, {3, 1}, {4, 5}, {5, 2}, {5, 4}}, {1, 3, 5}).H();
    eig = theory::HEigenvalues(H);
    t1 = *theory::ComputeTheorem1(H, k1, k2, 0.05, 6.4);
    margin = theory::ComputeDelayMargin(eig, k1, k2);
  }
  VerdictInput Input(double k1, double k2) const {
    VerdictInput in;
    in.k1 = k1;
    in.k2 = k2;
    in.theorem1 = &t1;
    in.margin = &margin;
    return in;
  }
};

TEST(Verdict, NoDelayNoFactorIsCertifiedByTheorem1) {
  const Fixture f(0.18, 1.152);
  const Verdict v = Decide(f.Input(0.18, 1.152));
  EXPECT_TRUE(v.certified);
  EXPECT_EQ(v.by, "Theorem 1");
  EXPECT_NE(v.Line().find("CERTIFIED by Theorem 1"), std::string::npos);
}

TEST(Verdict, NoDelayGainsBelowTheorem1AreCertifiedByTheExactEquation) {
  // k1 = 0.05 < 0.1754: Theorem 1's P is not negative, but the loop is stable.
  const Fixture f(0.05, 0.32);
  ASSERT_FALSE(f.t1.certifies);
  const Verdict v = Decide(f.Input(0.05, 0.32));
  EXPECT_TRUE(v.certified);
  EXPECT_NE(v.by.find("exact characteristic equation"), std::string::npos);
}

TEST(Verdict, ConstantDelayBelowTheExactMarginIsCertified) {
  const Fixture f(0.18, 1.152);
  VerdictInput in = f.Input(0.18, 1.152);
  in.h_s = 0.2;
  in.kappa = 0.0;
  const Verdict v = Decide(in);
  EXPECT_TRUE(v.certified);
  EXPECT_EQ(v.by, "the exact delay margin");
  EXPECT_NEAR(v.margin_over_h, f.margin.tau_s / 0.2, 1e-12);
  // 0.3435 < 2 x 0.2: certified, with the safety advice.
  EXPECT_NE(v.advice.find("below the safety factor"), std::string::npos);
}

TEST(Verdict, ConstantDelayAboveTheMarginIsNotCertifiedAndTheAdviceFixesIt) {
  const double k1 = 0.18, k2 = 1.152, h = 0.5;
  const Fixture f(k1, k2);
  VerdictInput in = f.Input(k1, k2);
  in.h_s = h;
  in.kappa = 0.0;
  const Verdict v = Decide(in);
  EXPECT_FALSE(v.certified);
  EXPECT_NE(v.reason.find("unstable at this delay"), std::string::npos);
  // The advice: k1 c^2, k2 c with c = margin / (safety h) gives margin = safety h exactly.
  const double c = f.margin.tau_s / (2.0 * h);
  EXPECT_NEAR(theory::ComputeDelayMargin(f.eig, c * c * k1, c * k2).tau_s, 2.0 * h, 1e-9);
  char buf[64];
  std::snprintf(buf, sizeof(buf), "k1 = %.4g, k2 = %.4g", c * c * k1, c * k2);
  EXPECT_NE(v.advice.find(buf), std::string::npos) << v.advice;
}

TEST(Verdict, TimeVaryingDelayNeedsTheorem3) {
  const Fixture f(0.18, 1.152);
  VerdictInput in = f.Input(0.18, 1.152);
  in.h_s = 0.15;
  in.kappa = 0.05;
  in.delay_time_varying = true;
  in.delay_common_constant = false;
  in.factor = FactorKind::kLipschitz;
  in.rho0 = 0.5;
  Verdict v = Decide(in);
  EXPECT_FALSE(v.certified);
  EXPECT_NE(v.reason.find("Theorem 3 not evaluated"), std::string::npos);
  EXPECT_NE(v.reason.find("time-varying"), std::string::npos);

  in.theorem3_certified = false;
  v = Decide(in);
  EXPECT_FALSE(v.certified);
  EXPECT_NE(v.reason.find("not feasible"), std::string::npos);

  in.theorem3_certified = true;
  v = Decide(in);
  EXPECT_TRUE(v.certified);
  EXPECT_EQ(v.by, "Theorem 3 (LMI (27)-(28))");

  // A feasible LMI never certifies what it does not model.
  in.factor = FactorKind::kUncovered;
  EXPECT_FALSE(Decide(in).certified);
  in.factor = FactorKind::kLipschitz;
  in.kappa.reset();  // uniform jitter: no bounded d tau/dt
  EXPECT_FALSE(Decide(in).certified);
}

// Example 2's factor removes the pitch damping when lambda_min k2 < 0.48: the verdict
// says so and asks for k2 > 0.48 / lambda_min.
TEST(Verdict, LinearisedFactorWithoutDampingAsksForMoreK2) {
  const Fixture f(0.18, 1.0);
  DisturbanceConfig d;
  d.kind = DisturbanceKind::kPaperExample2;
  const theory::FactorDelayMargin fm =
      theory::ComputeFactorDelayMargin(f.eig, 0.18, 1.0, theory::LipschitzOf(d));
  ASSERT_FALSE(fm.stable_at_zero);
  VerdictInput in = f.Input(0.18, 1.0);
  in.h_s = 0.15;
  in.kappa = 0.05;
  in.delay_time_varying = true;
  in.delay_common_constant = false;
  in.factor = FactorKind::kLipschitz;
  in.rho0 = 0.5;
  in.factor_margin = &fm;
  const Verdict v = Decide(in);
  EXPECT_FALSE(v.certified);
  EXPECT_NE(v.reason.find("UNSTABLE with the uncertain factor linearised"), std::string::npos);
  char buf[32];
  std::snprintf(buf, sizeof(buf), "k2 > %.4g", 0.48 / f.eig.back().real());
  EXPECT_NE(v.advice.find(buf), std::string::npos) << v.advice;
}

TEST(Verdict, UnstableWithoutDelayIsNeverCertified) {
  // A complex eigenvalue with a large k1 / k2^2: unstable at tau = 0.
  const Eigen::MatrixXd H = Topology::Build(3, {{1, 3}, {2, 1}, {3, 2}}, {1}).H();
  const auto eig = theory::HEigenvalues(H);
  const auto t1 = theory::ComputeTheorem1(H, 50.0, 0.1, 0.05, 6.4);
  const auto margin = theory::ComputeDelayMargin(eig, 50.0, 0.1);
  ASSERT_FALSE(margin.stable_at_zero);
  VerdictInput in;
  in.k1 = 50.0;
  in.k2 = 0.1;
  in.theorem1 = &*t1;
  in.margin = &margin;
  in.theorem3_certified = true;  // even a (wrong) feasible LMI cannot override it
  in.h_s = 0.1;
  in.kappa = 0.0;
  const Verdict v = Decide(in);
  EXPECT_FALSE(v.certified);
  EXPECT_NE(v.reason.find("unstable even without delay"), std::string::npos);
}

TEST(Verdict, NoDelayWithFactorUsesTheorem2) {
  const Eigen::MatrixXd H = Topology::Build(3, {}, {1, 2, 3}).H();  // H = I
  const auto eig = theory::HEigenvalues(H);
  const auto t1 = theory::ComputeTheorem1(H, 3.0, 12.0, 0.2, 4.0);
  const auto margin = theory::ComputeDelayMargin(eig, 3.0, 12.0);
  const theory::Theorem2 small = theory::ComputeTheorem2(*t1, 0.2, 4.0, 0.01);
  const theory::Theorem2 large = theory::ComputeTheorem2(*t1, 0.2, 4.0, 50.0);
  ASSERT_TRUE(small.certifies);
  ASSERT_FALSE(large.certifies);
  VerdictInput in;
  in.k1 = 3.0;
  in.k2 = 12.0;
  in.theorem1 = &*t1;
  in.margin = &margin;
  in.factor = FactorKind::kLipschitz;
  in.rho0 = 0.01;
  in.theorem2 = &small;
  EXPECT_TRUE(Decide(in).certified);
  EXPECT_EQ(Decide(in).by, "Theorem 2 (corrected)");
  in.rho0 = 50.0;
  in.theorem2 = &large;
  EXPECT_FALSE(Decide(in).certified);
  in.factor = FactorKind::kUncovered;
  in.theorem2 = nullptr;
  EXPECT_FALSE(Decide(in).certified);
}

// The nonlinear sampled loop cannot tolerate more than the continuous-time linear loop
// (sampling and the zero-order hold add about half a period of delay), and loses little:
// for paper Example 1 (no uncertain factor) the empirical margin lies within two control
// periods below the exact one. The bracket is consistent with direct runs.
TEST(EmpiricalMargin, PaperExample1IsJustBelowTheExactMargin) {
  Scenario s = Load("scenarios/paper_example1.toml");
  const auto eig = theory::HEigenvalues(Topology::Build(s.followers, s.edges, s.leader_links).H());
  const double exact = theory::ComputeDelayMargin(eig, s.k1, s.k2).tau_s;
  EmpiricalMarginOptions opt;
  opt.initial_upper_s = 2.0 * exact;
  const EmpiricalMargin em = FindEmpiricalMargin(s, opt);
  ASSERT_TRUE(em.converges_without_delay);
  ASSERT_FALSE(em.capped);
  EXPECT_NEAR(em.period_s, 0.02, 1e-12);
  EXPECT_LE(em.margin_s, exact);
  EXPECT_GE(em.margin_s, exact - 2 * em.period_s);
  EXPECT_NEAR(em.first_failing_s, em.margin_s + em.period_s, 1e-9);
  EXPECT_TRUE(RunSwarm(WithConstantDelay(s, em.margin_s), -1).converged);
  EXPECT_FALSE(RunSwarm(WithConstantDelay(s, em.first_failing_s), -1).converged);
}

// Each cost is the squared sum of its residuals; the position ISE is its own cost.
TEST(SimEval, CostIsTheSquaredSumOfTheResiduals) {
  const Scenario s = Load("scenarios/paper_example1.toml");
  std::vector<double> r;
  for (CostKind k : {CostKind::kPositionIse, CostKind::kIse, CostKind::kItse}) {
    const SimOutcome o = RunSwarm(s, 20.0, k, &r);
    double sum = 0.0;
    for (double x : r) sum += x * x;
    EXPECT_NEAR(sum, o.cost, 1e-9 * o.cost) << CostName(k);
    EXPECT_EQ(r.size(), 2u * 1001u * 5u);  // ticks 0..1000, two errors per follower
    EXPECT_GT(o.ise_m2s, 0.0);
    if (k == CostKind::kPositionIse) {
      EXPECT_NEAR(o.cost, o.ise_m2s, 1e-9 * o.cost);
    }
  }
}

// Tuning respects the margin requirement exactly and never ends worse than the best start,
// and the start set contains the scenario's own (feasible) gains.
TEST(Tune, MeetsTheMarginRequirementAndDoesNotIncreaseTheCost) {
  Scenario s = Load("scenarios/paper_example1.toml");
  s.duration_s = 150.0;
  const auto eig = theory::HEigenvalues(Topology::Build(s.followers, s.edges, s.leader_links).H());
  TuneOptions opt;
  opt.safety = 2.0;
  opt.horizon_s = 40.0;
  opt.max_iterations = 8;
  const double h = 0.1;
  const TuneResult r = Tune(s, eig, h, opt);
  ASSERT_TRUE(r.ok) << r.message;
  EXPECT_NEAR(r.required_margin_s, 0.2, 1e-12);
  EXPECT_TRUE(r.before_feasible);  // 0.3435 >= 0.2
  EXPECT_GE(r.after.margin_s, r.required_margin_s - 1e-9);
  EXPECT_LE(r.after.cost, r.before.cost * (1 + 1e-9));
  for (const TuneStart& st : r.starts) {
    if (!st.usable) continue;
    EXPECT_GE(theory::ComputeDelayMargin(eig, st.k1, st.k2).tau_s, r.required_margin_s - 1e-9);
    EXPECT_GE(st.cost, r.after.cost * (1 - 1e-9));
  }
  EXPECT_GT(r.sim_runs, 4);
}

}  // namespace
}  // namespace design
}  // namespace shoal
