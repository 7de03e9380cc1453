// Loads and validates a scenario TOML file completely before anything runs.
#pragma once

#include <stdexcept>
#include <string>

#include "core/scenario.h"

namespace shoal {

/// A scenario problem. what() is the complete user-facing message:
///   "<file>:<line>: <key>: <what is wrong>; <how to fix it>"
class ScenarioError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Reads `path` and returns the validated scenario; throws ScenarioError.
Scenario LoadScenario(const std::string& path);

/// LoadScenario for a command's start-up: on error prints "<who>: <message>" to stderr and
/// returns false (the caller exits with status 2).
bool LoadScenarioOrReport(const std::string& who, const std::string& path, Scenario* out);

/// Parses scenario text; `path` is used in messages, for source_path and for the default
/// name. Relative trace files are read from the directory of `path` if it names a regular
/// file, else from the working directory (the text of a log).
Scenario ParseScenario(const std::string& text, const std::string& path);

}  // namespace shoal
