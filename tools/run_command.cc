#include "tools/run_command.h"

#include <unistd.h>

#include <cstdio>
#include <iostream>

#include "analysis/verdict.h"
#include "launcher/launch_script.h"
#include "launcher/run_report.h"
#include "runtime/clocked_node.h"
#include "runtime/stop_signals.h"
#include "scenario/loader.h"
#include "tools/json_text.h"

namespace shoal {
namespace {

/// --print-launch: the script on stdout; nothing is started or written.
int PrintLaunch(const Scenario& s, const RunOptions& opt, const LaunchOptions& launch) {
  LaunchPlan plan;
  std::string error;
  if (!PlanLaunch(s, launch, &plan, &error)) {
    std::cerr << "shoal run: " << error << "\n";
    return kExitBadInput;
  }
  LaunchScriptContext ctx;
  ctx.scenario_name = s.name;
  ctx.command = opt.command;
  char cwd[4096];
  ctx.working_dir = getcwd(cwd, sizeof(cwd)) != nullptr ? cwd : ".";
  std::cout << LaunchScript(plan, ctx) << std::flush;
  return std::cout ? kExitOk : kExitFailed;
}

// --stagger, --no-stagger or neither: sets launch->stagger; false (said why) if --stagger
// cannot be.
bool ResolveStagger(const Scenario& s, const RunOptions& opt, LaunchOptions* launch) {
  const bool realtime = launch->mode == ModeName(Mode::kRealtime);
  if (launch->stagger && !realtime) {
    std::cerr << "shoal run: --stagger spreads the loops of a real-time run; lockstep has "
                 "none (add --mode realtime, or leave --stagger out)\n";
    return false;
  }
  const bool allowed = ClockedNode::StaggerPhaseUs(s, s.followers) > 0;
  if (launch->stagger && !allowed) {
    std::cerr << "shoal run: --stagger needs the channel's smallest delay to be above one "
                 "control period (a state must go out before it can be due); this "
                 "scenario's is not\n";
    return false;
  }
  // Staggering changes when a loop runs, not what its tick reads (only what reached the
  // host by the tick's time, runtime/clocked_node.h): the default wherever it is allowed.
  if (realtime && allowed && !opt.no_stagger) launch->stagger = true;
  return true;
}

}  // namespace

int RunRun(const RunOptions& opt) {
  Scenario s;
  if (!LoadScenarioWithSetsOrReport("shoal run", opt.launch.scenario, opt.launch.set, &s))
    return kExitBadInput;
  LaunchOptions launch_options = opt.launch;
  launch_options.restart_on_failure = opt.restart == "on-failure";
  launch_options.wall_clock_t0 = opt.t0_clock == "wall";
  if (!opt.hosts_file.empty()) {
    try {
      launch_options.hosts = LoadHostsFile(opt.hosts_file);
    } catch (const HostsFileError& e) {
      std::cerr << "shoal run: " << e.what() << "\n";
      return kExitBadInput;
    }
    const std::string misplaced = CheckPlacement(*launch_options.hosts, s.followers);
    if (!misplaced.empty()) {
      std::cerr << "shoal run: " << misplaced << "\n";
      return kExitBadInput;
    }
  }
  if (!ResolveStagger(s, opt, &launch_options)) return kExitBadInput;
  const bool stagger_allowed = ClockedNode::StaggerPhaseUs(s, s.followers) > 0;
  if (opt.print_launch) return PrintLaunch(s, opt, launch_options);
  const bool show = !opt.quiet && !opt.json && isatty(2);
  LaunchCallbacks cb;
  if (show) {
    cb.progress = [](const LaunchProgress& p) {
      std::fprintf(stderr,
                   "\r  t = %7.1f / %.0f s  (%.1fx real time)  worst position error %.2f m  "
                   "processes alive %d/%d   ",
                   p.sim_time_s, p.duration_s, p.realtime_factor, p.worst_position_error_m, p.alive,
                   p.processes);
    };
  }
  // On stderr as they happen, with --json too: its report goes to stdout at the end.
  cb.problem = [show](const std::string& problem, bool stops_run) {
    std::fprintf(stderr, "%sshoal run: %s%s\n", show ? "\n" : "", problem.c_str(),
                 stops_run ? "" : "; the others keep running (--keep-going)");
  };
  cb.restarted = [show](const std::string& what) {
    std::fprintf(stderr, "%sshoal run: %s\n", show ? "\n" : "", what.c_str());
  };
  LaunchResult launch;
  std::string error;
  if (!LaunchRun(s, launch_options, cb, &launch, &error)) {
    std::cerr << "shoal run: " << error << "\n";
    return kExitBadInput;
  }
  if (show) std::fprintf(stderr, "\r%110s\r", "");
  // The run's own handlers ended with it: a Ctrl-C while a long run's log is read for
  // the report waits for the report rather than killing the command before it prints.
  const StopSignals reporting;
  RunReport report = MakeRunReport(s, std::move(launch));
  LoopPlacement placement;
  placement.staggered = launch_options.stagger;
  placement.one_host = !launch_options.hosts.has_value();
  placement.stagger_allowed = stagger_allowed;
  placement.cpus = sysconf(_SC_NPROCESSORS_ONLN);
  for (const std::string& hint : {StaggerHint(report, placement), FifoHint(report, placement)}) {
    if (!hint.empty()) report.hints.push_back(hint);
  }
  if (opt.json) {
    std::cout << JsonText(RunReportJson(report)) << "\n";
  } else {
    PrintRunReport(report, stdout);
  }
  return RunExitStatus(report);
}

}  // namespace shoal
