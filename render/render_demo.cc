// render_demo: writes the four standard Shoal figures of a synthetic Example-2-like run
// (render/synthetic_run.h) as PNGs, off-screen, and prints where they are.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "render/figure.h"
#include "render/shoal_figures.h"
#include "render/synthetic_run.h"

namespace {

template <typename Figure>
bool Write(const std::string& path, const Figure& figure) {
  const auto t0 = std::chrono::steady_clock::now();
  std::string err;
  if (!shoal::render::RenderPng(figure, path, &err)) {
    std::fprintf(stderr, "render_demo: %s\n", err.c_str());
    return false;
  }
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::printf("  %s  (%d x %d, %.0f ms)\n", path.c_str(), figure.width_px, figure.height_px, ms);
  return true;
}

// The 2-D figures (states, errors on log and linear axes, channel) with their file names;
// width 0: default sizes.
std::vector<std::pair<std::string, shoal::render::Figure2D>> Figures2D(
    const shoal::render::SyntheticRun& run, const std::string& scenario, int width, int height) {
  using namespace shoal::render;
  const int w2 = width > 0 ? width : 1600, h2 = height > 0 ? height : 1000;
  std::vector<std::pair<std::string, Figure2D>> figures;
  figures.emplace_back("states.png", StateFigure(run.vehicles, scenario, w2, h2));
  ErrorOptions eo;
  eo.scenario = scenario;
  eo.log_y = true;
  eo.position_tol_m = 0.5;
  eo.velocity_tol_mps = 0.05;
  eo.converged_s = run.converged_s;
  eo.width_px = w2;
  eo.height_px = h2;
  figures.emplace_back("errors.png", ErrorFigure(run.errors, eo));
  eo.log_y = false;
  figures.emplace_back("errors_linear.png", ErrorFigure(run.errors, eo));
  ChannelOptions co;
  co.scenario = scenario;
  co.tau_t_s = run.tau_t_s;
  co.tau_s = run.tau_s;
  co.mode = "lockstep";  // the synthetic deliveries are tick-aligned
  co.control_period_s = 0.02;
  co.width_px = w2;
  co.height_px = height > 0 ? height : 0;
  figures.emplace_back("channel.png", ChannelFigure(run.links, co));
  return figures;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"render_demo: the standard Shoal figures of a synthetic run, rendered off-screen"};
  std::string out = "render_demo";
  double duration_s = 600.0;
  double drop = 0.02;
  double azimuth_deg = shoal::render::kAutoRange, elevation_deg = 22.0;
  app.add_option("--out", out, "Directory for the PNGs (created if missing)");
  app.add_option("--duration", duration_s, "Synthetic run length in seconds")
      ->check(CLI::Range(10.0, 36000.0));
  app.add_option("--drop", drop, "Drop probability per message")->check(CLI::Range(0.0, 1.0));
  std::string size;
  app.add_option("--size", size,
                 "Figure size WxH in pixels (default: 1400x1000 for 3-D, 1600x1000 for 2-D)");
  app.add_option("--azimuth", azimuth_deg,
                 "3-D camera bearing, degrees clockwise from north (default: automatic)");
  app.add_option("--elevation", elevation_deg, "3-D camera elevation, degrees")
      ->check(CLI::Range(-85.0, 85.0));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? 0 : 2;
  }
  int width = 0, height = 0;
  if (!size.empty()) {
    if (!shoal::render::ParseImageSize(size, &width, &height)) {
      std::fprintf(stderr, "render_demo: --size '%s' is not WxH (e.g. 1600x1000)\n", size.c_str());
      return 2;
    }
  }
  std::error_code ec;
  std::filesystem::create_directories(out, ec);
  if (ec) {
    std::fprintf(stderr, "render_demo: cannot create directory '%s': %s\n", out.c_str(),
                 ec.message().c_str());
    return 2;
  }
  using namespace shoal::render;
  const SyntheticRun run = MakeSyntheticRun(duration_s, 50.0, drop, 1);
  const std::string scenario = "synthetic paper_example2";

  TrajectoryOptions to;
  to.scenario = scenario;
  to.snapshot_times_s = {0.0, 30.0};
  for (double t = 100.0; t <= duration_s + 1e-9; t += 100.0) to.snapshot_times_s.push_back(t);
  if (width > 0) {
    to.width_px = width;
    to.height_px = height;
  }
  Figure3D traj = TrajectoryFigure(run.vehicles, to);
  traj.azimuth_deg = azimuth_deg;
  traj.elevation_deg = elevation_deg;

  const std::vector<std::pair<std::string, Figure2D>> figures =
      Figures2D(run, scenario, width, height);

  // Bad options (e.g. a size too small for a figure) are reported before anything is drawn.
  std::string err;
  bool valid = Validate(traj, &err);
  for (const auto& f : figures) valid = valid && Validate(f.second, &err);
  if (!valid) {
    std::fprintf(stderr, "render_demo: %s\n", err.c_str());
    return 2;
  }
  std::printf("render_demo: %.0f s of synthetic data at 50 Hz, figures:\n", duration_s);
  bool ok = Write(out + "/trajectories.png", traj);
  for (const auto& f : figures) ok = Write(out + "/" + f.first, f.second) && ok;
  return ok ? 0 : 1;
}
