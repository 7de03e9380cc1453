#pragma once

#include <string>
#include <vector>

namespace shoal {

struct SweepOptions {
  std::string campaign;
  std::string out;
  int workers = 0;               // 0: the campaign's, else one per core (realtime: 1)
  std::string shard;             // "K/N"; "" = all points
  std::vector<std::string> set;  // --set KEY=VALUE, applied before the axes
  bool quiet = false;            // no progress line, no summary
  bool allow_large = false;      // run (and pass --allow-large to) points estimated large
};

struct SweepMergeOptions {
  std::vector<std::string> dirs;
  std::string out;
  bool allow_missing = false;
  bool allow_overlap = false;
  bool quiet = false;
};

/// `shoal sweep`: exit status 0 every point passed, 1 some point failed, crashed or hung,
/// 2 bad input (nothing ran), 130 interrupted (finished points kept; rerun to resume).
int RunSweep(const SweepOptions& opt);

/// `shoal sweep merge`: 0 every point passed, 1 some did not, 2 bad input.
int RunSweepMerge(const SweepMergeOptions& opt);

}  // namespace shoal
