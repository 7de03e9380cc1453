#include "render/shoal_figures.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

namespace shoal::render {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kPi = 3.14159265358979323846;

std::string Title(const std::string& scenario, const std::string& what) {
  return scenario.empty() ? what : scenario + " \xE2\x80\x94 " + what;  // em dash
}

std::vector<LegendEntry> VehicleLegend(const std::vector<int>& ids) {
  std::vector<LegendEntry> legend;
  for (int id : ids)
    legend.push_back({VehicleName(id), VehicleColor(id), LineStyle::kSolid, Marker::kNone, 2.5f});
  return legend;
}

void SetAxis(Axis* a, std::string label, std::string unit) {
  a->label = std::move(label);
  a->unit = std::move(unit);
}

float WidthFor(int id) { return id == 0 ? 2.2f : 1.6f; }

// Index of the sample nearest to t in a sorted time vector.
std::size_t Nearest(const std::vector<double>& t, double at) {
  auto it = std::lower_bound(t.begin(), t.end(), at);
  if (it == t.end()) return t.size() - 1;
  const auto i = static_cast<std::size_t>(it - t.begin());
  if (i > 0 && at - t[i - 1] < t[i] - at) return i - 1;
  return i;
}

std::string FormatSeconds(double t) {
  char buf[32];
  if (std::fabs(t - std::round(t)) < 1e-6) {
    std::snprintf(buf, sizeof buf, "t = %.0f s", t);
  } else {
    std::snprintf(buf, sizeof buf, "t = %.1f s", t);
  }
  return buf;
}

}  // namespace

Figure3D TrajectoryFigure(const std::vector<VehicleSeries>& vehicles, const TrajectoryOptions& o) {
  Figure3D f;
  f.width_px = o.width_px;
  f.height_px = o.height_px;
  f.title = Title(o.scenario, "trajectories and formation snapshots");
  std::vector<const VehicleSeries*> sorted;
  for (const VehicleSeries& v : vehicles) sorted.push_back(&v);
  std::sort(sorted.begin(), sorted.end(), [](auto* a, auto* b) { return a->id < b->id; });
  double t0 = INFINITY, t1 = -INFINITY;
  for (const VehicleSeries* v : sorted) {
    Polyline3D l;
    l.label = VehicleName(v->id);
    l.color = VehicleColor(v->id);
    l.line_width_px = v->id == 0 ? 2.8f : 2.2f;
    l.points.resize(v->t_s.size());
    for (std::size_t i = 0; i < v->t_s.size(); ++i) {
      l.points[i] = {v->eta[0][i], v->eta[1][i], v->eta[2][i]};
    }
    if (!v->t_s.empty()) {
      t0 = std::min(t0, v->t_s.front());
      t1 = std::max(t1, v->t_s.back());
    }
    f.lines.push_back(std::move(l));
  }
  std::vector<double> times = o.snapshot_times_s;
  if (times.empty() && t1 >= t0) {
    for (int k = 0; k < 6; ++k) times.push_back(t0 + (t1 - t0) * k / 5.0);
  }
  // A snapshot at a line's first or last sample already marks its start or end.
  for (std::size_t k = 0; k < sorted.size(); ++k) {
    const std::vector<double>& t = sorted[k]->t_s;
    if (t.empty()) continue;
    const double dt =
        t.size() > 1 ? (t.back() - t.front()) / static_cast<double>(t.size() - 1) : 0.0;
    for (double s : times) {
      if (std::fabs(s - t.front()) <= dt) f.lines[k].mark_start = false;
      if (std::fabs(s - t.back()) <= dt) f.lines[k].mark_end = false;
    }
  }
  std::vector<std::pair<int, int>> edges = o.snapshot_edges;
  if (edges.empty()) {
    for (const VehicleSeries* v : sorted) {
      if (v->id != 0) edges.push_back({0, v->id});
    }
  }
  for (double t : times) {
    Snapshot s;
    s.label = FormatSeconds(t);
    std::map<int, int> index_of;
    for (const VehicleSeries* v : sorted) {
      if (v->t_s.empty() || t < v->t_s.front() - 1e-9 || t > v->t_s.back() + 1e-9) continue;
      const std::size_t i = Nearest(v->t_s, t);
      index_of[v->id] = static_cast<int>(s.points.size());
      s.points.push_back({v->eta[0][i], v->eta[1][i], v->eta[2][i]});
      s.colors.push_back(VehicleColor(v->id));
    }
    if (s.points.empty()) continue;
    for (const auto& e : edges) {
      auto a = index_of.find(e.first), b = index_of.find(e.second);
      if (a != index_of.end() && b != index_of.end()) s.edges.push_back({a->second, b->second});
    }
    f.snapshots.push_back(std::move(s));
  }
  f.extra_legend.push_back({"formation snapshot", Color{0.3f, 0.3f, 0.3f, 1.0f}, LineStyle::kSolid,
                            Marker::kCircle, 1.5f});
  return f;
}

