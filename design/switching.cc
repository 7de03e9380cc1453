#include "design/switching.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <limits>
#include <string>

#include "core/timeline.h"
#include "core/topology.h"
#include "design/csdp_lmi.h"
#include "design/format.h"

namespace shoal {
namespace design {
namespace {

double MinEigenvalueSymmetric(const Eigen::MatrixXd& S) {
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(0.5 * (S + S.transpose()),
                                                    Eigen::EigenvaluesOnly);
  return es.eigenvalues().minCoeff();
}

double MaxEigenvalueSymmetric(const Eigen::MatrixXd& S) {
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(0.5 * (S + S.transpose()),
                                                    Eigen::EigenvaluesOnly);
  return es.eigenvalues().maxCoeff();
}

TopologyResult AnalyseTopology(const Topology& topo, double k1, double k2, double alpha,
                               double beta) {
  TopologyResult t;
  t.H = topo.H();
  t.eigenvalues = theory::HEigenvalues(t.H);
  t.unreachable_followers = topo.UnreachableFollowers();
  const std::optional<theory::Theorem1> t1 = theory::ComputeTheorem1(t.H, k1, k2, alpha, beta);
  t.theorem1_available = t1.has_value();
  if (t1) {
    t.theorem1_certifies = t1->certifies;
    t.theorem1_P_max_eigenvalue = t1->P_max_eigenvalue;
  }
  t.margin = theory::ComputeDelayMargin(t.eigenvalues, k1, k2);
  return t;
}

/// The LMI in CSDP's form: y = the upper triangle of P (column by column), block 0
/// P - eps I >= 0, block k -(A_k^T P + P A_k) - eps I >= 0, minimise trace(P).
LmiProblem CommonLyapunovLmi(const std::vector<Eigen::MatrixXd>& A, double eps) {
  const int m = static_cast<int>(A.front().rows());
  LmiProblem lmi;
  const int p_block = lmi.AddBlock(m);
  lmi.AddConstant(p_block, -eps * Eigen::MatrixXd::Identity(m, m));
  std::vector<int> a_block;
  for (std::size_t k = 0; k < A.size(); ++k) {
    a_block.push_back(lmi.AddBlock(m));
    lmi.AddConstant(a_block.back(), -eps * Eigen::MatrixXd::Identity(m, m));
  }
  for (int j = 0; j < m; ++j) {
    for (int i = 0; i <= j; ++i) {
      const int v = lmi.AddVariable(i == j ? 1.0 : 0.0);
      Eigen::MatrixXd E = Eigen::MatrixXd::Zero(m, m);
      E(i, j) = 1.0;
      E(j, i) = 1.0;
      lmi.AddCoefficient(v, p_block, E);
      for (std::size_t k = 0; k < A.size(); ++k) {
        lmi.AddCoefficient(v, a_block[k], -(A[k].transpose() * E + E * A[k]));
      }
    }
  }
  return lmi;
}

Eigen::MatrixXd PFromVariables(const Eigen::VectorXd& y, int m) {
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(m, m);
  int v = 0;
  for (int j = 0; j < m; ++j) {
    for (int i = 0; i <= j; ++i, ++v) {
      P(i, j) = y(v);
      P(j, i) = y(v);
    }
  }
  return P;
}

}  // namespace

Eigen::MatrixXd ErrorSystemMatrix(const Eigen::MatrixXd& H, double k1, double k2) {
  const Eigen::Index n = H.rows();
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(2 * n, 2 * n);
  A.topRightCorner(n, n).setIdentity();
  A.bottomLeftCorner(n, n) = -k1 * H;
  A.bottomRightCorner(n, n) = -k2 * H;
  return A;
}

LyapunovCheck CheckCommonLyapunov(const Eigen::MatrixXd& P, const std::vector<Eigen::MatrixXd>& A,
                                  double eps) {
  LyapunovCheck c;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  bool sized = P.rows() == P.cols() && P.rows() > 0 && P.allFinite();
  for (const Eigen::MatrixXd& a : A) sized = sized && a.rows() == P.rows() && a.cols() == P.cols();
  if (!sized || A.empty()) {
    c.P_min_eigenvalue = nan;
    c.max_eigenvalues.assign(A.size(), nan);
    return c;
  }
  const Eigen::MatrixXd S = 0.5 * (P + P.transpose());
  c.P_min_eigenvalue = MinEigenvalueSymmetric(S);
  c.verified = c.P_min_eigenvalue >= 0.5 * eps;
  for (const Eigen::MatrixXd& a : A) {
    c.max_eigenvalues.push_back(MaxEigenvalueSymmetric(a.transpose() * S + S * a));
    c.verified = c.verified && c.max_eigenvalues.back() <= -0.5 * eps;
  }
  return c;
}

CommonLyapunov FindCommonLyapunov(const std::vector<Eigen::MatrixXd>& A, double eps) {
  CommonLyapunov out;
  out.eps = eps;
  bool same_size = !A.empty() && A.front().rows() > 0;
  for (const Eigen::MatrixXd& a : A) {
    same_size = same_size && a.rows() == A.front().rows() && a.cols() == a.rows() && a.allFinite();
  }
  if (!same_size || !(eps > 0.0)) {
    out.not_attempted_reason = "the matrices must be square, finite, of one size, and eps > 0";
    return out;
  }
  out.attempted = true;
  const CsdpSolution sol = SolveWithCsdp(CommonLyapunovLmi(A, eps));
  out.csdp_return_code = sol.return_code;
  out.csdp_status = sol.message;
  out.seconds = sol.seconds;
  const int m = static_cast<int>(A.front().rows());
  if (sol.y.size() == m * (m + 1) / 2) out.P = PFromVariables(sol.y, m);
  // Only a solved LMI gives a P worth checking; the check alone decides.
  if (sol.solved()) out.check = CheckCommonLyapunov(out.P, A, eps);
  return out;
}

namespace {
// 60 followers (m = 120: 7260 variables, a Schur matrix of 0.4 GB) and the block entries
// of a few hundred topologies of that size.
constexpr double kMaxCommonLmiVariables = 7260.0;
constexpr double kMaxCommonLmiEntries = 5e6;
}  // namespace

SwitchingSection AnalyseSwitching(const Scenario& s, double k1, double k2, double alpha,
                                  double beta) {
  SwitchingSection sw;
  const Timeline timeline(s);
  const std::vector<Topology>& topos = timeline.topologies();
  // The topology events in file order are topologies 1, 2, ...
  std::vector<int> topology_events;
  for (std::size_t e = 0; e < s.events.size(); ++e) {
    if (s.events[e].kind == EventKind::kTopology) topology_events.push_back(static_cast<int>(e));
  }
  std::vector<Eigen::MatrixXd> A;
  // A timeline that returns to earlier topologies repeats them: each distinct H is
  // analysed once and enters the common LMI once.
  std::vector<std::size_t> first_of;  // index in sw.topologies of each distinct H
  sw.min_margin_s = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < topos.size(); ++k) {
    const Eigen::MatrixXd H = topos[k].H();
    std::size_t same = first_of.size();
    for (std::size_t u = 0; u < first_of.size(); ++u) {
      if (sw.topologies[first_of[u]].H == H) same = u;
    }
    TopologyResult t = same < first_of.size() ? sw.topologies[first_of[same]]
                                              : AnalyseTopology(topos[k], k1, k2, alpha, beta);
    t.index = static_cast<int>(k);
    t.event_index = -1;
    t.event_line = 0;
    t.at_s = 0.0;
    if (k > 0 && k - 1 < topology_events.size()) {
      const ScenarioEvent& e = s.events[static_cast<std::size_t>(topology_events[k - 1])];
      t.event_index = topology_events[k - 1];
      t.event_line = e.line;
      t.at_s = e.at_s;
    }
    if (t.margin_s() < sw.min_margin_s) {
      sw.min_margin_s = t.margin_s();
      sw.critical = t.index;
    }
    if (same == first_of.size()) {
      first_of.push_back(sw.topologies.size());
      A.push_back(ErrorSystemMatrix(t.H, k1, k2));
    }
    sw.topologies.push_back(std::move(t));
  }
  bool stable = true;
  for (const TopologyResult& t : sw.topologies) stable = stable && t.margin.stable_at_zero;
  // CSDP's dense Schur complement grows as (variables)^2 = (m (m + 1) / 2)^2 with
  // m = 2n: beyond these sizes the LMI would take gigabytes and hours.
  const double m = A.empty() ? 0.0 : static_cast<double>(A.front().rows());
  const double variables = m * (m + 1.0) / 2.0;
  const double entries = static_cast<double>(A.size() + 1) * m * m;
  if (!stable) {
    sw.common.not_attempted_reason =
        "some topology's error system is unstable without delay: no common P can exist";
  } else if (variables > kMaxCommonLmiVariables || entries > kMaxCommonLmiEntries) {
    sw.common.not_attempted_reason =
        "the common LMI is too large to solve here (" + std::to_string(A.size()) +
        " distinct topologies of " + std::to_string(static_cast<int>(m / 2)) +
        " followers: " + std::to_string(static_cast<long long>(variables)) + " variables, " +
        std::to_string(static_cast<long long>(entries)) + " block entries; limits " +
        std::to_string(static_cast<long long>(kMaxCommonLmiVariables)) + " and " +
        std::to_string(static_cast<long long>(kMaxCommonLmiEntries)) + ")";
  } else {
    sw.common = FindCommonLyapunov(A);
  }
  return sw;
}

}  // namespace design
}  // namespace shoal

