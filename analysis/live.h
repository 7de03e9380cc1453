// shoal analyze --live: a run read from the bus instead of a log.
#pragma once

#include <string>

#include "analysis/run_data.h"

namespace shoal {

struct LiveOptions {
  std::string url;                  // LCM URL; "" = LCM's default
  double duration_s = 0;            // stop after this many wall seconds; <= 0 or NaN: no limit
  bool progress = false;            // a progress line on stderr (only on a terminal)
  /// The run's key: every message must verify with it (the others are dropped and
  /// counted). None: trailers are stripped unchecked (and counted as unverified).
  std::optional<bus_auth::Key> key;
};

/// Subscribes to every Shoal channel on `opt.url` until SIGINT/SIGTERM, a run-level end
/// status (plus a short drain for the last messages in flight), or `opt.duration_s` wall
/// seconds, and builds the run's RunData as a log would. False with a message when the
/// bus cannot be opened or nothing from a Shoal run was received.
bool ReadLiveRun(const LiveOptions& opt, const LoadOptions& lo, RunData* run, std::string* error);

}  // namespace shoal
