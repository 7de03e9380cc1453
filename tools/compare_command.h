#pragma once

#include <string>

namespace shoal {

struct CompareOptions {
  std::string a, b;
  /// Largest allowed difference of matching states. The defaults let a lockstep SIL run
  /// and shoal sim of the same scenario pass (they agree to the bit; 1e-9 leaves room for
  /// the last digits of a log written elsewhere) and flag any other difference.
  double position_tol_m = 1e-9;
  double velocity_tol_mps = 1e-9;
  bool json = false;
};

/// `shoal compare A B`: vehicle states of two logs at matching (vehicle, time).
/// Exit 0 with at least one matching sample and every difference within the tolerances,
/// 1 with none or beyond a tolerance, 2 for unreadable input (docs/cli.md).
int RunCompare(const CompareOptions& opt);

}  // namespace shoal
