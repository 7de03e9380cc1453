#pragma once

#include <optional>
#include <string>
#include <vector>

namespace shoal {

struct DesignOptions {
  std::string scenario;
  std::vector<std::string> set;  // --set KEY=VALUE changes of the scenario, in order
  bool json = false;
  // Overrides of the scenario's values (empty: the scenario's).
  std::optional<double> k1, k2;
  std::optional<double> h_s, kappa;
  std::optional<double> rho0;
  double alpha = 0.05;  // Theorem 1-2 parameters, the paper's values by default
  double beta = 6.4;
  double safety = 2.0;  // required margin = safety x h (--tune, advice)
  std::string certificate;  // --certificate FILE: Theorem 3's matrices (JSON)
  bool empirical = false;
  double empirical_duration_s = -1.0;  // < 0: the scenario's run.duration_s
  bool tune = false;
  double tune_horizon_s = 120.0;
  std::string tune_cost = "itse";  // itse, ise or position_ise (design/sim_eval.h)
  bool advise = false;         // --advise: gains Theorem 3 certifies (design/advise.h)
  std::string write_scenario;  // --write-scenario FILE: the scenario with the advised gains
  bool allow_large = false;    // --allow-large: run a design estimated beyond the limits
};

/// `shoal design` (docs/theory.md): exit status 0 certified, 1 not certified, 2 bad input.
int RunDesign(const DesignOptions& opt);

}  // namespace shoal
