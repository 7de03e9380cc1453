// LCM channel names: built and parsed here and nowhere else, so that a name's shape
// (docs/run.md lists the channels) lives in one place.
#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace shoal {
namespace channels {

namespace detail {
constexpr std::string_view kPrefix = "SHOAL_";
constexpr std::string_view kState = "SHOAL_STATE_";
constexpr std::string_view kRx = "SHOAL_RX_";
constexpr std::string_view kHealth = "SHOAL_HEALTH_";

inline bool StartsWith(std::string_view s, std::string_view p) {
  return s.size() >= p.size() && s.compare(0, p.size(), p) == 0;
}
/// "123" or "-1" (the whole string, at most 7 characters) -> the id.
inline std::optional<int> ParseId(std::string_view s) {
  if (s.empty() || s.size() > 7) return std::nullopt;
  const bool neg = s[0] == '-';
  std::size_t i = neg ? 1 : 0;
  if (i == s.size()) return std::nullopt;
  int v = 0;
  for (; i < s.size(); ++i) {
    if (s[i] < '0' || s[i] > '9') return std::nullopt;
    v = v * 10 + (s[i] - '0');
  }
  return neg ? -v : v;
}
/// The id after `prefix`, if `ch` is `prefix` followed by an id.
inline std::optional<int> IdAfter(std::string_view ch, std::string_view prefix) {
  if (!StartsWith(ch, prefix)) return std::nullopt;
  return ParseId(ch.substr(prefix.size()));
}
}  // namespace detail

/// What vehicle `id` (leader = 0) transmits.
inline std::string State(int id) { return std::string(detail::kState) + std::to_string(id); }
/// What vehicle `id` receives, after the channel emulator.
inline std::string Rx(int id) { return std::string(detail::kRx) + std::to_string(id); }
/// Health of process `id`.
inline std::string Health(int id) { return std::string(detail::kHealth) + std::to_string(id); }
/// Ground truth of every channel decision.
inline const char* ChannelEvents() { return "SHOAL_CHANNEL"; }
inline const char* Clock() { return "SHOAL_CLOCK"; }
inline const char* Status() { return "SHOAL_STATUS"; }

/// Subscription patterns (LCM regular expressions): every vehicle's state; everything.
constexpr const char* kStatePattern = "SHOAL_STATE_[0-9]+";
constexpr const char* kAllPattern = "SHOAL_.*";

/// The id of a State(id) channel; nullopt for any other name.
inline std::optional<int> ParseStateId(std::string_view ch) {
  return detail::IdAfter(ch, detail::kState);
}
/// The id of an Rx(id) channel; nullopt for any other name.
inline std::optional<int> ParseRxId(std::string_view ch) {
  return detail::IdAfter(ch, detail::kRx);
}
/// The id of a Health(id) channel (-1: the channel emulator); nullopt for any other name.
inline std::optional<int> ParseHealthId(std::string_view ch) {
  return detail::IdAfter(ch, detail::kHealth);
}

/// What a channel name is, for readers of every channel (logs, shoal analyze --live).
enum class Kind { kState, kRx, kHealth, kChannelEvents, kClock, kStatus, kOther };
struct Parsed {
  Kind kind = Kind::kOther;
  int id = 0;  // kState, kRx, kHealth
};
/// Parses any name; kOther for one that no Shoal process publishes (a malformed id too).
inline Parsed Parse(std::string_view ch) {
  if (!detail::StartsWith(ch, detail::kPrefix)) return {};
  if (const auto id = ParseStateId(ch)) return {Kind::kState, *id};
  if (const auto id = ParseRxId(ch)) return {Kind::kRx, *id};
  if (const auto id = ParseHealthId(ch)) return {Kind::kHealth, *id};
  if (ch == ChannelEvents()) return {Kind::kChannelEvents, 0};
  if (ch == Clock()) return {Kind::kClock, 0};
  if (ch == Status()) return {Kind::kStatus, 0};
  return {};
}

}  // namespace channels

/// Publisher ids of processes that are not vehicles.
constexpr int kEmulatorId = -1;
constexpr int kLauncherId = -2;

}  // namespace shoal
