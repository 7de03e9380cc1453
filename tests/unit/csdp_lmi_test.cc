// Tests of design/csdp_lmi (the CSDP front end): known answers (λmax of a symmetric
// matrix as an SDP, a scalar LP), CSDP's infeasibility certificate, rejection of
// malformed problems without calling CSDP (which would exit()), and silence on stdout.
#include "design/csdp_lmi.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

namespace shoal::design {
namespace {

Eigen::MatrixXd RandomSymmetric(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::MatrixXd m(n, n);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) m(i, j) = g(rng);
  }
  return 0.5 * (m + m.transpose());
}

// Given a symmetric M, when we minimise t subject to tI − M ⪰ 0, then t* = λmax(M).
TEST(CsdpLmiTest, LargestEigenvalueAsSdp) {
  for (unsigned seed = 1; seed <= 5; ++seed) {
    const Eigen::MatrixXd M = RandomSymmetric(7, seed);
    LmiProblem p;
    const int t = p.AddVariable(1.0);
    const int b = p.AddBlock(7);
    p.AddCoefficient(t, b, Eigen::MatrixXd::Identity(7, 7));
    p.AddConstant(b, -M);
    const CsdpSolution s = SolveWithCsdp(p);
    ASSERT_EQ(s.return_code, 0) << s.message;
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(M);
    EXPECT_NEAR(s.y(t), es.eigenvalues().maxCoeff(), 1e-6);
    EXPECT_NEAR(s.objective, s.y(t), 1e-9);
    // The returned point satisfies the LMI (up to the solver's accuracy).
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> f(p.Evaluate(b, s.y));
    EXPECT_GT(f.eigenvalues().minCoeff(), -1e-6);
  }
}

// Given x >= 2 and x >= -1 as an LP block, minimising x gives 2.
TEST(CsdpLmiTest, ScalarLinearProgram) {
  LmiProblem p;
  const int x = p.AddVariable(1.0);
  const int b = p.AddBlock(2, /*diagonal=*/true);
  p.AddCoefficientEntry(x, b, 0, 0, 1.0);
  p.AddCoefficientEntry(x, b, 1, 1, 1.0);
  Eigen::MatrixXd c = Eigen::MatrixXd::Zero(2, 2);
  c(0, 0) = -2.0;
  c(1, 1) = 1.0;
  p.AddConstant(b, c);
  const CsdpSolution s = SolveWithCsdp(p);
  ASSERT_TRUE(s.solved()) << s.message;
  EXPECT_NEAR(s.y(x), 2.0, 1e-6);
}

// Given x >= 1 and x <= 0, CSDP proves the LMI infeasible (its code 2) and we report it.
TEST(CsdpLmiTest, InfeasibleLmiIsReportedAsSuch) {
  LmiProblem p;
  const int x = p.AddVariable(1.0);
  const int b = p.AddBlock(2, /*diagonal=*/true);
  p.AddCoefficientEntry(x, b, 0, 0, 1.0);
  p.AddCoefficientEntry(x, b, 1, 1, -1.0);
  Eigen::MatrixXd c = Eigen::MatrixXd::Zero(2, 2);
  c(0, 0) = -1.0;
  p.AddConstant(b, c);
  const CsdpSolution s = SolveWithCsdp(p);
  EXPECT_FALSE(s.solved());
  EXPECT_EQ(s.return_code, 2) << s.message;
  EXPECT_NE(s.message.find("infeasible"), std::string::npos) << s.message;
}

TEST(CsdpLmiTest, MalformedProblemsAreRejectedBeforeCsdp) {
  {
    LmiProblem p;  // no variables, no blocks
    const CsdpSolution s = SolveWithCsdp(p);
    EXPECT_EQ(s.return_code, -1);
    EXPECT_FALSE(s.solved());
  }
  {
    LmiProblem p;
    p.AddVariable(1.0);
    const int unused = p.AddVariable(0.0);
    const int b = p.AddBlock(2);
    p.AddCoefficient(0, b, Eigen::MatrixXd::Identity(2, 2));
    const CsdpSolution s = SolveWithCsdp(p);
    EXPECT_EQ(s.return_code, -1);
    EXPECT_NE(s.message.find("variable " + std::to_string(unused)), std::string::npos) << s.message;
  }
  {
    LmiProblem p;
    const int x = p.AddVariable(1.0);
    const int b = p.AddBlock(2);
    Eigen::MatrixXd a = Eigen::MatrixXd::Identity(2, 2);
    a(0, 1) = a(1, 0) = std::numeric_limits<double>::quiet_NaN();
    p.AddCoefficient(x, b, a);
    const CsdpSolution s = SolveWithCsdp(p);
    EXPECT_EQ(s.return_code, -1);
    EXPECT_NE(s.message.find("non-finite"), std::string::npos) << s.message;
  }
  {
    LmiProblem p;
    const int x = p.AddVariable(1.0);
    const int b = p.AddBlock(2, /*diagonal=*/true);
    p.AddCoefficientEntry(x, b, 0, 1, 1.0);
    const CsdpSolution s = SolveWithCsdp(p);
    EXPECT_EQ(s.return_code, -1);
    EXPECT_NE(s.message.find("off-diagonal"), std::string::npos) << s.message;
  }
}

// Given an iteration limit of 1, CSDP stops with code 4 and we pass it on.
TEST(CsdpLmiTest, IterationLimitIsAFailureCode) {
  const Eigen::MatrixXd M = RandomSymmetric(6, 11);
  LmiProblem p;
  const int t = p.AddVariable(1.0);
  const int b = p.AddBlock(6);
  p.AddCoefficient(t, b, Eigen::MatrixXd::Identity(6, 6));
  p.AddConstant(b, -M);
  CsdpOptions o;
  o.max_iterations = 1;
  const CsdpSolution s = SolveWithCsdp(p, o);
  EXPECT_EQ(s.return_code, 4) << s.message;
  EXPECT_FALSE(s.solved());
  EXPECT_EQ(s.message, CsdpReturnCodeMeaning(4));
}

TEST(CsdpLmiTest, PrintsNothing) {
  LmiProblem p;
  const int t = p.AddVariable(1.0);
  const int b = p.AddBlock(3);
  p.AddCoefficient(t, b, Eigen::MatrixXd::Identity(3, 3));
  p.AddConstant(b, -RandomSymmetric(3, 3));
  ::testing::internal::CaptureStdout();
  const CsdpSolution s = SolveWithCsdp(p);
  const std::string out = ::testing::internal::GetCapturedStdout();
  EXPECT_EQ(s.return_code, 0);
  EXPECT_EQ(out, "");
}

}  // namespace
}  // namespace shoal::design
