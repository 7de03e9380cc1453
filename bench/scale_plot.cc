// scale_plot: the figure of bench/scale.sh against the number of followers, one line per
// mode (and per CSV: a second median CSV, e.g. the code before a change, is drawn dashed),
// in two panels, each with the +-20 % band around the fewest followers' value that the
// scaling target allows: the CPU per tick of one vehicle process, and the CPU per tick of
// all the run's processes that work per message (the vehicles, the channel emulator and
// lcm-logger) divided by the number of followers. Prints, per panel and mode, the dearest
// size's figure over the cheapest's.
//
//   build/bench/scale_plot MEDIAN_CSV OUT_PNG [BEFORE_MEDIAN_CSV]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "render/figure.h"

namespace {

using shoal::render::Series;

// What a panel plots of a median CSV row: one vehicle's CPU, or every role's per follower.
enum class Quantity { kVehicle, kPerFollower };

// mode -> (followers, CPU per tick in us), from a median CSV of bench/scale.sh.
std::map<std::string, std::vector<std::pair<double, double>>> ReadMedians(const std::string& path,
                                                                         Quantity q) {
  std::map<std::string, std::vector<std::pair<double, double>>> out;
  std::ifstream in(path);
  std::string line;
  std::vector<std::string> header;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) f.push_back(c);
    if (header.empty()) {
      header = f;
      continue;
    }
    std::map<std::string, std::string> row;
    for (std::size_t k = 0; k < f.size() && k < header.size(); ++k) row[header[k]] = f[k];
    const double n = std::atof(row["followers"].c_str());
    const double vehicle = std::atof(row["vehicle_cpu_us_per_tick"].c_str());
    const double others = std::atof(row["emulator_cpu_us_per_tick"].c_str()) +
                          std::atof(row["logger_cpu_us_per_tick"].c_str());
    const double cpu = q == Quantity::kVehicle ? vehicle : vehicle + others / n;
    if (n > 0 && vehicle > 0) out[row["mode"]].push_back({n, cpu});
  }
  // The band is drawn around the fewest followers, whatever order the sizes were run in.
  for (auto& [mode, points] : out) std::sort(points.begin(), points.end());
  return out;
}

void AddSeries(const std::string& path, const std::string& suffix, bool dashed, Quantity q,
               shoal::render::Panel* panel) {
  for (const auto& [mode, points] : ReadMedians(path, q)) {
    Series s;
    s.label = mode + suffix;
    double lo = INFINITY, hi = 0.0;
    for (const auto& [n, cpu] : points) {
      s.x.push_back(n);
      s.y.push_back(cpu);
      lo = std::min(lo, cpu);
      hi = std::max(hi, cpu);
    }
    s.color = shoal::render::Hex(mode == "lockstep" ? 0x1f77b4 : 0xd62728);
    s.line = dashed ? shoal::render::LineStyle::kDashed : shoal::render::LineStyle::kSolid;
    s.marker = dashed ? shoal::render::Marker::kRing : shoal::render::Marker::kCircle;
    if (!dashed && mode == "lockstep" && !points.empty()) {
      for (double f : {0.8, 1.2}) {
        shoal::render::RefLine r;
        r.value = points.front().second * f;
        r.label = f < 1 ? "lockstep at the fewest followers, ±20 %" : "";
        panel->hlines.push_back(r);
      }
    }
    if (!points.empty()) {
      std::printf("%s, %s%s: dearest / cheapest size %.2f\n", panel->title.c_str(),
                  mode.c_str(), suffix.c_str(), hi / lo);
    }
    panel->series.push_back(std::move(s));
  }
}

shoal::render::Panel MakePanel(Quantity q, char** argv, int argc) {
  shoal::render::Panel p;
  p.title = q == Quantity::kVehicle ? "one vehicle process" : "vehicles, emulator and logger";
  p.note = q == Quantity::kVehicle
               ? "two in-links per follower; medians of the runs"
               : "their CPU per tick divided by the followers: the run's cost per follower";
  p.x.label = "followers";
  p.x.log = true;
  p.y.label = q == Quantity::kVehicle ? "CPU per tick per vehicle" : "CPU per tick per follower";
  p.y.unit = "µs";
  p.y.min = 0;
  AddSeries(argv[1], "", false, q, &p);
  if (argc == 4) AddSeries(argv[3], " (before)", true, q, &p);
  return p;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3 || argc > 4) {
    std::fprintf(stderr, "usage: scale_plot MEDIAN_CSV OUT_PNG [BEFORE_MEDIAN_CSV]\n");
    return 2;
  }
  shoal::render::Figure2D fig;
  fig.width_px = 1200;
  fig.height_px = 1100;
  fig.title = "shoal run: CPU per tick against the swarm's size (bench/scale.sh)";
  for (Quantity q : {Quantity::kVehicle, Quantity::kPerFollower}) {
    shoal::render::Panel p = MakePanel(q, argv, argc);
    if (p.series.empty()) {
      std::fprintf(stderr, "scale_plot: no rows with vehicle_cpu_us_per_tick in %s\n", argv[1]);
      return 1;
    }
    fig.panels.push_back(std::move(p));
  }
  fig.link_x = true;
  std::string err;
  if (!shoal::render::RenderPng(fig, argv[2], &err)) {
    std::fprintf(stderr, "scale_plot: %s\n", err.c_str());
    return 1;
  }
  return 0;
}
