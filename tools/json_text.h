// The one way the shoal commands print JSON.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

namespace shoal {

/// One line of JSON. Strings that are not valid UTF-8 (a path typed on the command line, a
/// name read from a damaged log or the bus) are written with U+FFFD in place of the bad
/// bytes: nlohmann's default would throw, and a report must never abort the command.
inline std::string JsonText(const nlohmann::ordered_json& j) {
  return j.dump(-1, ' ', false, nlohmann::ordered_json::error_handler_t::replace);
}

}  // namespace shoal
