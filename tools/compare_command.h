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
  /// Compare only the states both logs hold. Without it a state in only one log fails
  /// the comparison (a truncated log must not pass); with it, for a log known to be
  /// partial (lcm-logger may drop states of a run on a shared bus).
  bool allow_missing = false;
  bool json = false;
  /// The runs' key files (default: <log>.key next to each log if it exists): with a key,
  /// only the states that authenticate are compared.
  std::string key_a, key_b;
};

/// `shoal compare A B`: vehicle states of two logs at matching (vehicle, time).
/// Exit 0 with at least one matching state, every difference finite and within the
/// tolerances, and (unless allow_missing) no state in only one of the logs; 1 otherwise;
/// 2 for unreadable input (docs/cli.md).
int RunCompare(const CompareOptions& opt);

}  // namespace shoal
