// A switching topology (the scenario's `topology` events, core/timeline.h): the
// per-topology results `shoal design` gives for one topology (Assumption 1, Theorem 1, the
// exact delay margin), and one common quadratic Lyapunov function for every topology's
// delay-free error system, found with CSDP and checked independently (docs/theory.md,
// "Switching topologies and acoustic delays").
#pragma once

#include <Eigen/Dense>
#include <string>
#include <vector>

#include "core/scenario.h"
#include "core/theory.h"
#include "design/verdict.h"

namespace shoal {
namespace design {

/// One topology of the timeline and what the report computes for it.
struct TopologyResult {
  int index = 0;         ///< in Timeline::topologies(): 0 is [swarm]
  int event_index = -1;  ///< index in Scenario::events of its topology event (-1: [swarm])
  int event_line = 0;    ///< line of that event's [[event]] header (0: [swarm] or built in code)
  double at_s = 0.0;     ///< start of its window (0 for [swarm])
  Eigen::MatrixXd H;
  std::vector<theory::Complex> eigenvalues;
  std::vector<int> unreachable_followers;  ///< empty: Assumption 1 holds
  bool theorem1_available = false;         ///< W exists (every Re lambda(H) > 0)
  bool theorem1_certifies = false;         ///< Q > 0 and P = Q(A+B) + (A+B)^T Q < 0
  double theorem1_P_max_eigenvalue = 0.0;
  theory::DelayMargin margin;
  /// The exact margin, 0 when unstable without delay.
  double margin_s() const { return margin.stable_at_zero ? margin.tau_s : 0.0; }
};

/// A = [0 I; -k1 H, -k2 H]: the closed loop of the delay-free error system (13) without
/// the uncertain factor, per component of eta (the (x) I_5 dropped), as Theorem 1 uses it.
Eigen::MatrixXd ErrorSystemMatrix(const Eigen::MatrixXd& H, double k1, double k2);

/// What the independent double-precision check found for a candidate P.
struct LyapunovCheck {
  bool verified = false;            ///< P >= eps/2 I and every A_k^T P + P A_k <= -eps/2 I
  double P_min_eigenvalue = 0.0;
  std::vector<double> max_eigenvalues;  ///< per A_k: lambda_max(A_k^T P + P A_k)
};

/// Checks P against every A_k with Eigen's self-adjoint eigensolver (P symmetrised
/// first; a non-finite or wrongly sized P fails). `eps` is the LMI's margin.
LyapunovCheck CheckCommonLyapunov(const Eigen::MatrixXd& P, const std::vector<Eigen::MatrixXd>& A,
                                  double eps);

/// One P > 0 with A_k^T P + P A_k < 0 for every k: V = e^T P e decreases along every
/// topology's error system, so the delay-free loop is stable under arbitrary switching.
struct CommonLyapunov {
  bool attempted = false;
  std::string not_attempted_reason;
  /// The LMI's margin: P >= eps I, A_k^T P + P A_k <= -eps I (homogeneous in P, so
  /// eps = 1 loses nothing); trace(P) is minimised to keep P bounded.
  double eps = 1.0;
  int csdp_return_code = -1;
  std::string csdp_status;
  double seconds = 0.0;
  Eigen::MatrixXd P;  ///< CSDP's P (empty if CSDP returned none)
  LyapunovCheck check;
  /// Found and confirmed by CheckCommonLyapunov: the only case that claims a certificate.
  bool found() const { return check.verified; }
};

/// Solves the LMI for the matrices A (each square, the same size) with CSDP.
CommonLyapunov FindCommonLyapunov(const std::vector<Eigen::MatrixXd>& A, double eps = 1.0);

/// Per topology and the common certificate for a scenario whose timeline switches.
struct SwitchingSection {
  std::vector<TopologyResult> topologies;
  int critical = 0;          ///< index of the smallest exact margin
  double min_margin_s = 0.0;
  CommonLyapunov common;
};

/// For a scenario with at least one topology event (Timeline(s).switches_topology()).
SwitchingSection AnalyseSwitching(const Scenario& s, double k1, double k2, double alpha,
                                  double beta);

/// "[swarm]" or "event E (line L)" (E counted from 1 in the file's order).
std::string TopologySource(const TopologyResult& t);

/// The verdict for a switching topology, which replaces the one-topology verdict: the
/// delay-free loop without uncertain factor is certified by a verified common Lyapunov
/// function; nothing here certifies switching with delays or a factor, so then the
/// verdict is NOT CERTIFIED with the smallest per-topology margin as an indication.
Verdict SwitchingVerdict(const SwitchingSection& sw, double h_s, FactorKind factor);

}  // namespace design
}  // namespace shoal
