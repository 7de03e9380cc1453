// Gain tuning with Ceres: k1, k2 minimising the integrated squared formation error of a
// `shoal sim` run of the scenario (core::Swarm over a tuning horizon; see CostKind: by
// default time-weighted, position and velocity errors each normalised by its convergence
// tolerance), subject to the exact constant-delay margin being at least safety x h.
//
// The constraint is built into the parametrisation instead of a penalty. Scaling
// k1 -> c^2 k1, k2 -> c k2 divides the margin by c exactly (s -> c s, tau -> tau / c in
// s^2 + lambda (k2 s + k1) e^{-s tau}). So with the shape r = k1 / k2^2 and the margin
// theta(r) of (k1, k2) = (r, 1), every pair is
//   k2 = u theta(r) / tau_required,  k1 = r k2^2,  margin = theta(r) / k2 = tau_required / u,
// and the constraint margin >= tau_required is exactly the bound u <= 1. Ceres
// (Levenberg-Marquardt, central-difference Jacobians of the simulated error samples)
// optimises (log r, u) with bounds, from several starts; the best result wins.
#pragma once

#include <string>
#include <vector>

#include "core/scenario.h"
#include "core/theory.h"
#include "design/sim_eval.h"

namespace shoal {
namespace design {

struct TuneOptions {
  double safety = 2.0;       ///< required margin = safety x max(h, control period)
  double horizon_s = 120.0;  ///< simulated horizon of each cost evaluation
  int max_iterations = 20;   ///< per start
  CostKind cost = CostKind::kItse;
};

struct TunePoint {
  double k1 = 0.0, k2 = 0.0;
  double margin_s = 0.0;             ///< exact constant-delay margin
  double cost = 0.0;                 ///< the tuning cost over the horizon (TuneOptions::cost)
  double position_ise_m2s = 0.0;     ///< position part alone, in m^2 s
  bool converged = false;            ///< full-length run (scenario duration) converged
  double convergence_time_s = -1.0;  ///< of that run; -1 if not converged
};

struct TuneStart {
  double k1_start = 0.0, k2_start = 0.0;
  double k1 = 0.0, k2 = 0.0;
  double cost = 0.0;
  int iterations = 0;
  bool usable = false;
  std::string message;  ///< Ceres' termination message
};

struct TuneResult {
  bool ok = false;
  std::string message;  ///< why not ok
  double h_s = 0.0;
  double required_margin_s = 0.0;  ///< safety x max(h, control period)
  double horizon_s = 0.0;
  TunePoint before, after;
  bool before_feasible = false;  ///< the scenario's gains meet the margin requirement
  std::vector<TuneStart> starts;
  int sim_runs = 0;
};

/// `eigenvalues` of H; `h_s` the delay bound to protect (the scenario's or --h).
TuneResult Tune(const Scenario& s, const std::vector<theory::Complex>& eigenvalues, double h_s,
                const TuneOptions& opt);

}  // namespace design
}  // namespace shoal
