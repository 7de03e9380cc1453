// Runs a scenario's swarm (core::Swarm: the same step semantics as `shoal sim`) and
// measures what the design tools need: convergence as `shoal sim` reports it and the
// integrated squared formation error.
#pragma once

#include <vector>

#include "core/scenario.h"

namespace shoal {
namespace design {

/// The tuning cost, a functional of the formation errors e_p,i(t) (position, m) and
/// e_v,i(t) (velocity, all of eta', so pitch and heading rates count too), summed over the
/// followers, integrated by the rectangle rule at the control period:
///   kPositionIse  integral of e_p^2 dt                                  (m^2 s)
///   kIse          integral of (e_p / p_tol)^2 + (e_v / v_tol)^2 dt       (s)
///   kItse         integral of t ((e_p / p_tol)^2 + (e_v / v_tol)^2) dt   (s^2)
/// with p_tol, v_tol the scenario's convergence tolerances ([metrics]).
enum class CostKind { kPositionIse, kIse, kItse };

const char* CostName(CostKind k);

struct SimOutcome {
  bool converged = false;            ///< shoal sim's criterion, and no follower diverged
  double convergence_time_s = -1.0;  ///< -1 if not converged
  int diverged_id = 0;               ///< first follower that diverged (0: none)
  double sim_time_s = 0.0;           ///< simulated time reached
  /// Integrated squared position error (the kPositionIse cost), m^2 s.
  double ise_m2s = 0.0;
  /// The requested cost.
  double cost = 0.0;
};

/// Runs `s` for duration_s (< 0: the scenario's). If `residuals` is given it receives two
/// residuals per tick and follower whose squared sum is `cost` (the position and velocity
/// terms; the velocity residual is 0 for kPositionIse).
SimOutcome RunSwarm(const Scenario& s, double duration_s, CostKind cost = CostKind::kItse,
                    std::vector<double>* residuals = nullptr);

/// The scenario with a constant delay tau_s on every link (defaults and per-link overrides;
/// losses unchanged) and in the uncertain factor's delayed arguments.
Scenario WithConstantDelay(const Scenario& s, double tau_s);

/// The scenario with gains k1, k2.
Scenario WithGains(const Scenario& s, double k1, double k2);

}  // namespace design
}  // namespace shoal
