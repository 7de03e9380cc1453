#pragma once

#include <string>
#include <vector>

namespace shoal {

struct SoakOptions {
  std::string campaign;          // campaign file with a [soak] table
  std::string out;               // directory for soak.lcmlog, soak.json, soak.png
  std::vector<std::string> set;  // --set KEY=VALUE on the base scenario
  bool json = false;             // print soak.json instead of the summary
  bool quiet = false;            // no progress line
  std::string sched_fifo;        // real time: --sched-fifo all|emulator (LaunchOptions)
  bool allow_large = false;      // run a soak estimated at over 1 h of wall time or 4 GiB
};

/// `shoal soak`: one long shoal run whose phases step the campaign's axis values, judged
/// phase by phase and minute by minute (docs/campaigns.md). Exit 0 the verdict is pass;
/// 1 it is fail; 2 bad input (nothing ran); 130 interrupted (the part that ran is judged
/// and written).
int RunSoak(const SoakOptions& opt);

}  // namespace shoal
