// shoal run --print-launch: a run's plan (launcher.h) as a plain bash script that starts
// the same processes with the same commands, without shoal run (docs/run.md, "Launching
// by hand or by script").
#pragma once

#include <string>
#include <vector>

#include "launcher/launcher.h"

namespace shoal {

struct LaunchScriptContext {
  std::string scenario_name;
  std::vector<std::string> command;  // the shoal run command line that printed it
  std::string working_dir;           // relative paths in the plan are relative to it
};

/// The script: makes the run's key (or runs --insecure), starts lcm-logger and waits for
/// its log, takes tick 0 on the wall clock 4 s ahead, starts the channel emulator, the
/// leader and the vehicles in the plan's order, stops everything it started on INT, TERM
/// or its exit, and after the emulator's end stops the others as shoal run does.
std::string LaunchScript(const LaunchPlan& plan, const LaunchScriptContext& ctx);

/// `word` as one bash word: as it is when it needs no quoting, else in single quotes. The
/// plan's placeholders (kT0Arg, kLoggerPidArg) become the script's variables.
std::string ShellWord(const std::string& word);

}  // namespace shoal
