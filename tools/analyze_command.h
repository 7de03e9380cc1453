#pragma once

#include <limits>
#include <string>

namespace shoal {

struct AnalyzeOptions {
  std::string log;        // LCM log to analyse (not with --live)
  std::string scenario;   // scenario file to use instead of the log's (shoal run logs)
  std::string csv_dir;    // "" = no CSV
  bool json = false;
  bool live = false;      // attach to an LCM bus instead of reading a log
  std::string lcm_url;    // --live: "" = LCM's default URL
  /// --live: stop after this many wall-clock seconds (NaN: not given, no limit).
  double duration_s = std::numeric_limits<double>::quiet_NaN();
  /// --live: stop this many wall seconds after the last Shoal message (NaN: not given,
  /// kDefaultUntilIdleS; 0: never).
  double until_idle_s = std::numeric_limits<double>::quiet_NaN();
  bool quiet = false;     // no progress line (--live)
  /// The run's key file (default: <log>.key if it exists; --live: SHOAL_BUS_KEY).
  std::string key_file;
};

/// `shoal analyze`: metrics of a run from its log (or live from a bus), --json, --csv.
/// Exit 0 analysed (warnings, if the log is damaged, on stderr and in the JSON);
/// 2 bad input (options, unreadable / empty / non-LCM log, no Shoal data, nothing received);
/// 3 (--live) the stream missed part of the run: the analysis is printed, marked incomplete.
int RunAnalyze(const AnalyzeOptions& opt);

}  // namespace shoal