Figure2D StateFigure(const std::vector<VehicleSeries>& vehicles, const std::string& scenario,
                     int width_px, int height_px) {
  Figure2D f;
  f.width_px = width_px;
  f.height_px = height_px;
  f.title = Title(scenario, "states of all vehicles");
  f.columns = 2;
  f.link_x = true;
  static const char* const kEta[5] = {"x", "y", "z", "\xCE\xB8", "\xCF\x88"};  // θ ψ
  static const char* const kNu[5] = {"u", "v", "w", "q", "r"};
  static const char* const kEtaUnit[5] = {"m", "m", "m", "rad", "rad"};
  static const char* const kNuUnit[5] = {"m/s", "m/s", "m/s", "rad/s", "rad/s"};
  std::vector<const VehicleSeries*> sorted;
  for (const VehicleSeries& v : vehicles) sorted.push_back(&v);
  std::sort(sorted.begin(), sorted.end(), [](auto* a, auto* b) { return a->id < b->id; });
  // Followers first, the leader last, so that it is drawn on top.
  std::vector<const VehicleSeries*> order;
  for (const VehicleSeries* v : sorted) {
    if (v->id != 0) order.push_back(v);
  }
  for (const VehicleSeries* v : sorted) {
    if (v->id == 0) order.push_back(v);
  }
  std::vector<int> ids;
  for (const VehicleSeries* v : sorted) ids.push_back(v->id);
  f.legend = VehicleLegend(ids);
  for (int row = 0; row < 5; ++row) {
    for (int col = 0; col < 2; ++col) {
      Panel p;
      SetAxis(&p.x, "time", "s");
      SetAxis(&p.y, col == 0 ? kEta[row] : kNu[row], col == 0 ? kEtaUnit[row] : kNuUnit[row]);
      p.legend = LegendPlacement::kNone;
      for (const VehicleSeries* v : order) {
        Series s;
        s.x = v->t_s;
        s.y =
            col == 0 ? v->eta[static_cast<std::size_t>(row)] : v->nu[static_cast<std::size_t>(row)];
        if (col == 0 && row == 4) {
          // Heading wrapped to (-pi, pi], the line broken where it wraps.
          std::vector<double> x, y;
          x.reserve(s.x.size() + 16);
          y.reserve(s.y.size() + 16);
          double prev = kNaN;
          for (std::size_t i = 0; i < s.y.size(); ++i) {
            const double w = std::remainder(s.y[i], 2.0 * kPi);
            if (std::isfinite(prev) && std::fabs(w - prev) > kPi) {
              x.push_back(kNaN);
              y.push_back(kNaN);
            }
            x.push_back(s.x[i]);
            y.push_back(w);
            prev = w;
          }
          s.x = std::move(x);
          s.y = std::move(y);
        }
        s.color = VehicleColor(v->id);
        s.line_width_px = WidthFor(v->id);
        if (s.x.empty()) continue;
        p.series.push_back(std::move(s));
      }
      f.panels.push_back(std::move(p));
    }
  }
  return f;
}

Figure2D ErrorFigure(const std::vector<ErrorSeries>& followers, const ErrorOptions& o) {
  Figure2D f;
  f.width_px = o.width_px;
  f.height_px = o.height_px;
  f.title = Title(o.scenario, "tracking errors of the followers");
  f.columns = 1;
  f.link_x = true;
  std::vector<const ErrorSeries*> sorted;
  for (const ErrorSeries& e : followers) sorted.push_back(&e);
  std::sort(sorted.begin(), sorted.end(), [](auto* a, auto* b) { return a->id < b->id; });
  std::vector<int> ids;
  for (const ErrorSeries* e : sorted) ids.push_back(e->id);
  f.legend = VehicleLegend(ids);
  struct Which {
    const char* label;
    const char* unit;
    double tol;
  };
  const Which which[3] = {{"position error", "m", o.position_tol_m},
                          {"velocity error", "m/s", o.velocity_tol_mps},
                          {"attitude error", "rad", -1.0}};
  for (int k = 0; k < 3; ++k) {
    Panel p;
    SetAxis(&p.x, "time", "s");
    SetAxis(&p.y, which[k].label, which[k].unit);
    p.y.log = o.log_y;
    for (const ErrorSeries* e : sorted) {
      Series s;
      s.x = e->t_s;
      s.y = k == 0 ? e->position_m : k == 1 ? e->velocity_mps : e->attitude_rad;
      s.color = VehicleColor(e->id);
      s.line_width_px = 1.6f;
      if (s.x.empty()) continue;
      p.series.push_back(std::move(s));
    }
    if (which[k].tol > 0) {
      char buf[64];
      std::snprintf(buf, sizeof buf, "tolerance %g %s", which[k].tol, which[k].unit);
      p.hlines.push_back(
          {which[k].tol, Color{0.45f, 0.45f, 0.45f, 1.0f}, LineStyle::kDashed, 1.5f, buf});
    }
    if (o.converged_s >= 0) {
      char buf[64];
      std::snprintf(buf, sizeof buf, "converged at %.2f s", o.converged_s);
      p.vlines.push_back({o.converged_s, Color{0.1f, 0.1f, 0.1f, 1.0f}, LineStyle::kDotted, 1.8f,
                          k == 0 ? buf : ""});
    }
    f.panels.push_back(std::move(p));
  }
  return f;
}

