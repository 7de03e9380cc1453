// Applying scenario overrides to a parsed TOML tree: shared by the loader only (it needs
// toml++, which the public headers keep out of their users' builds).
#pragma once

#include <toml++/toml.h>

#include <vector>

#include "scenario/overrides.h"
#include "scenario/toml_depth.h"

namespace shoal {

/// Applies `overrides` to `root` in order. A value's nodes carry its origin as their
/// source path, so that the loader's messages name it. Throws ScenarioError naming the
/// origin when a key or value is malformed or its path does not exist in `root`.
void ApplyOverrides(const std::vector<ScenarioOverride>& overrides, toml::table* root);

}  // namespace shoal
