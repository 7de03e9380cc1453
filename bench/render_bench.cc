// render_bench: time to draw all figures of a one-hour run of 6 vehicles at 50 Hz (the
// target for `shoal render`: <= 5 s), from synthetic data shaped like a real run
// (render/synthetic_run.h): 180,001 samples per series; 3-D trajectories, 10-panel
// states (60 series), tracking errors (15 series, log y) and the channel (10 links, about
// 1.76 million delivered messages and 36,000 drops).
//
//   build/bench/render_bench [runs] [out_dir]      (defaults: 5, a temporary directory)
//
// Prints each run's per-figure and total wall-clock times and the medians. The figures'
// construction from the arrays (copies, as the render command would make) is included;
// generating the synthetic data is not.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "render/shoal_figures.h"
#include "render/synthetic_run.h"

namespace {

using Clock = std::chrono::steady_clock;

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double Ms(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

// Draws the four figures into out, their times in t[] (ms). False with *err on failure.
bool RenderAll(const shoal::render::SyntheticRun& run, const std::string& out, double t[4],
               std::string* err) {
  using namespace shoal::render;
  auto a = Clock::now();
  TrajectoryOptions to;
  to.scenario = "bench";
  if (!RenderPng(TrajectoryFigure(run.vehicles, to), out + "/trajectories.png", err)) return false;
  auto b = Clock::now();
  t[0] = Ms(a, b);
  if (!RenderPng(StateFigure(run.vehicles, "bench"), out + "/states.png", err)) return false;
  a = Clock::now();
  t[1] = Ms(b, a);
  ErrorOptions eo;
  eo.scenario = "bench";
  eo.position_tol_m = 0.5;
  eo.velocity_tol_mps = 0.05;
  eo.converged_s = run.converged_s;
  if (!RenderPng(ErrorFigure(run.errors, eo), out + "/errors.png", err)) return false;
  b = Clock::now();
  t[2] = Ms(a, b);
  ChannelOptions co;
  co.scenario = "bench";
  co.tau_t_s = run.tau_t_s;
  co.tau_s = run.tau_s;
  co.mode = "lockstep";  // the synthetic deliveries are tick-aligned
  co.control_period_s = 0.02;
  if (!RenderPng(ChannelFigure(run.links, co), out + "/channel.png", err)) return false;
  a = Clock::now();
  t[3] = Ms(b, a);
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc > 1 && (std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h")) {
    std::printf(
        "usage: render_bench [runs] [out_dir]\n"
        "Renders all figures of a synthetic one-hour, 6-vehicle, 50 Hz run `runs` times\n"
        "(default 5) into out_dir (default: a temporary directory) and prints the\n"
        "median time.\n");
    return 0;
  }
  const int runs = argc > 1 ? std::atoi(argv[1]) : 5;
  if (runs < 1) {
    std::fprintf(stderr, "render_bench: runs must be a positive integer (got '%s')\n", argv[1]);
    return 2;
  }
  const std::string out =
      argc > 2 ? argv[2] : (std::filesystem::temp_directory_path() / "shoal_render_bench").string();
  std::error_code ec;
  std::filesystem::create_directories(out, ec);
  if (ec) {
    std::fprintf(stderr, "render_bench: cannot create '%s': %s\n", out.c_str(),
                 ec.message().c_str());
    return 2;
  }
  using namespace shoal::render;
  const auto g0 = Clock::now();
  const SyntheticRun run = MakeSyntheticRun(3600.0, 50.0, 0.02, 7);
  std::size_t delivered = 0, dropped = 0;
  for (const LinkSeries& l : run.links) {
    delivered += l.sent_s.size();
    dropped += l.dropped_s.size();
  }
  std::printf(
      "render_bench: %zu vehicles x %zu samples, %zu links (%zu delivered, %zu dropped); "
      "data generated in %.0f ms; output in %s\n",
      run.vehicles.size(), run.vehicles[0].t_s.size(), run.links.size(), delivered, dropped,
      Ms(g0, Clock::now()), out.c_str());

  const char* names[4] = {"trajectories", "states", "errors", "channel"};
  std::vector<double> per[4], total;
  for (int r = 0; r < runs; ++r) {
    double t[4] = {0, 0, 0, 0};
    std::string err;
    if (!RenderAll(run, out, t, &err)) {
      std::fprintf(stderr, "render_bench: %s\n", err.c_str());
      return 1;
    }
    const double sum = t[0] + t[1] + t[2] + t[3];
    std::printf(
        "run %d: trajectories %.0f ms, states %.0f ms, errors %.0f ms, channel %.0f ms, "
        "total %.0f ms\n",
        r + 1, t[0], t[1], t[2], t[3], sum);
    for (int k = 0; k < 4; ++k) per[k].push_back(t[k]);
    total.push_back(sum);
  }
  std::printf("median of %d runs:", runs);
  for (int k = 0; k < 4; ++k) std::printf(" %s %.0f ms,", names[k], Median(per[k]));
  std::printf(" total %.2f s (target <= 5 s)\n", Median(total) / 1000.0);
  return 0;
}
