// Runs a scenario's swarm (core::Swarm: the same step semantics as `shoal sim`) and
// measures what the design tools need: convergence as `shoal sim` reports it and the
// integrated squared formation position error.
#pragma once

#include <vector>

#include "core/scenario.h"

namespace shoal {
namespace design {

struct SimOutcome {
  bool converged = false;            ///< shoal sim's criterion, and no follower diverged
  double convergence_time_s = -1.0;  ///< -1 if not converged
  int diverged_id = 0;               ///< first follower that diverged (0: none)
  double sim_time_s = 0.0;           ///< simulated time reached
  /// Integrated squared position error, sum over followers of the integral of
  /// ||(p_i - d_i) - p_0||^2 dt (m^2 s), rectangle rule at the control period.
  double ise_m2s = 0.0;
  /// The tuning cost: the integrated squared formation error with each error normalised by
  /// its convergence tolerance ([metrics]), summed over followers (s):
  ///   sum_i integral (e_p,i / position_tol_m)^2 + (e_v,i / velocity_tol_mps)^2 dt.
  /// e_v covers all of eta' (also pitch and heading rates), so attitude dynamics count too.
  double cost_s = 0.0;
};

/// Runs `s` for duration_s (< 0: the scenario's). If `residuals` is given it receives
/// sqrt(period) e_p,i / position_tol_m and sqrt(period) e_v,i / velocity_tol_mps at every
/// tick and follower (so that their squared sum is cost_s).
SimOutcome RunSwarm(const Scenario& s, double duration_s, std::vector<double>* residuals = nullptr);

/// The scenario with a constant delay tau_s on every link (defaults and per-link overrides;
/// losses unchanged) and in the uncertain factor's delayed arguments.
Scenario WithConstantDelay(const Scenario& s, double tau_s);

/// The scenario with gains k1, k2.
Scenario WithGains(const Scenario& s, double k1, double k2);

}  // namespace design
}  // namespace shoal
