// The report of `shoal design`: everything the command computes for a scenario (topology,
// delays, uncertain factor, Theorems 1-3, the exact delay margins, optionally the
// empirical margin, tuning and advised gains; per topology of a switching timeline and
// the acoustic delays in formation) and the verdict, as one value. The command
// only parses flags, calls BuildDesignReport and prints one of the two renderings.
#pragma once

#include <cstdint>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/scenario.h"
#include "core/theory.h"
#include "design/advise.h"
#include "design/empirical_margin.h"
#include "design/formation_delay.h"
#include "design/sim_eval.h"
#include "design/switching.h"
#include "design/theorem3.h"
#include "design/tune.h"
#include "design/verdict.h"

namespace shoal {
namespace design {

/// What to compute; empty optionals take the scenario's values. Field by field the flags
/// of `shoal design` (docs/theory.md), so IsValid's messages name the flags.
struct DesignRequest {
  std::optional<double> k1, k2;
  std::optional<double> h_s, kappa;
  std::optional<double> rho0;
  double alpha = 0.05;  ///< Theorem 1-2 parameters, the paper's values by default
  double beta = 6.4;
  double safety = 2.0;  ///< required margin = safety x h (--tune, advice)
  bool empirical = false;
  double empirical_duration_s = -1.0;  ///< < 0: the scenario's run.duration_s
  bool tune = false;
  double tune_horizon_s = 120.0;
  CostKind tune_cost = CostKind::kItse;
  bool advise = false;
  /// Called before each long step (empirical margin, tuning, advice); may be empty.
  std::function<void(const std::string&)> progress;

  /// The values alone and against the scenario (--rho0 below the model's own Lipschitz
  /// constant). On failure `why` is the message, naming the flag.
  bool IsValid(const Scenario& s, std::string* why) const;
};

struct Theorem3Section {
  bool evaluated = false;
  std::string not_evaluated_reason;
  bool rho0_from_flag = false;  ///< lambda_G2 = lambda_J2 = rho0^2 from --rho0
  Theorem3Input input;
  Theorem3Result at_h;
  MaxDelayResult max_delay;
  PaperMultipliersResult paper;
  /// The result to write with --certificate: at h if certified there (or nothing is
  /// certified even at h = 0), else at the largest certified h.
  const Theorem3Result& CertificateResult() const;
  /// Set by the caller that wrote it (empty: not written).
  std::string certificate_path;
};

struct EmpiricalSection {
  EmpiricalMargin margin;
  double wall_s = 0.0;
  std::string model;
};

struct TuneSection {
  TuneResult result;
  CostKind cost = CostKind::kItse;
  double wall_s = 0.0;
  /// Margins with the uncertain factor linearised (when shown), before and after.
  double before_factor_margin_s = 0.0, after_factor_margin_s = 0.0;
};

struct AdviceSection {
  bool evaluated = false;
  std::string not_evaluated_reason;
  GainAdvice advice;
  std::string scenario_written;  ///< set by the caller that wrote it (--write-scenario)
};

struct DesignReport {
  std::string scenario_name;
  int followers = 0;
  double k1 = 0.0, k2 = 0.0, alpha = 0.0, beta = 0.0;
  bool gains_from_flags = false;
  double safety = 2.0;
  double duration_s = 0.0;  ///< the scenario's run length
  double period_s = 0.0;    ///< the control period
  double position_tol_m = 0.0, velocity_tol_mps = 0.0;

  Eigen::MatrixXd H;
  std::vector<theory::Complex> eigenvalues;
  std::vector<int> unreachable_followers;

  DelayKind delay_model = DelayKind::kNone;
  bool per_link_overrides = false;
  bool delay_from_flags = false;
  theory::DelayBounds delay;
  /// Why kappa is unbounded, when it is and the flags did not bound it: "uniform jitter
  /// draws a new delay per message", "a channel event makes tau jump up", ...; "" else.
  std::string delay_rate_unbounded_why;

  DisturbanceKind disturbance = DisturbanceKind::kNone;
  bool relative_to_leader = false;
  theory::Lipschitz lipschitz;
  std::optional<double> rho0;
  bool rho0_from_flag = false;
  FactorKind factor = FactorKind::kNone;

  std::optional<theory::Theorem1> theorem1;
  std::optional<theory::Theorem2> theorem2;
  Theorem3Section theorem3;
  theory::DelayMargin margin;
  bool factor_margin_shown = false;
  theory::FactorDelayMargin factor_margin;
  /// Set when the timeline switches the topology: every section above is for topology 0
  /// (the [swarm] one); this one gives every topology and the common certificate.
  std::optional<SwitchingSection> switching;
  /// Set when some link's delay model is acoustic.
  std::optional<FormationDelay> formation_delay;
  std::optional<EmpiricalSection> empirical;
  std::optional<TuneSection> tune;
  std::optional<AdviceSection> advice;
  Verdict verdict;

  /// The exact margin the delays are held against: the smallest over the topologies
  /// when the topology switches, else the one topology's (0 when unstable without delay).
  double GoverningMarginS() const;
};

/// What BuildDesignReport will cost, estimated before it starts: Theorem 3's LMI has
/// 12 n^2 + 5 n variables (Q, Psi, Z, X symmetric 2n x 2n, Y 2n x 2n, Phi diagonal), and
/// CSDP's Schur complement is a dense matrix of that side, factorised at every iteration:
/// memory grows as n^4, time as n^6 (and faster with more links: H is denser).
struct DesignEstimate {
  bool theorem3 = false;         ///< Theorem 3 will be solved (else no SDP, little work)
  std::int64_t lmi_variables = 0;
  double wall_seconds = 0.0;     ///< Theorem 3 at h and its bisection, on one core
  double memory_bytes = 0.0;     ///< peak, mostly the Schur complement
  /// Beyond these a design is refused unless the user allows it (--allow-large).
  static constexpr double kMaxWallSeconds = 600.0;
  static constexpr double kMaxMemoryBytes = 4.0 * (1 << 30);
  bool large() const { return wall_seconds > kMaxWallSeconds || memory_bytes > kMaxMemoryBytes; }
};

/// Precondition: request.IsValid(s). Cheap: neither builds H nor solves anything.
DesignEstimate EstimateDesign(const Scenario& s, const DesignRequest& request);

/// "" if the design is not large, else why it is refused and how to run it anyway.
std::string LargeDesignRefusal(const Scenario& s, const DesignRequest& request);

/// Precondition: request.IsValid(s). Runs every analysis the request asks for; never
/// prints (progress goes to request.progress) and writes no file.
DesignReport BuildDesignReport(const Scenario& s, const DesignRequest& request);

/// The readable report; its last line is the verdict, followed by the advised gains when
/// they were asked for.
std::string DesignReportText(const DesignReport& r);

/// The same as one JSON object (docs/theory.md lists the keys). Non-finite numbers are null.
nlohmann::ordered_json DesignReportJson(const DesignReport& r);

const char* DelayKindName(DelayKind k);
const char* DisturbanceName(DisturbanceKind k);

}  // namespace design
}  // namespace shoal
