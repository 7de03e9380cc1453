// Loads and validates a scenario TOML file completely before anything runs.
#pragma once

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/scenario.h"
#include "scenario/overrides.h"

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

// The same with overrides (--set) applied in order to the parsed file before validation.
// A message about a value an override gave names the override's origin instead of
// "<file>:<line>"; any other message that only the overrides caused ends with
// "(scenario changed by <origins>)". Scenario::source_text is then ApplyOverridesToText's
// document. With no overrides these are the functions above, message for message.
Scenario LoadScenario(const std::string& path, const std::vector<ScenarioOverride>& overrides);
Scenario ParseScenario(const std::string& text, const std::string& path,
                       const std::vector<ScenarioOverride>& overrides);
bool LoadScenarioOrReport(const std::string& who, const std::string& path,
                          const std::vector<ScenarioOverride>& overrides, Scenario* out);

/// LoadScenarioOrReport with the text of --set flags (ParseSetFlags): a bad flag is
/// reported the same way.
bool LoadScenarioWithSetsOrReport(const std::string& who, const std::string& path,
                                  const std::vector<std::string>& set_flags, Scenario* out);

/// The scenario text with the overrides applied (a TOML document), for logs and campaigns:
/// the merged tree in TOML, headed by comments naming the base file and each override.
/// `text` itself when there are none. Throws ScenarioError on a bad file or override (it
/// does not validate the result: ParseScenario does).
std::string ApplyOverridesToText(const std::string& text, const std::string& path,
                                 const std::vector<ScenarioOverride>& overrides);

/// A scenario file parsed once, for checking many sets of overrides (a campaign's points):
/// Read(overrides) accepts and refuses what ParseScenario(text, path, overrides) does, with
/// the same messages, and gives the same scenario except that its source_text is empty and
/// an event's line is the file's (the effective text is not written and parsed again).
class ScenarioTemplate {
 public:
  /// Throws ScenarioError, located, on a syntax error.
  ScenarioTemplate(std::string text, std::string path);
  ~ScenarioTemplate();
  ScenarioTemplate(const ScenarioTemplate&) = delete;
  ScenarioTemplate& operator=(const ScenarioTemplate&) = delete;

  Scenario Read(const std::vector<ScenarioOverride>& overrides) const;

 private:
  struct Tree;
  std::unique_ptr<Tree> tree_;
  std::string text_;
  std::string path_;
};

}  // namespace shoal
