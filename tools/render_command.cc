#include "tools/render_command.h"

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <map>
#include <utility>
#include <vector>

#include "analysis/analysis.h"
#include "analysis/run_data.h"
#include "core/channel_model.h"
#include "render/figure.h"
#include "render/shoal_figures.h"
#include "scenario/loader.h"

namespace shoal {
namespace {

const char* kWho = "shoal render: ";

bool ParseSize(const std::string& text, int* w, int* h) {
  int a = 0, b = 0;
  char x = 0, extra = 0;
  if (std::sscanf(text.c_str(), "%d%c%d%c", &a, &x, &b, &extra) != 3 || (x != 'x' && x != 'X')) {
    return false;
  }
  if (a < 320 || b < 240 || a > 8192 || b > 8192) return false;
  *w = a;
  *h = b;
  return true;
}

bool Finite(const FormationErrors& e) {
  return std::isfinite(e.position_m) && std::isfinite(e.velocity_mps) &&
         std::isfinite(e.attitude_rad);
}

}  // namespace

int RunRender(const RenderOptions& opt) {
  int w = 0, h = 0;
  if (!opt.size.empty() && !ParseSize(opt.size, &w, &h)) {
    std::cerr << kWho << "--size must be WxH in pixels, 320x240 to 8192x8192 (got '" << opt.size
              << "'), e.g. --size 1600x1000\n";
    return 2;
  }
  if (mkdir(opt.out_dir.c_str(), 0755) != 0 && errno != EEXIST) {
    std::cerr << kWho << opt.out_dir << ": cannot create the output directory ("
              << std::strerror(errno) << ")\n";
    return 2;
  }
  struct stat st {};
  if (stat(opt.out_dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) {
    std::cerr << kWho << opt.out_dir << ": exists and is not a directory; give --out a directory\n";
    return 2;
  }
  {  // Writable before anything is loaded or drawn.
    const std::string probe = opt.out_dir + "/.shoal_render_probe";
    FILE* f = std::fopen(probe.c_str(), "w");
    if (!f) {
      std::cerr << kWho << opt.out_dir << ": cannot write there (" << std::strerror(errno)
                << ")\n";
      return 2;
    }
    std::fclose(f);
    std::remove(probe.c_str());
  }
  Scenario scenario;
  LoadOptions lo;
  if (!opt.scenario.empty()) {
    if (!LoadScenarioOrReport("shoal render", opt.scenario, &scenario)) return 2;
    lo.scenario = &scenario;
  }
  const auto t0 = std::chrono::steady_clock::now();
  RunData run;
  std::string error;
  if (!LoadRunLog(opt.log, lo, &run, &error)) {
    std::cerr << kWho << error << "\n";
    return 2;
  }
  for (const std::string& warn : run.warnings) std::cerr << kWho << "warning: " << warn << "\n";
  const RunAnalysis a = AnalyseRun(run);
  const std::string name = run.scenario_name.empty() ? "run" : run.scenario_name;

  // Vehicles (leader first).
  std::vector<render::VehicleSeries> vehicles;
  for (const VehicleTrack& track : run.vehicles) {
    if (track.samples.empty()) continue;
    render::VehicleSeries v;
    v.id = track.id;
    const std::size_t n = track.samples.size();
    v.t_s.reserve(n);
    for (auto& c : v.eta) c.reserve(n);
    for (auto& c : v.nu) c.reserve(n);
    for (const StateMsg& m : track.samples) {
      v.t_s.push_back(ToSeconds(m.utime));
      for (int k = 0; k < 5; ++k) {
        v.eta[k].push_back(m.eta(k));
        v.nu[k].push_back(m.nu(k));
      }
    }
    vehicles.push_back(std::move(v));
  }
  if (vehicles.empty()) {
    std::cerr << kWho << opt.log << ": no vehicle states to draw\n";
    return 2;
  }

  std::vector<std::string> written;
  int failures = 0;
  auto emit = [&](bool ok, const std::string& path, const std::string& err) {
    if (ok) {
      written.push_back(path);
    } else {
      ++failures;
      std::cerr << kWho << path << ": " << err << "\n";
    }
  };
  std::string err;

  // 1. 3-D trajectories with formation snapshots along the topology's links.
  {
    render::TrajectoryOptions o;
    o.scenario = name;
    if (run.has_scenario) {
      const Topology topo = Topology::Build(run.scenario.followers, run.scenario.edges,
                                            run.scenario.leader_links);
      for (const auto& [from, to] : topo.Links()) {
        const auto e = std::make_pair(std::min(from, to), std::max(from, to));
        if (std::find(o.snapshot_edges.begin(), o.snapshot_edges.end(), e) == o.snapshot_edges.end()) {
          o.snapshot_edges.push_back(e);
        }
      }
    }
    if (w > 0) {
      o.width_px = w;
      o.height_px = h;
    }
    const std::string path = opt.out_dir + "/trajectory.png";
    emit(render::RenderPng(render::TrajectoryFigure(vehicles, o), path, &err), path, err);
  }
  // 2. States over time.
  {
    const std::string path = opt.out_dir + "/states.png";
    const render::Figure2D f =
        w > 0 ? render::StateFigure(vehicles, name, w, h) : render::StateFigure(vehicles, name);
    emit(render::RenderPng(f, path, &err), path, err);
  }
  // 3. Tracking errors (needs the scenario's offsets and the leader).
  if (a.has_formation) {
    std::vector<render::ErrorSeries> errors;
    for (const FollowerAnalysis& fa : a.followers) {
      if (fa.id <= 0 || fa.id >= static_cast<int>(run.vehicles.size())) continue;
      const VehicleTrack& track = run.vehicles[fa.id];
      render::ErrorSeries e;
      e.id = fa.id;
      for (std::size_t k = 0; k < fa.errors.size() && k < track.samples.size(); ++k) {
        if (!Finite(fa.errors[k])) continue;
        e.t_s.push_back(ToSeconds(track.samples[k].utime));
        e.position_m.push_back(fa.errors[k].position_m);
        e.velocity_mps.push_back(fa.errors[k].velocity_mps);
        e.attitude_rad.push_back(fa.errors[k].attitude_rad);
      }
      if (!e.t_s.empty()) errors.push_back(std::move(e));
    }
    render::ErrorOptions o;
    o.scenario = name;
    o.log_y = !opt.linear_errors;
    o.position_tol_m = run.scenario.metrics.position_tol_m;
    o.velocity_tol_mps = run.scenario.metrics.velocity_tol_mps;
    o.converged_s = a.summary.converged ? a.summary.convergence_time_s : -1.0;
    if (w > 0) {
      o.width_px = w;
      o.height_px = h;
    }
    const std::string path = opt.out_dir + "/errors.png";
    if (errors.empty()) {
      std::cerr << kWho << "no follower has a leader state at the same time: errors.png skipped\n";
    } else {
      emit(render::RenderPng(render::ErrorFigure(errors, o), path, &err), path, err);
    }
  } else {
    std::cerr << kWho << "no scenario (offsets) or no leader states in the log: errors.png "
                         "skipped (give --scenario FILE)\n";
  }
  // 4. The channel: realised delay against tau(t), drops, per link.
  if (!run.channel_events.empty()) {
    std::map<std::pair<int, int>, render::LinkSeries> links;
    for (const ChannelEventRecord& e : run.channel_events) {
      render::LinkSeries& l = links[{e.sender, e.receiver}];
      l.from = e.sender;
      l.to = e.receiver;
      if (e.status == 0) {
        l.sent_s.push_back(ToSeconds(e.send_utime));
        l.delay_s.push_back(ToSeconds(e.deliver_utime - e.send_utime));
      } else {
        l.dropped_s.push_back(ToSeconds(e.send_utime));
      }
    }
    std::vector<render::LinkSeries> list;
    for (auto& [key, l] : links) list.push_back(std::move(l));
    render::ChannelOptions o;
    o.scenario = name;
    if (run.has_scenario) {  // the configured (default) link delay, every 10 ms
      const double end = ToSeconds(run.channel_events.back().send_utime);
      for (double t = 0.0; t <= end + 1e-9; t += 0.01) {
        o.tau_t_s.push_back(t);
        o.tau_s.push_back(NominalDelaySeconds(run.scenario.delay, t));
      }
    }
    if (w > 0) {
      o.width_px = w;
      o.height_px = h;
    }
    const std::string path = opt.out_dir + "/channel.png";
    emit(render::RenderPng(render::ChannelFigure(list, o), path, &err), path, err);
  } else {
    std::cerr << kWho << "no SHOAL_CHANNEL events in the log: channel.png skipped\n";
  }

  const double secs =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!opt.quiet) {
    std::printf("shoal render: %zu figure(s) of %s in %.2f s\n", written.size(), name.c_str(), secs);
    for (const std::string& p : written) std::printf("  %s\n", p.c_str());
  }
  return failures == 0 ? 0 : 1;
}

}  // namespace shoal
