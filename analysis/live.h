// shoal analyze --live: a run read from the bus instead of a log.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "analysis/analysis.h"
#include "analysis/run_data.h"

namespace shoal {

/// --until-idle's default: a stream that ends without a run-level end status ends the
/// listening this long after its last message. Long enough for the silence of a large
/// swarm's start-up on a loaded host (statuses, then the first tick).
constexpr double kDefaultUntilIdleS = 30.0;

struct LiveOptions {
  std::string url;                  // LCM URL; "" = LCM's default
  double duration_s = 0;            // stop after this many wall seconds; <= 0 or NaN: no limit
  /// Stop when no Shoal message arrived for this many wall seconds, after the first one
  /// (a player that ends, a run that stops publishing); <= 0: never.
  double until_idle_s = kDefaultUntilIdleS;
  bool progress = false;            // a progress line on stderr (only on a terminal)
  /// The run's key: every message must verify with it (the others are dropped and
  /// counted). None: trailers are stripped unchecked (and counted as unverified).
  std::optional<bus_auth::Key> key;
};

/// Subscribes to every Shoal channel on `opt.url` until SIGINT/SIGTERM, a run-level end
/// status (plus a short drain for the last messages in flight), `opt.duration_s` wall
/// seconds, or `opt.until_idle_s` without a message, and builds the run's RunData as a
/// log would, with run->stream saying how it ended and what the sequence numbers miss.
/// False with a message when the bus cannot be opened or nothing from a Shoal run was
/// received.
bool ReadLiveRun(const LiveOptions& opt, const LoadOptions& lo, RunData* run, std::string* error);

/// Whether a live stream held the whole run. The states the run should have published
/// are those `shoal run` expects of its log (RunAnalysis::states_expected: every tick of
/// the scenario, or up to the clock's final tick, for the leader and every follower),
/// less those a restarted process never published; what did not arrive was missed,
/// before the listening started, in it (a receive buffer overrun when a player goes
/// faster than the analysis), or after it stopped.
struct LiveCompleteness {
  bool complete = false;
  std::int64_t states_missed = 0;
  std::int64_t messages_missed = 0;  // the other channels' sequence gaps
  std::vector<std::string> reasons;  // one sentence each; empty when complete
};
LiveCompleteness JudgeLiveStream(const RunData& run, const RunAnalysis& a);

}  // namespace shoal
