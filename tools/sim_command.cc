#include "tools/sim_command.h"

#include <unistd.h>

#include <cstdio>
#include <iomanip>
#include <iostream>

#include "analysis/sim_report.h"
#include "analysis/verdict.h"
#include "core/swarm.h"
#include "runtime/stop_signals.h"
#include "scenario/loader.h"
#include "scenario/regular_file.h"
#include "tools/json_text.h"

namespace shoal {

int RunSim(const SimOptions& opt) {
  Scenario s;
  if (!LoadScenarioWithSetsOrReport("shoal sim", opt.scenario, opt.set, &s)) return kExitBadInput;
  if (opt.duration_s == 0 || (opt.duration_s < 0 && opt.duration_s != -1)) {
    std::cerr << "shoal sim: --duration must be a positive number of seconds (got "
              << opt.duration_s << ")\n";
    return kExitBadInput;
  }
  if (opt.duration_s > 0 && opt.duration_s * 1e6 < static_cast<double>(s.period_us())) {
    std::cerr << "shoal sim: --duration must be at least one control period, "
              << s.period_us() / 1e6 << " s (got " << std::setprecision(15) << opt.duration_s
              << ")\n";
    return kExitBadInput;
  }
  if (const std::string ticks = s.TickLimitRefusal(opt.duration_s); !ticks.empty()) {
    std::cerr << "shoal sim: --duration " << std::setprecision(15) << opt.duration_s
              << " is too long: " << ticks << "\n";
    return kExitBadInput;
  }
  if (!opt.out.empty() && SameFile(opt.out, opt.scenario)) {
    std::cerr << "shoal sim: --out " << opt.out
              << " is the scenario file: the log would overwrite it; write it elsewhere\n";
    return kExitBadInput;
  }
  if (!opt.allow_large) {
    const std::string refusal = LargeRunRefusal(s, opt.duration_s);
    if (!refusal.empty()) {
      std::cerr << "shoal sim: " << opt.scenario << ": " << refusal << "\n";
      return kExitBadInput;
    }
  }
  SimRunOptions run;
  run.out = opt.out;
  run.duration_s = opt.duration_s;
  run.show_progress = !opt.quiet && !opt.json && isatty(2);
  run.stop_requested = &StopSignals::Requested;
  SimReport report;
  std::string error;
  {
    const StopSignals signals;  // Ctrl-C ends the run at the current tick, with a summary
    if (!RunSimulation(s, run, &report, &error)) {
      std::cerr << "shoal sim: " << error << "\n";
      return kExitBadInput;
    }
  }
  // The log replaced one of shoal run's? Its key file belongs to that log (docs/run.md),
  // and would make every message of this one look forged.
  if (!opt.out.empty()) unlink((opt.out + ".key").c_str());
  if (!report.log_error.empty()) std::cerr << "shoal sim: " << report.log_error << "\n";
  if (opt.json) {
    std::cout << JsonText(SimReportJson(report)) << "\n";
  } else {
    PrintSimReport(report, stdout);
  }
  return SimExitStatus(report);
}

}  // namespace shoal
