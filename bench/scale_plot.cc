// scale_plot: the figure of bench/scale.sh -- CPU per tick of one vehicle process against
// the number of followers, one line per mode (and per CSV: a second median CSV, e.g. the
// code before a change, is drawn dashed), with the +-20 % band around the 5-follower value
// that the scaling target allows.
//
//   build/bench/scale_plot MEDIAN_CSV OUT_PNG [BEFORE_MEDIAN_CSV]
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

// mode -> (followers, vehicle CPU per tick in us), from a median CSV of bench/scale.sh.
std::map<std::string, std::vector<std::pair<double, double>>> ReadMedians(const std::string& path) {
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
    const double cpu = std::atof(row["vehicle_cpu_us_per_tick"].c_str());
    if (n > 0 && cpu > 0) out[row["mode"]].push_back({n, cpu});
  }
  return out;
}

void AddSeries(const std::string& path, const std::string& suffix, bool dashed,
               shoal::render::Panel* panel) {
  for (const auto& [mode, points] : ReadMedians(path)) {
    Series s;
    s.label = mode + suffix;
    for (const auto& [n, cpu] : points) {
      s.x.push_back(n);
      s.y.push_back(cpu);
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
    panel->series.push_back(std::move(s));
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3 || argc > 4) {
    std::fprintf(stderr, "usage: scale_plot MEDIAN_CSV OUT_PNG [BEFORE_MEDIAN_CSV]\n");
    return 2;
  }
  shoal::render::Figure2D fig;
  fig.width_px = 1200;
  fig.height_px = 750;
  fig.title = "shoal run: CPU per tick of one vehicle process (bench/scale.sh)";
  shoal::render::Panel p;
  p.note = "two in-links per follower; medians of the runs";
  p.x.label = "followers";
  p.x.log = true;
  p.y.label = "CPU per tick per vehicle";
  p.y.unit = "µs";
  p.y.min = 0;
  AddSeries(argv[1], "", false, &p);
  if (argc == 4) AddSeries(argv[3], " (before)", true, &p);
  if (p.series.empty()) {
    std::fprintf(stderr, "scale_plot: no rows with vehicle_cpu_us_per_tick in %s\n", argv[1]);
    return 1;
  }
  fig.panels.push_back(std::move(p));
  std::string err;
  if (!shoal::render::RenderPng(fig, argv[2], &err)) {
    std::fprintf(stderr, "scale_plot: %s\n", err.c_str());
    return 1;
  }
  return 0;
}
