// Paper Theorem 3 (leader-following consensus with uncertain factor and time-varying
// delay): the LMI (27)-(28), solved with every multiplier free by CSDP.
//
// Error system (13), per coordinate (the ⊗ I5 factor drops out of every LMI):
//   ε̇(t) = A ε(t) + B ε(t−τ(t)) + E2 F̃(t−τ(t)),   ε = [x̄; v̄] ∈ R^{2n},
//   A = [0 I; 0 0],  B = [0 0; −k1 H  −k2 H],  E2 = [0; I_n],
//   0 ≤ τ(t) ≤ h,  τ̇(t) ≤ κ < 1,  ‖F̃_i‖ ≤ ‖G‖ ‖x̄_i‖ + ‖J‖ ‖v̄_i‖.
//
// Ξ (5n × 5n, ζ = [ε(t); ε(t−τ); F̃(t−τ)]) as implemented (docs/theory_theorem3.md
// explains every difference from the printed (27)):
//   Ξ11 = QA + AᵀQ + hX + Y + Yᵀ + hAᵀZA + Ψ + Q1,   Q1 = diag(2λmax(G²)Φ, 2λmax(J²)Φ)
//   Ξ12 = QB − Y + hAᵀZB
//   Ξ13 = Q E2 + hAᵀZ E2            (the printed Ξ13 = hAᵀC2 lacks Q E2, C2 = Z E2)
//   Ξ22 = −(1−κ)Ψ + hBᵀZB
//   Ξ23 = hBᵀZ E2
//   Ξ33 = hE2ᵀZ E2 − (1−κ)Φ         (E2ᵀZE2 = Z4)
// Conditions: Ξ ≺ 0 (27), [X Y; Yᵀ Z] ⪰ 0 (28), Q, Ψ, Z ≻ 0, Φ ≻ 0 diagonal (the printed
// Q1 bound holds only for a diagonal Φ, and a full Φ can never do better; see the docs).
#pragma once

#include <Eigen/Dense>
#include <string>

#include "design/csdp_lmi.h"

namespace shoal::design {

enum class Theorem3Form {
  /// The LMI with the errata corrected. The only form whose feasibility is a proof.
  kCorrected,
  /// The printed (27) literally (Ξ13 = hAᵀC2 without Q E2, full Φ inside Q1); for
  /// comparison with the paper only, its feasibility certifies nothing.
  kAsPrinted,
};

struct Theorem3Input {
  Eigen::MatrixXd H;       // n × n, H = L + D (paper eq. (12))
  double k1 = 0.0;         // position gain of protocol (10)
  double k2 = 0.0;         // velocity gain of protocol (10)
  double h_s = 0.0;        // delay bound h: 0 <= τ(t) <= h (s)
  double kappa = 0.0;      // bound κ on τ̇(t), 0 <= κ < 1 (Assumption 3)
  double lambda_G2 = 0.0;  // λmax(G²) of the Lipschitz bound (Assumption 2)
  double lambda_J2 = 0.0;  // λmax(J²)
  Theorem3Form form = Theorem3Form::kCorrected;

  /// Finite numbers, H square and non-empty, k1, k2 > 0, h >= 0, 0 <= κ < 1,
  /// λmax(G²), λmax(J²) >= 0. On failure `why` names the field and the rule.
  bool IsValid(std::string* why) const;
};

/// Every multiplier of Theorem 3 (n followers): Q, Ψ, Z, X, Y are 2n × 2n, Φ is n × n.
struct Theorem3Multipliers {
  Eigen::MatrixXd Q, Psi, Z, X, Y, Phi;
};

/// The paper's Example 2 choice: X = 0.3I, Y = 0, Z = I, Ψ = 0.1I, Φ = 0.6I (Q zero; the
/// paper solves for Q).
Theorem3Multipliers PaperMultipliers(int n);

/// Ξ of (27) for the given multipliers (in the input's form); symmetric, 5n × 5n.
/// Precondition: H is n × n, Q, Ψ, Z, X, Y are 2n × 2n, Φ is n × n.
Eigen::MatrixXd AssembleXi(const Theorem3Input& in, const Theorem3Multipliers& m);

/// Eigenvalue check of a candidate certificate, recomputed in double precision.
struct Theorem3Check {
  double xi_max_eigenvalue = 0.0;   // λmax(Ξ), must be < 0
  double q_min_eigenvalue = 0.0;    // λmin(Q), must be > 0
  double psi_min_eigenvalue = 0.0;  // λmin(Ψ) > 0
  double z_min_eigenvalue = 0.0;    // λmin(Z) > 0
  double phi_min_eigenvalue = 0.0;  // λmin(Φ) > 0
  double xyz_min_eigenvalue = 0.0;  // λmin([X Y; Yᵀ Z]) >= 0 (we require > 0)
  double phi_off_diagonal = 0.0;    // max |Φ_ij|, i != j (must be 0 in the corrected form)
  double scale = 0.0;               // tr Q + tr Ψ + tr X + tr Z + tr Φ (the SDP sets it to 1)
  /// min(−λmax(Ξ), λmin(Q), λmin(Ψ), λmin(Φ), λmin([X Y; Yᵀ Z])) / scale; negative or zero
  /// means the matrices are no certificate.
  double margin = 0.0;
};
/// Wrong shapes give margin −inf.
Theorem3Check CheckMultipliers(const Theorem3Input& in, const Theorem3Multipliers& m);

struct Theorem3Options {
  /// A certificate counts only if Theorem3Check::margin >= strict_margin: every strict
  /// inequality holds with at least this margin relative to the multipliers' total trace.
  double strict_margin = 1e-7;
  CsdpOptions csdp;
};

struct Theorem3Result {
  Theorem3Input input;
  bool input_valid = false;
  /// One line: the outcome and, when not feasible, why (invalid input, solver failure,
  /// no certificate with the required margin).
  std::string message;
  int csdp_return_code = -1;  // -1 if CSDP was not called
  std::string csdp_status;    // CsdpReturnCodeMeaning(csdp_return_code)
  /// The LMI (in input.form) holds at the returned multipliers, checked with Eigen:
  /// CSDP returned 0 or 3 and check.margin >= strict_margin. Never true otherwise.
  bool feasible = false;
  double solver_margin = 0.0;  // t* of the SDP (normalised margin CSDP reports)
  Theorem3Check check;         // recomputed at `certificate`
  Theorem3Multipliers certificate;
  double strict_margin = 0.0;  // the threshold used
  double seconds = 0.0;        // set-up + CSDP + check
  int lmi_variables = 0;       // scalar decision variables (t included)

