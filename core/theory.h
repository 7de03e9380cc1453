// The paper's stability theory as numbers (used by `shoal design`; docs/theory.md):
// Theorem 1 (no delay, no uncertain factor), Theorem 2 (no delay, Lipschitz uncertain
// factor), the delay data h and kappa of Assumption 3, the Lipschitz data of Assumption 2,
// and the exact delay margin of protocol (10) for a constant delay. Pure Eigen, no I/O.
// Theorem 3 (an LMI solved with an SDP solver) lives outside core/.
#pragma once

#include <Eigen/Dense>
#include <complex>
#include <optional>
#include <string>
#include <vector>

#include "core/scenario.h"

namespace shoal {
namespace theory {

using Complex = std::complex<double>;

/// Eigenvalues of H = L + D (paper eq. (12)), sorted by decreasing real part, then by
/// decreasing imaginary part (a conjugate pair appears as +im, -im).
std::vector<Complex> HEigenvalues(const Eigen::MatrixXd& H);

/// Solves W H + H^T W = I for symmetric W (Bartels-Stewart on the complex Schur form of H).
/// Requires every eigenvalue of H to have a positive real part (Assumption 1 guarantees
/// it); returns std::nullopt otherwise (then no positive definite solution exists).
std::optional<Eigen::MatrixXd> SolveW(const Eigen::MatrixXd& H);

/// Paper Theorem 1 (eq. (14)-(18)) for gains k1, k2 and the free parameters alpha, beta.
struct Theorem1 {
  Eigen::MatrixXd W;                    ///< W H + H^T W = I
  Eigen::VectorXd W_eigenvalues;        ///< ascending
  Eigen::MatrixXd M;                    ///< M = W - alpha beta W H - H^T W
  std::vector<Complex> M2_eigenvalues;  ///< eig(M^2), descending real part
  double lambda_max_W = 0.0;
  double lambda_max_M2 = 0.0;   ///< largest real part of eig(M^2) (as the paper)
  double lambda_max_MtM = 0.0;  ///< lambda_max(M^T M) = ||M||_2^2
  /// Eq. (15) as printed, with lambda_max(M^2):
  ///   k1 > max{alpha^2, 2 alpha^2 lambda_max(W) / (alpha beta - lambda_max(M^2))},
  ///   k2 > max{alpha^2 beta, 2 alpha^2 beta lambda_max(W) / (alpha beta - lambda_max(M^2))}.
  /// Empty when alpha beta <= lambda_max(M^2): then no gains satisfy (15).
  std::optional<double> k1_min, k2_min;
  /// The same with lambda_max(M^T M), which the Schur step of the proof really needs
  /// (M is not symmetric). Empty when alpha beta <= lambda_max(M^T M).
  std::optional<double> k1_min_corrected, k2_min_corrected;
  /// Q = [k1 W, alpha W; alpha W, W] (the Lyapunov matrix (16), without the (x) I_5):
  /// positive definite iff k1 > alpha^2.
  bool Q_positive_definite = false;
  /// Largest eigenvalue of P = Q(A+B) + (A+B)^T Q for the given k1, k2 (any k2, not only
  /// k2 = beta k1). Negative together with Q > 0: V = e^T Q e certifies the gains.
  double P_max_eigenvalue = 0.0;
  Eigen::MatrixXd P;       ///< P itself (2n x 2n, symmetric)
  bool certifies = false;  ///< Q > 0 and P < 0
};

/// Theorem 1 for H, gains and alpha, beta > 0; std::nullopt if W does not exist (an
/// eigenvalue of H with real part <= 0).
std::optional<Theorem1> ComputeTheorem1(const Eigen::MatrixXd& H, double k1, double k2,
                                        double alpha, double beta);

/// Paper Theorem 2 (eq. (20)-(21)): bounds on k1, k2 for a Lipschitz uncertain factor with
/// constant rho0 (||F_i|| <= rho0 (||x_i - x_0|| + ||v_i - v_0||)) and no delay.
struct Theorem2 {
  double rho0 = 0.0;
  /// As printed: k11 = (3 alpha + 1) rho0 lambda_max(W) / alpha, k21 = beta k11,
  /// k12 = (2 alpha^2 lambda_max(W) + alpha (alpha + 3) / 2 rho0 lambda_max(W)) /
  ///       (alpha beta - 2 lambda_max(M^2)),  k22 = beta k12 (empty if the denominator <= 0).
  double k11 = 0.0, k21 = 0.0;
  std::optional<double> k12, k22;
  /// k1_min = max(k11, k12), k2_min = max(k21, k22); empty when k12 is.
  std::optional<double> k1_min, k2_min;
  /// Corrected: eq. (23) drops the factor 2 of dV/dt = 2 e^T Q (...), so every rho0 term
  /// doubles, and the Schur step needs lambda_max(M^T M):
  ///   k11c = 2 (3 alpha + 1) rho0 lambda_max(W) / alpha,
  ///   k12c = (2 alpha^2 lambda_max(W) + alpha (alpha + 3) rho0 lambda_max(W)) /
  ///          (alpha beta - 2 lambda_max(M^T M)).
  double k11_corrected = 0.0, k21_corrected = 0.0;
  std::optional<double> k12_corrected, k22_corrected;
  std::optional<double> k1_min_corrected, k2_min_corrected;
  /// Direct check for the given gains: largest eigenvalue of the corrected
  ///   P~ = P + diag((3 alpha + 1) rho0 lambda_max(W) I, (alpha + 3) rho0 lambda_max(W) I);
  /// negative together with Q > 0 certifies the gains.
  double P_tilde_max_eigenvalue = 0.0;
  bool certifies = false;
};

/// Theorem 2 for the gains, W and M of `t1` (computed with the same alpha, beta).
Theorem2 ComputeTheorem2(const Theorem1& t1, double alpha, double beta, double rho0);

/// Lipschitz data of the uncertain factor (Assumption 2):
///   ||f(x1, v1) - f(x2, v2)|| <= ||G|| ||x1 - x2|| + ||J|| ||v1 - v2||,
/// and rho0 = max(||G||, ||J||), so that ||f(x1, v1) - f(x2, v2)|| <= rho0 (||dx|| + ||dv||)
/// as used in the proof of Theorem 2.
struct Lipschitz {
  bool applicable = false;  ///< false: the factor is not of the form f(x_i) - f(x_0)
  Eigen::MatrixXd G, J;     ///< 5x5, when applicable
  double lambda_max_G2 = 0.0, lambda_max_J2 = 0.0;
  double rho0 = 0.0;
  /// The factor is separable per component (f_c depends on x_c and v_c only): the range
  /// [min, max] over all states of df_c/dx_c (column 0, 1) and df_c/dv_c (columns 2, 3).
  /// Known for none and paper_example2 (slopes_known).
  bool slopes_known = false;
  Eigen::Matrix<double, 5, 4> slopes = Eigen::Matrix<double, 5, 4>::Zero();
  std::string note;  ///< what the numbers mean for this model (or why there are none)
};

/// For the scenario's disturbance model: none -> G = J = 0, rho0 = 0; paper_example2 ->
/// G = diag(0, 0.01, 0.01, 0, 0.02), J = diag(0.4, 0.45, 0, 0.48, 0.5) (the largest slopes
/// of the sin/cos and tanh terms), rho0 = 0.5; ocean_current -> not applicable (an
/// exogenous disturbance that does not vanish at consensus).
Lipschitz LipschitzOf(const DisturbanceConfig& d);

/// Delay data of Assumption 3: 0 <= tau(t) <= h, d tau/dt <= kappa.
struct DelayBounds {
  double h_s = 0.0;
  /// Empty when tau(t) has no bounded derivative (uniform: a new random delay per
  /// message, so tau jumps and Assumption 3 cannot hold; acoustic and trace: nothing
  /// bounds the rate of the range or of the series).
  std::optional<double> kappa;
  bool time_varying = false;  ///< any link (or the uncertain factor) has a varying delay
  bool constant = true;       ///< every delay is one constant value (or zero)
};

/// One delay model: none (0, 0); constant (base, 0); sinusoid (base + amplitude,
/// amplitude * omega); uniform (base + amplitude, unbounded unless amplitude is 0).
DelayBounds DelayBoundsOf(const DelayConfig& c);

/// The scenario: the maximum over every link of the topology (defaults and per-link
/// overrides) and, when the paper's uncertain factor is on, its delay (the default model).
DelayBounds DelayBoundsOf(const Scenario& s);

/// Delay margin of one eigenvalue lambda of H for
///   s^2 + lambda (k2 s + k1) e^{-s tau} = 0.
struct EigenMargin {
  Complex lambda;
  bool stable_at_zero = false;  ///< both roots of s^2 + lambda k2 s + lambda k1 in Re s < 0
  double omega_rad_s = 0.0;     ///< crossing frequency of the first crossing (signed)
  double tau_s = 0.0;           ///< smallest tau > 0 with a root at s = j omega
  /// Re(ds/dtau) at that crossing: > 0 means the root moves into the right half plane.
  double crossing_direction = 0.0;
};

/// Exact delay margin of protocol (10) with the same constant delay on own and neighbour
/// states: the smallest tau > 0 for which some eigenvalue's characteristic equation has a
/// root on the imaginary axis, provided every one is stable at tau = 0.
///   |lambda|^2 (k2^2 w^2 + k1^2) = w^4   gives w^2 = (|lambda|^2 k2^2 +
///       sqrt(|lambda|^4 k2^4 + 4 |lambda|^2 k1^2)) / 2,
///   w tau = arg(lambda (k1 + j k2 w)) (mod 2 pi)   for both signs of w.
struct DelayMargin {
  bool stable_at_zero = false;
  /// Smallest tau; +inf only if no eigenvalue has a crossing (cannot happen for k1 > 0).
  double tau_s = 0.0;
  int critical = -1;  ///< index into per_eigenvalue of the eigenvalue that sets tau_s
  std::vector<EigenMargin> per_eigenvalue;
};

EigenMargin EigenDelayMargin(Complex lambda, double k1, double k2);
DelayMargin ComputeDelayMargin(const std::vector<Complex>& eigenvalues, double k1, double k2);

/// Delay margin of s^2 + (a s + b) e^{-s tau} = 0 for complex a, b (lambda is left 0):
/// the crossing frequencies are the real roots of
///   w^4 - |a|^2 w^2 + 2 Im(a conj(b)) w - |b|^2 = 0   (|j w a + b| = w^2),
/// and w tau = arg(j w a + b) (mod 2 pi). With a = lambda k2, b = lambda k1 this is
/// EigenDelayMargin.
EigenMargin GeneralDelayMargin(Complex a, Complex b);

/// An indication, not a certificate: the exact constant-delay margin of the loop with the
/// uncertain factor replaced by its linearisation (delayed like the protocol), its slopes
/// frozen at the corners of their ranges (Lipschitz::slopes). Per eigenvalue lambda of H,
/// component c of eta and corner (g, j):
///   s^2 + ((lambda k2 - j) s + (lambda k1 - g)) e^{-s tau} = 0.
/// The smallest margin over all of them (0 if some corner is unstable without delay).
struct FactorDelayMargin {
  bool available = false;  ///< the factor's slopes are known
  bool stable_at_zero = false;
  double tau_s = 0.0;
  Complex lambda;          ///< the critical eigenvalue of H
  int component = -1;      ///< the critical component of eta (0..4: x y z theta psi)
  double x_slope = 0.0;    ///< g at the critical corner
  double v_slope = 0.0;    ///< j at the critical corner
  double omega_rad_s = 0.0;
};

FactorDelayMargin ComputeFactorDelayMargin(const std::vector<Complex>& eigenvalues, double k1,
                                           double k2, const Lipschitz& l);

}  // namespace theory
}  // namespace shoal
