#include "tools/render_command.h"

#include <chrono>
#include <cstdio>
#include <iostream>

#include "analysis/analysis.h"
#include "analysis/run_data.h"
#include "render/figure.h"
#include "render/run_figures.h"
#include "scenario/loader.h"

namespace shoal {
namespace {

const char* kWho = "shoal render: ";

bool ParseSize(const std::string& text, int* w, int* h) {
  int a = 0, b = 0;
  if (!render::ParseImageSize(text, &a, &b)) return false;
  if (a < 320 || b < 240 || a > 8192 || b > 8192) return false;
  *w = a;
  *h = b;
  return true;
}

}  // namespace

int RunRender(const RenderOptions& opt) {
  render::RunFigureOptions fo;
  fo.linear_errors = opt.linear_errors;
  if (!opt.size.empty() && !ParseSize(opt.size, &fo.width_px, &fo.height_px)) {
    std::cerr << kWho << "--size must be WxH in pixels, 320x240 to 8192x8192 (got '" << opt.size
              << "'), e.g. --size 1600x1000\n";
    return 2;
  }
  std::string error;
  if (!render::PrepareOutputDir(opt.out_dir, &error)) {
    std::cerr << kWho << error << "\n";
    return 2;
  }
  Scenario scenario;
  LoadOptions lo;
  if (!opt.scenario.empty()) {
    if (!LoadScenarioOrReport("shoal render", opt.scenario, &scenario)) return 2;
    lo.scenario = &scenario;
  }
  lo.key_file = opt.key_file;
  const auto t0 = std::chrono::steady_clock::now();
  RunData run;
  if (!LoadRunLog(opt.log, lo, &run, &error)) {
    std::cerr << kWho << error << "\n";
    return 2;
  }
  // A state at a damaged time would stretch every time axis to it (9e12 s for INT64_MAX).
  DropImpossibleTimes(&run);
  for (const std::string& warn : run.warnings) std::cerr << kWho << "warning: " << warn << "\n";
  render::RunFigureReport report;
  if (!render::WriteRunFigures(run, opt.out_dir, fo, &report, &error)) {
    std::cerr << kWho << error << "\n";
    return 2;
  }
  for (const std::string& s : report.skipped) std::cerr << kWho << s << "\n";
  for (const std::string& f : report.failures) std::cerr << kWho << f << "\n";
  const double secs =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!opt.quiet) {
    std::printf("shoal render: %zu figure(s) of %s in %.2f s\n", report.written.size(),
                run.scenario_name.empty() ? "run" : run.scenario_name.c_str(), secs);
    for (const std::string& p : report.written) std::printf("  %s\n", p.c_str());
  }
  return report.failures.empty() ? 0 : 1;
}

}  // namespace shoal
