#pragma once

#include <string>

namespace shoal {

struct RunOptions {
  std::string scenario;
  std::string mode = "lockstep";
  double duration_s = -1;
  std::string out;          // log path; default <scenario name>.lcmlog
  std::string lcm_url;      // default: a private udpm URL (random port, ttl=0)
  bool per_vehicle_urls = false;  // explicit; the default with the private URL anyway
  bool shared_url = false;        // everything on one group (vehicles hear all traffic)
  long long max_lookahead = 50;  // lockstep: most ticks the clock master releases at once
  bool deep_idle = false;  // do not hold the 0 us CPU latency request during the run
  bool json = false;
  bool quiet = false;
};

/// `shoal run`: launches lcm-logger, the channel emulator, the leader and every vehicle
/// as separate processes, supervises them, and summarises the run from its log.
/// Exit 0 only if every process ran to the end; 1 otherwise; 2 bad input; 130 on SIGINT.
int RunRun(const RunOptions& opt);

}  // namespace shoal
