// shoal retime: a copy of a run's log whose event timestamps are mission time, so that
// lcm-logplayer replays it at the mission's pace (docs/analyze.md, Replay).
#pragma once

#include <string>

namespace shoal {

struct RetimeOptions {
  std::string log;    // the log to read (never written)
  std::string out;    // the retimed log to write
  bool force = false; // replace an existing `out` (never the input)
  bool quiet = false; // no summary line
};

/// Writes `out` (atomically: a temporary file renamed into place) with the events of
/// `log`, in the same order and with the same bytes, each stamped with the log's first
/// timestamp plus the mission time its message holds (its utime; never earlier than the
/// event before it), preceded by a marker event (kRetimedChannel) that names the
/// original and keeps its first and last stamps. `<log>.key` is copied to `<out>.key`.
/// Exit 0 written; 2 bad input (options, unreadable or non-LCM log, no Shoal message,
/// `out` is the input, exists without --force, or cannot be written).
int RunRetime(const RetimeOptions& opt);

}  // namespace shoal
