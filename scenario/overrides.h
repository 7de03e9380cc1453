// Changes to a scenario given on the command line (--set) or by a campaign, applied to the
// parsed TOML tree before validation (docs/scenario.md, "Changing a scenario from the
// command line: --set").
#pragma once

#include <string>
#include <vector>

namespace shoal {

/// One `key=value` change of a scenario. `key`: dotted, as in the loader's messages
/// ("channel.delay.base_s", "follower[2].k1", "channel.link[0].delay"); `value`: TOML value
/// text ("0.3", "\"constant\"", "{ model = \"constant\", base_s = 0.3 }", "[1, 2]"); a
/// bare word that is not a TOML value (constant) reads as a string. `origin`: how messages
/// name where it came from ("--set channel.delay.base_s=0.3", "sweep.toml:12: axis
/// channel.delay.base_s").
struct ScenarioOverride {
  std::string key;
  std::string value;
  std::string origin;
};

/// Parses "key=value" as given to --set; throws ScenarioError naming --set on bad syntax.
ScenarioOverride ParseSetFlag(const std::string& text);

/// ParseSetFlag of each, in order.
std::vector<ScenarioOverride> ParseSetFlags(const std::vector<std::string>& texts);

/// A double as text that reads back as the same double (%.17g), for a number handed to
/// another process or written into a scenario: six decimals would make 0.0199996 s 0.02 s,
/// a tick more at 50 Hz, and 1e-7 s zero.
std::string ExactNumber(double v);

}  // namespace shoal