namespace shoal {
namespace design {

std::string TopologySource(const TopologyResult& t) {
  if (t.event_index < 0) return "[swarm]";
  std::string s = "event " + std::to_string(t.event_index + 1);
  if (t.event_line > 0) s += " (line " + std::to_string(t.event_line) + ")";
  return s;
}

Verdict SwitchingVerdict(const SwitchingSection& sw, double h_s, FactorKind factor) {
  Verdict v;
  const std::string count = std::to_string(sw.topologies.size()) + " topologies";
  const TopologyResult& crit = sw.topologies.at(static_cast<std::size_t>(sw.critical));
  v.margin_over_h = h_s > 0.0 ? sw.min_margin_s / h_s : std::numeric_limits<double>::infinity();
  if (!crit.margin.stable_at_zero) {
    v.reason = "the topology switches among " + count + " and topology " +
               std::to_string(crit.index) + " (" + TopologySource(crit) +
               ") is unstable even without delay";
    v.advice = "raise k2 relative to k1, or give that topology a spanning tree from the leader";
    return v;
  }
  const std::string margin = "smallest exact constant-delay margin " + G4(sw.min_margin_s) +
                             " s (topology " + std::to_string(crit.index) + ", " +
                             TopologySource(crit) + ")";
  if (h_s == 0.0 && factor == FactorKind::kNone) {
    if (sw.common.found()) {
      v.certified = true;
      v.by = "a common Lyapunov function";
      v.reason = "the delay-free loop is stable under arbitrary switching among the " + count;
    } else {
      v.reason = "no common quadratic Lyapunov function was found for the " + count +
                 " (each is stable; switching among them may still be, e.g. with a dwell time)";
    }
    return v;
  }
  v.reason = "the topology switches among " + count + "; " + margin +
             (h_s > 0.0 ? " = " + G4(sw.min_margin_s / h_s) + " x h" : std::string()) +
             ", per topology only: no result here certifies a switching loop with " +
             (h_s > 0.0 ? "delays" : "an uncertain factor");
  if (h_s > 0.0 && sw.min_margin_s <= h_s) {
    v.advice = "topology " + std::to_string(crit.index) + " is unstable at h = " + G4(h_s) +
               " s even without switching: scale the gains down (k1 x c^2, k2 x c, c < 1)";
  }
  return v;
}

}  // namespace design
}  // namespace shoal
