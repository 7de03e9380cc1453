// Applying scenario overrides to a parsed TOML tree: shared by the loader only (it needs
// toml++, which the public headers keep out of their users' builds).
#pragma once

#include <toml++/toml.h>

#include <string_view>
#include <vector>

#include "scenario/overrides.h"

namespace shoal {

/// Deepest nesting of tables a key may reach: the TOML parser builds and frees nested
/// tables recursively, so a deeper key would overflow the stack.
constexpr int kMaxKeyDepth = 256;

/// The line of the first key of `text` deeper than kMaxKeyDepth tables, 0 if there is none.
int LineOfTooDeepKey(std::string_view text);

/// Applies `overrides` to `root` in order. A value's nodes carry its origin as their
/// source path, so that the loader's messages name it. Throws ScenarioError naming the
/// origin when a key or value is malformed or its path does not exist in `root`.
void ApplyOverrides(const std::vector<ScenarioOverride>& overrides, toml::table* root);

}  // namespace shoal
