#pragma once

#include <string>
#include <vector>

namespace shoal {

struct SimOptions {
  std::string scenario;
  std::vector<std::string> set;  // --set KEY=VALUE changes of the scenario, in order
  std::string out;          // LCM log path; "" = no log
  double duration_s = -1;   // < 0: the scenario's
  bool json = false;
  bool quiet = false;       // no progress line
  bool allow_large = false; // run even when the estimate exceeds 1 h or 4 GiB
};

/// `shoal sim`: exit status 0 converged, 1 ran but did not converge / diverged,
/// 2 bad input, 130 interrupted.
int RunSim(const SimOptions& opt);

}  // namespace shoal