  /// Feasible in the corrected form: Theorem 3 certifies consensus for delays up to h
  /// with rate up to κ and the given Lipschitz data.
  bool certifies() const { return feasible && input.form == Theorem3Form::kCorrected; }
};

/// Feasibility SDP (every multiplier free), decided by the Eigen check:
///   maximise t  s.t.  −Ξ − tI ⪰ 0,  Q − tI ⪰ 0,  Ψ − tI ⪰ 0,  Φ − tI ⪰ 0,
///                     [X Y; Yᵀ Z] − tI ⪰ 0,  tr Q + tr Ψ + tr X + tr Z + tr Φ <= 1.
/// The LMI is homogeneous, so the trace normalisation loses nothing and bounds t; it is
/// strictly feasible iff t* > 0. Never prints; never throws on bad input (see message).
Theorem3Result CheckTheorem3(const Theorem3Input& in, const Theorem3Options& options = {});

struct MaxDelayResult {
  bool input_valid = false;
  std::string message;
  bool feasible_at_zero = false;  // the LMI holds at h = 0 (else no delay is certified)
  /// Largest h found feasible (the lower end of the final bracket, so never above the
  /// true threshold by more than the solver's accuracy); 0 if !feasible_at_zero.
  double max_delay_s = 0.0;
  /// Smallest h found infeasible (upper end of the final bracket); +inf if hit_cap.
  double infeasible_from_s = 0.0;
  bool hit_cap = false;  // feasible at h_cap: the search stopped there
  double h_cap_s = 0.0;
  int solves = 0;           // CSDP calls
  int solver_failures = 0;  // of those, CSDP return codes other than 0 and 3 (counted
                            // as infeasible: the search stays conservative)
  double seconds = 0.0;
  Theorem3Result at_max;  // the certificate at max_delay_s
};

/// Largest h for which CheckTheorem3 is feasible (input.h_s is ignored).
/// Bracket: h = 0 first (infeasible there: nothing certified, stop); then h = 0.1 s,
/// doubled until infeasible or above h_cap_s; then bisection until the bracket is
/// narrower than tol_s. Feasibility is monotone in h (Ξ(h') = Ξ(h) − (h − h')
/// (diag(X,0,0) + [A B E2]ᵀZ[A B E2]) ⪯ Ξ(h) for h' < h), so bisection is exact up to
/// the solver's accuracy.
MaxDelayResult MaxDelayTheorem3(Theorem3Input in, double tol_s = 1e-3,
                                const Theorem3Options& options = {}, double h_cap_s = 1000.0);

struct PaperMultipliersResult {
  bool input_valid = false;
  std::string message;
  int csdp_return_code = -1;
  std::string csdp_status;
  bool solved = false;        // CSDP returned 0 or 3
  double solver_value = 0.0;  // t* of the SDP
  /// λmax(Ξ) recomputed with Eigen at the returned Q and the paper's X, Y, Z, Ψ, Φ: the
  /// number to report. Negative would mean the paper's choice certifies h, κ.
  double max_eigenvalue = 0.0;
  Eigen::MatrixXd Q;
  double q_min = 0.0;  // the lower bound imposed on Q (Q ⪰ q_min I)
  double seconds = 0.0;
};

/// min t over Q  s.t.  Ξ(Q; X = 0.3I, Y = 0, Z = I, Ψ = 0.1I, Φ = 0.6I) ⪯ tI,  Q ⪰ q_min I.
/// With the other multipliers fixed, λmax(Ξ) is bounded below (Ξ22 and Ξ33 do not
/// depend on Q), so the minimum exists.
PaperMultipliersResult PaperMultipliersMaxEigenvalue(const Theorem3Input& in,
                                                     const Theorem3Options& options = {},
                                                     double q_min = 1e-6);

/// Writes the result (input, status, margins and the matrices Q, Ψ, Z, X, Y, Φ) as one
/// JSON object (nlohmann-json: every number in its shortest round-trip form, so the
/// certificate re-reads to the same matrices; non-finite numbers as null).
bool WriteCertificate(const Theorem3Result& result, const std::string& path, std::string* err);
std::string CertificateJson(const Theorem3Result& result);

}  // namespace shoal::design
