// LCM channel names: built here and nowhere else (DESIGN.md, "Processes and messages").
#pragma once

#include <string>

namespace shoal {
namespace channels {

/// What vehicle `id` (leader = 0) transmits.
inline std::string State(int id) { return "SHOAL_STATE_" + std::to_string(id); }
/// What vehicle `id` receives, after the channel emulator.
inline std::string Rx(int id) { return "SHOAL_RX_" + std::to_string(id); }
/// Health of process `id`.
inline std::string Health(int id) { return "SHOAL_HEALTH_" + std::to_string(id); }
/// Ground truth of every channel decision.
inline const char* ChannelEvents() { return "SHOAL_CHANNEL"; }
inline const char* Clock() { return "SHOAL_CLOCK"; }
inline const char* Status() { return "SHOAL_STATUS"; }

}  // namespace channels

/// Publisher ids of processes that are not vehicles.
constexpr int kEmulatorId = -1;
constexpr int kLauncherId = -2;

}  // namespace shoal
