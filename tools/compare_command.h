#pragma once

#include <string>

namespace shoal {

struct CompareOptions {
  std::string a, b;
  bool json = false;
};

/// `shoal compare A B`: vehicle states of two logs at matching (vehicle, time).
/// Exit 0 with at least one matching sample, 1 with none, 2 for unreadable input.
int RunCompare(const CompareOptions& opt);

}  // namespace shoal
