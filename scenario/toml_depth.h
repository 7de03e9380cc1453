// Key depth of TOML text, checked before parsing it: shared by every reader of a TOML file
// (scenarios, their overrides, campaigns). Free of toml++ so its users need not build it.
#pragma once

#include <string_view>

namespace shoal {

/// Deepest nesting of tables a key may reach: the TOML parser builds and frees nested
/// tables recursively, so a deeper key would overflow the stack.
constexpr int kMaxKeyDepth = 256;

/// The line of the first key of `text` deeper than kMaxKeyDepth tables, 0 if there is none.
int LineOfTooDeepKey(std::string_view text);

}  // namespace shoal