Figure2D ChannelFigure(const std::vector<LinkSeries>& links, const ChannelOptions& o) {
  Figure2D f;
  f.width_px = o.width_px;
  f.height_px = o.height_px;
  f.title = Title(o.scenario, "channel: realised delays and drops");
  f.columns = 1;
  const bool have_tau = !o.tau_t_s.empty() && o.tau_t_s.size() == o.tau_s.size();
  // tau at t by linear interpolation; `hint` speeds up increasing t (send times).
  const auto tau_at = [&](double t, std::size_t* hint) {
    if (!have_tau) return kNaN;
    const std::vector<double>& T = o.tau_t_s;
    std::size_t i = *hint;
    if (i >= T.size() || T[i] > t) i = 0;
    if (i + 64 < T.size() && T[i + 64] < t) {
      i = static_cast<std::size_t>(std::lower_bound(T.begin(), T.end(), t) - T.begin());
      if (i > 0) --i;
    }
    while (i + 1 < T.size() && T[i + 1] <= t) ++i;
    *hint = i;
    if (t <= T.front()) return o.tau_s.front();
    if (i + 1 >= T.size()) return o.tau_s.back();
    const double a = T[i], b = T[i + 1];
    return o.tau_s[i] + (o.tau_s[i + 1] - o.tau_s[i]) * (t - a) / (b - a);
  };
  // Drop markers of dense links are translucent, so that bursts show as darker: alpha
  // such that the average number of drops per pixel column of a plot ~1500 px wide reaches
  // about half opacity. (The delay scatter stays opaque: single outliers must show.)
  const auto density_alpha = [](std::size_t points, float floor_alpha) {
    const double per_column = static_cast<double>(points) / 1500.0;
    if (per_column <= 1.0) return 1.0f;
    return std::max(floor_alpha, static_cast<float>(1.0 - std::pow(0.5, 1.0 / per_column)));
  };
  std::vector<const LinkSeries*> sorted;
  for (const LinkSeries& l : links) sorted.push_back(&l);
  std::sort(sorted.begin(), sorted.end(),
            [](auto* a, auto* b) { return a->to != b->to ? a->to < b->to : a->from < b->from; });
  double t_end = 0.0, t_start = INFINITY;
  for (const LinkSeries* l : sorted) {
    if (!l->sent_s.empty()) {
      t_end = std::max(t_end, l->sent_s.back());
      t_start = std::min(t_start, l->sent_s.front());
    }
    if (!l->dropped_s.empty()) {
      t_end = std::max(t_end, l->dropped_s.back());
      t_start = std::min(t_start, l->dropped_s.front());
    }
  }
  if (!std::isfinite(t_start)) t_start = 0.0;
  const double zoom_end = std::min(t_end, t_start + o.zoom_s);

  // Legend: one entry per receiving vehicle, then tau and drops.
  std::vector<int> receivers;
  for (const LinkSeries* l : sorted) {
    if (std::find(receivers.begin(), receivers.end(), l->to) == receivers.end())
      receivers.push_back(l->to);
  }
  for (int id : receivers) {
    f.legend.push_back(
        {"to " + VehicleName(id), VehicleColor(id), LineStyle::kNone, Marker::kCircle, 2.0f});
  }
  if (have_tau) {
    f.legend.push_back({"configured \xCF\x84(t)", Color{0.1f, 0.1f, 0.1f, 1.0f}, LineStyle::kDashed,
                        Marker::kNone, 1.8f});
  }
  f.legend.push_back(
      {"dropped", Color{0.1f, 0.1f, 0.1f, 1.0f}, LineStyle::kNone, Marker::kCross, 2.0f});

  // 1. Realised delay against tau over the first seconds.
  Panel zoom;
  char title[96];
  std::snprintf(title, sizeof title, "realised delay, first %.0f s", zoom_end - t_start);
  zoom.title = title;
  SetAxis(&zoom.x, "send time", "s");
  SetAxis(&zoom.y, "delay", "s");
  zoom.x.min = t_start;
  zoom.x.max = zoom_end > t_start ? zoom_end : t_start + 1.0;
  zoom.legend = LegendPlacement::kNone;
  Series drops_zoom;
  drops_zoom.line = LineStyle::kNone;
  drops_zoom.marker = Marker::kCross;
  drops_zoom.marker_size_px = 9.0f;
  drops_zoom.color = Color{0.1f, 0.1f, 0.1f, 1.0f};
  for (const LinkSeries* l : sorted) {
    Series s;
    s.line = LineStyle::kNone;
    s.marker = Marker::kCircle;
    s.marker_size_px = 5.0f;
    s.color = VehicleColor(l->to);
    for (std::size_t i = 0; i < l->sent_s.size() && l->sent_s[i] <= zoom_end; ++i) {
      s.x.push_back(l->sent_s[i]);
      s.y.push_back(l->delay_s[i]);
    }
    if (!s.x.empty()) zoom.series.push_back(std::move(s));
    std::size_t hint = 0;
    for (double t : l->dropped_s) {
      if (t > zoom_end) break;
      drops_zoom.x.push_back(t);
      drops_zoom.y.push_back(have_tau ? tau_at(t, &hint) : 0.0);
    }
  }
  if (have_tau) {
    Series tau;
    tau.color = Color{0.1f, 0.1f, 0.1f, 1.0f};
    tau.line = LineStyle::kDashed;
    tau.line_width_px = 1.8f;
    for (std::size_t i = 0; i < o.tau_t_s.size() && o.tau_t_s[i] <= zoom_end + 1.0; ++i) {
      tau.x.push_back(o.tau_t_s[i]);
      tau.y.push_back(o.tau_s[i]);
    }
    if (!tau.x.empty()) zoom.series.push_back(std::move(tau));
  }
  if (!drops_zoom.x.empty()) zoom.series.push_back(std::move(drops_zoom));
  f.panels.push_back(std::move(zoom));

  // 2. Realised minus configured delay (or the realised delay) over the whole run.
  Panel all;
  all.title = have_tau ? "realised minus configured delay, whole run" : "realised delay, whole run";
  SetAxis(&all.x, "send time", "s");
  SetAxis(&all.y, have_tau ? "delay \xE2\x88\x92 \xCF\x84" : "delay", "s");
  all.legend = LegendPlacement::kNone;
  for (const LinkSeries* l : sorted) {
    Series s;
    s.line = LineStyle::kNone;
    s.marker = Marker::kCircle;
    s.marker_size_px = 4.0f;
    s.color = VehicleColor(l->to);
    s.x = l->sent_s;
    s.y = l->delay_s;
    if (have_tau) {
      std::size_t hint = 0;
      for (std::size_t i = 0; i < s.x.size(); ++i) s.y[i] -= tau_at(s.x[i], &hint);
    }
    if (!s.x.empty()) all.series.push_back(std::move(s));
  }
  f.panels.push_back(std::move(all));

  // 3. Drops per link over time.
  Panel drops;
  drops.title = "dropped messages per link";
  SetAxis(&drops.x, "send time", "s");
  SetAxis(&drops.y, "link", "");
  drops.legend = LegendPlacement::kNone;
  for (std::size_t k = 0; k < sorted.size(); ++k) {
    const LinkSeries* l = sorted[k];
    const double row = static_cast<double>(sorted.size() - 1 - k);
    drops.y.ticks.push_back(
        {row, std::to_string(l->from) + " \xE2\x86\x92 " + std::to_string(l->to)});
    Series s;
    s.line = LineStyle::kNone;
    s.marker = Marker::kVBar;
    s.marker_size_px = 10.0f;
    s.color = VehicleColor(l->to);
    s.x = l->dropped_s;
    s.y.assign(s.x.size(), row);
    s.color.a = density_alpha(s.x.size(), 0.05f);
    if (!s.x.empty()) drops.series.push_back(std::move(s));
  }
  drops.x.min = t_start;
  drops.x.max = t_end > t_start ? t_end : t_start + 1.0;
  f.panels.push_back(std::move(drops));
  return f;
}

}  // namespace shoal::render
