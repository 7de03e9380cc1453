// The empirical delay margin: the constant delay at which `shoal sim` of the scenario stops
// converging, found by bisection. Model: the scenario's full nonlinear closed loop (Fossen
// 5-DOF REMUS plant, feedback linearisation with its actuator limits, protocol (10) with
// formation offsets, the leader's path, the uncertain factor and losses as configured),
// with the delay model replaced by one constant delay on every link (and in the uncertain
// factor's delayed arguments). Step semantics are `shoal sim`'s: a message is usable at
// the first control tick at or after send + tau and never before the next tick, so the
// delay is resolved to whole control periods and the search runs over tick counts.
#pragma once

#include <string>

#include "core/scenario.h"

namespace shoal {
namespace design {

struct EmpiricalMarginOptions {
  double duration_s = -1.0;  ///< simulated horizon of each run; < 0: the scenario's
  /// Upper end of the first bracket (e.g. 2x the exact margin); grown by doubling while
  /// the swarm still converges, up to the neighbour timeout.
  double initial_upper_s = 1.0;
};

struct EmpiricalMargin {
  bool converges_without_delay = false;  ///< converges with tau = one control period
  /// Largest constant delay (a whole number of control periods) at which the run converges.
  double margin_s = 0.0;
  /// The next period up, at which it does not converge (margin_s + one period); when
  /// capped is true, no failing delay was found below the cap.
  double first_failing_s = 0.0;
  bool capped = false;
  double cap_s = 0.0;       ///< largest delay tried (below the neighbour timeout)
  double period_s = 0.0;    ///< resolution: the control period
  double duration_s = 0.0;  ///< horizon of each run
  int runs = 0;             ///< simulations run
};

EmpiricalMargin FindEmpiricalMargin(const Scenario& s, const EmpiricalMarginOptions& opt);

/// One sentence describing the model and criterion, for reports.
std::string EmpiricalModelDescription(const Scenario& s, double duration_s);

}  // namespace design
}  // namespace shoal
