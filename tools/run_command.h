#pragma once

#include "launcher/launcher.h"

namespace shoal {

struct RunOptions {
  LaunchOptions launch;
  bool json = false;
  bool quiet = false;
  std::string restart = "no";  // "no" or "on-failure" (sets launch.restart_on_failure)
  std::string t0_clock = "monotonic";  // "monotonic" or "wall" (sets launch.wall_clock_t0)
  /// --print-launch: print a bash script that starts the run as shoal run would, instead
  /// of running it (docs/run.md, "Launching by hand or by script").
  bool print_launch = false;
  std::vector<std::string> command;  // shoal's command line, for the script's header
  std::string hosts_file;  // --hosts: read into launch.hosts (docs/run.md)
  /// --no-stagger: every real-time loop wakes at the start of its period. Otherwise a
  /// real-time run staggers its followers whenever its channel leaves room (launch.stagger
  /// is then set; given as --stagger, a scenario without room is an error).
  bool no_stagger = false;
};

/// `shoal run`: launches lcm-logger, the channel emulator, the leader and every vehicle
/// as separate processes, supervises them, and summarises the run from its log.
/// Exit 0 every process ran to the end and the formation converged; 1 a process failed
/// or the formation did not converge or diverged; 2 bad input; 130 interrupted
/// (docs/cli.md).
int RunRun(const RunOptions& opt);

}  // namespace shoal
