#include "render/shoal_figures.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <set>
#include <tuple>

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
  const Color grey{0.3f, 0.3f, 0.3f, 1.0f};
  f.extra_legend.push_back({"formation snapshot", grey, LineStyle::kSolid, Marker::kCircle, 1.5f});
  f.extra_legend.push_back({"start", grey, LineStyle::kNone, Marker::kRing, 1.5f});
  f.extra_legend.push_back({"end", grey, LineStyle::kNone, Marker::kSquare, 1.5f});
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
  // z is drawn growing downwards, as in the 3-D figure (NED: z is positive down).
  static const char* const kEta[5] = {"x (north)", "y (east)", "z (down)", "\xCE\xB8",
                                      "\xCF\x88"};  // θ ψ
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
      p.y.reversed = col == 0 && row == 2;
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
    for (const EventWindow& w : o.events) {
      p.bands.push_back({w.t0_s, w.t1_s, kAutoRange, kAutoRange, Hex(0xE69F00, 0.16f),
                         k == 0 ? w.label : ""});
    }
    f.panels.push_back(std::move(p));
  }
  return f;
}

namespace {

const Color kInk{0.1f, 0.1f, 0.1f, 1.0f};

// tau(t) by linear interpolation in the caller's samples; `hint` speeds up increasing t
// (send times).
class TauCurve {
 public:
  explicit TauCurve(const ChannelOptions& o) : t_(o.tau_t_s), tau_(o.tau_s) {}
  bool valid() const { return !t_.empty() && t_.size() == tau_.size(); }
  double At(double t, std::size_t* hint) const {
    if (!valid()) return kNaN;
    std::size_t i = *hint;
    if (i >= t_.size() || t_[i] > t) i = 0;
    if (i + 64 < t_.size() && t_[i + 64] < t) {
      i = static_cast<std::size_t>(std::lower_bound(t_.begin(), t_.end(), t) - t_.begin());
      if (i > 0) --i;
    }
    while (i + 1 < t_.size() && t_[i + 1] <= t) ++i;
    *hint = i;
    if (t <= t_.front()) return tau_.front();
    if (i + 1 >= t_.size()) return tau_.back();
    const double a = t_[i], b = t_[i + 1];
    return tau_[i] + (tau_[i + 1] - tau_[i]) * (t - a) / (b - a);
  }

 private:
  const std::vector<double>& t_;
  const std::vector<double>& tau_;
};

// Drop markers of dense links are translucent, so that bursts show as darker: alpha such
// that the average number of drops per pixel column of a plot ~1500 px wide reaches about
// half opacity. (The delay scatter stays opaque: single outliers must show.)
float DensityAlpha(std::size_t points, float floor_alpha) {
  const double per_column = static_cast<double>(points) / 1500.0;
  if (per_column <= 1.0) return 1.0f;
  return std::max(floor_alpha, static_cast<float>(1.0 - std::pow(0.5, 1.0 / per_column)));
}

std::string LinkName(const LinkSeries& l) {
  if (l.to < 0) return "all links";
  const std::string from = l.from < 0 ? "all" : std::to_string(l.from);
  return from + " \xE2\x86\x92 " + std::to_string(l.to);  // →
}

// At most this many rows in the per-link panels. Beyond it a figure of a row per link
// grows past any image size (400 densely linked followers: 160,000 links, 10^7 px) and
// says nothing a reader can see; links are then grouped by receiver, or all into one row.
constexpr std::size_t kMaxLinkRows = 48;

// `links` (sorted by receiver) as at most kMaxLinkRows rows: unchanged if they fit, else
// one series per receiver (from = -1), else one for all (from = to = -1); each merged
// series in time order, as the panels read them.
std::vector<LinkSeries> GroupLinks(const std::vector<const LinkSeries*>& links) {
  std::set<int> receivers;
  for (const LinkSeries* l : links) receivers.insert(l->to);
  const bool by_receiver = receivers.size() <= kMaxLinkRows;
  std::map<int, std::vector<const LinkSeries*>> groups;
  for (const LinkSeries* l : links) groups[by_receiver ? l->to : -1].push_back(l);
  std::vector<LinkSeries> out;
  for (const auto& [to, members] : groups) {
    LinkSeries g;
    g.from = -1;
    g.to = to;
    std::vector<std::array<double, 3>> sent;  // send time, delay, model delay (NaN: none)
    bool model = true;
    for (const LinkSeries* l : members) {
      model = model && l->model_delay_s.size() == l->delay_s.size();
      for (std::size_t i = 0; i < l->sent_s.size(); ++i) {
        sent.push_back({l->sent_s[i], l->delay_s[i],
                        i < l->model_delay_s.size() ? l->model_delay_s[i] : NAN});
      }
      g.dropped_s.insert(g.dropped_s.end(), l->dropped_s.begin(), l->dropped_s.end());
    }
    std::stable_sort(sent.begin(), sent.end(),
                     [](const auto& a, const auto& b) { return a[0] < b[0]; });
    std::sort(g.dropped_s.begin(), g.dropped_s.end());
    for (const auto& [t, d, m] : sent) {
      g.sent_s.push_back(t);
      g.delay_s.push_back(d);
      if (model) g.model_delay_s.push_back(m);
    }
    out.push_back(std::move(g));
  }
  return out;
}

// Row of link k (of n) in the per-link panels: the first link at the top.
double LinkRow(std::size_t k, std::size_t n) { return static_cast<double>(n - 1 - k); }

std::vector<Tick> LinkTicks(const std::vector<const LinkSeries*>& links) {
  std::vector<Tick> ticks;
  for (std::size_t k = 0; k < links.size(); ++k)
    ticks.push_back({LinkRow(k, links.size()), LinkName(*links[k])});
  return ticks;
}

// 1. Realised delay of every link against tau over the first seconds. All links share
// one colour: in tick-aligned runs their points coincide, so per-link colours would only
// show the last link drawn; the per-link view is the next panel.
Panel ZoomPanel(const std::vector<const LinkSeries*>& links, const ChannelOptions& o,
                const TauCurve& tau, double t_start, double zoom_end) {
  Panel zoom;
  char title[96];
  std::snprintf(title, sizeof title, "realised delay of every link, first %.0f s",
                zoom_end - t_start);
  zoom.title = title;
  SetAxis(&zoom.x, "send time", "s");
  SetAxis(&zoom.y, "delay", "s");
  zoom.x.min = t_start;
  zoom.x.max = zoom_end > t_start ? zoom_end : t_start + 1.0;
  zoom.legend = LegendPlacement::kNone;
  Series delivered, drops;
  delivered.line = drops.line = LineStyle::kNone;
  delivered.marker = Marker::kCircle;
  delivered.marker_size_px = 5.0f;
  delivered.color = Hex(0x0072B2);
  drops.marker = Marker::kCross;
  drops.marker_size_px = 9.0f;
  drops.color = kInk;
  for (const LinkSeries* l : links) {
    for (std::size_t i = 0; i < l->sent_s.size() && l->sent_s[i] <= zoom_end; ++i) {
      delivered.x.push_back(l->sent_s[i]);
      delivered.y.push_back(l->delay_s[i]);
    }
    std::size_t hint = 0;
    for (double t : l->dropped_s) {
      if (t > zoom_end) break;
      drops.x.push_back(t);
      drops.y.push_back(tau.valid() ? tau.At(t, &hint) : 0.0);
    }
  }
  if (!delivered.x.empty()) zoom.series.push_back(std::move(delivered));
  if (tau.valid()) {
    Series curve;
    curve.color = kInk;
    curve.line = LineStyle::kDashed;
    curve.line_width_px = 1.8f;
    for (std::size_t i = 0; i < o.tau_t_s.size() && o.tau_t_s[i] <= zoom_end + 1.0; ++i) {
      curve.x.push_back(o.tau_t_s[i]);
      curve.y.push_back(o.tau_s[i]);
    }
    if (!curve.x.empty()) zoom.series.push_back(std::move(curve));
  }
  if (!drops.x.empty()) zoom.series.push_back(std::move(drops));
  return zoom;
}

// What realised minus configured delay means in this run's mode. A real-time log stamps
// each delivery with its scheduled release (send + round(tau)), so there the difference is
// only that rounding: how late the emulator really released is in its health, not here.
std::string DelayErrorNote(const ChannelOptions& o) {
  char period[48] = "one control period)";
  if (o.control_period_s > 0) {
    std::snprintf(period, sizeof period, "%g ms), one control period", o.control_period_s * 1e3);
  }
  const std::string quantised = std::string("deliveries wait for the next control tick, so ") +
                                "delay \xE2\x88\x92 \xCF\x84 lies in [0, " + period;
  std::string scheduled = "deliveries are logged at their scheduled release, so delay \xE2\x88\x92 "
                          "\xCF\x84 is its rounding (\xC2\xB1" "0.5 \xC2\xB5s)";
  if (o.mode == "sim" || o.mode == "lockstep") return o.mode + " run: " + quantised;
  if (o.mode == "realtime") {
    std::string note = "real-time run: " + scheduled;
    if (std::isfinite(o.release_error_p99_s)) {
      char late[96];
      std::snprintf(late, sizeof late, "; the emulator's release error (how late it really released) p99 %.3g ms",
                    o.release_error_p99_s * 1e3);
      note += late;
    }
    return note;
  }
  return "sim and lockstep runs: " + quantised + "; real-time runs: " + scheduled;
}

// Summary of one link's values: min, 5th, 50th, 95th percentile, max.
std::array<double, 5> Quantiles(std::vector<double> v) {
  std::array<double, 5> q{};
  const double at[5] = {0.0, 0.05, 0.5, 0.95, 1.0};
  for (int k = 0; k < 5; ++k) {
    const auto i = static_cast<std::size_t>(std::lround(at[k] * static_cast<double>(v.size() - 1)));
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(i), v.end());
    q[static_cast<std::size_t>(k)] = v[i];
  }
  return q;
}

// 2. Realised minus configured delay per link over the whole run, one row per link: the
// range as a thin line, the middle 90 % as a thick bar, the median as a black tick.
Panel DelayErrorPanel(const std::vector<const LinkSeries*>& links, const ChannelOptions& o,
                      const TauCurve& tau) {
  // The reference: each message's drawn delay where the links know it, else tau(t).
  bool have_ref = tau.valid();
  if (!have_ref) {
    have_ref = true;
    for (const LinkSeries* l : links)
      have_ref = have_ref && l->model_delay_s.size() == l->delay_s.size();
  }
  Panel p;
  p.title = have_ref ? "realised minus configured delay per link, whole run"
                        : "realised delay per link, whole run";
  p.note = (have_ref ? DelayErrorNote(o) + ". " : std::string()) +
           "Thin line: min to max; bar: 5 to 95 %; black tick: median.";
  SetAxis(&p.x, have_ref ? "delay \xE2\x88\x92 \xCF\x84" : "delay", "ms");
  SetAxis(&p.y, "link", "");
  p.y.ticks = LinkTicks(links);
  p.legend = LegendPlacement::kNone;
  Series medians;
  medians.line = LineStyle::kNone;
  medians.marker = Marker::kVBar;
  medians.marker_size_px = 14.0f;
  medians.color = kInk;
  for (std::size_t k = 0; k < links.size(); ++k) {
    const LinkSeries& l = *links[k];
    if (l.sent_s.empty()) continue;
    std::vector<double> d(l.delay_s);
    std::size_t hint = 0;
    const bool drawn = l.model_delay_s.size() == d.size();
    for (std::size_t i = 0; i < d.size(); ++i) {
      const double ref = drawn ? l.model_delay_s[i] : tau.At(l.sent_s[i], &hint);
      d[i] = 1e3 * (have_ref ? d[i] - ref : d[i]);
    }
    const std::array<double, 5> q = Quantiles(std::move(d));
    const double row = LinkRow(k, links.size());
    Series range, bar;
    range.color = bar.color = VehicleColor(l.to);
    range.line_width_px = 1.5f;
    range.x = {q[0], q[4]};
    range.y = {row, row};
    bar.line_width_px = 8.0f;
    bar.x = {q[1], q[3]};
    bar.y = {row, row};
    p.series.push_back(std::move(range));
    p.series.push_back(std::move(bar));
    medians.x.push_back(q[2]);
    medians.y.push_back(row);
  }
  if (!medians.x.empty()) p.series.push_back(std::move(medians));
  if (have_ref && o.control_period_s > 0 && o.mode != "realtime") {
    for (double v : {0.0, 1e3 * o.control_period_s})
      p.vlines.push_back({v, Color{0.45f, 0.45f, 0.45f, 1.0f}, LineStyle::kDashed, 1.2f, ""});
  }
  return p;
}

// Whether an outage of link (from, to) concerns row l: the link itself, its receiver's
// group (from -1) or the one row of every link (to < 0).
bool OutageOnRow(const LinkOutage& out, const LinkSeries& l) {
  if (l.to < 0) return true;
  return l.to == out.to && (l.from == out.from || l.from < 0);
}

// The outages as bands on their rows, each row's band labelled once.
void AddOutageBands(const std::vector<const LinkSeries*>& links,
                    const std::vector<LinkOutage>& outages, Panel* p) {
  std::set<std::tuple<std::size_t, double, double>> drawn;  // grouped rows: once per window
  for (const LinkOutage& out : outages) {
    for (std::size_t k = 0; k < links.size(); ++k) {
      if (!OutageOnRow(out, *links[k]) || !drawn.insert({k, out.t0_s, out.t1_s}).second) continue;
      const double row = LinkRow(k, links.size());
      p->bands.push_back({out.t0_s, out.t1_s, row - 0.45, row + 0.45, Hex(0xD55E00, 0.22f),
                          out.label});
    }
  }
}

// 3. Drops per link over time, rows as in panel 2; outages shaded on their rows.
Panel DropPanel(const std::vector<const LinkSeries*>& links, const std::vector<LinkOutage>& outages,
                double t_start, double t_end) {
  Panel drops;
  drops.title = "dropped messages per link";
  SetAxis(&drops.x, "send time", "s");
  SetAxis(&drops.y, "link", "");
  drops.y.ticks = LinkTicks(links);
  drops.legend = LegendPlacement::kNone;
  for (std::size_t k = 0; k < links.size(); ++k) {
    const LinkSeries* l = links[k];
    Series s;
    s.line = LineStyle::kNone;
    s.marker = Marker::kVBar;
    s.marker_size_px = 10.0f;
    s.color = VehicleColor(l->to);
    s.x = l->dropped_s;
    s.y.assign(s.x.size(), LinkRow(k, links.size()));
    s.color.a = DensityAlpha(s.x.size(), 0.05f);
    if (!s.x.empty()) drops.series.push_back(std::move(s));
  }
  if (drops.series.empty()) drops.note = "no message was dropped";
  AddOutageBands(links, outages, &drops);
  if (!outages.empty()) {
    drops.note += std::string(drops.note.empty() ? "" : "; ") +
                  "shaded: outages of the scenario's timeline (link down, silent sender, deaf "
                  "receiver: by due time, drops by send time)";
  }
  drops.x.min = t_start;
  drops.x.max = t_end > t_start ? t_end : t_start + 1.0;
  return drops;
}

}  // namespace

Figure2D ChannelFigure(const std::vector<LinkSeries>& links, const ChannelOptions& o) {
  std::vector<const LinkSeries*> sorted;
  for (const LinkSeries& l : links) sorted.push_back(&l);
  std::sort(sorted.begin(), sorted.end(),
            [](auto* a, auto* b) { return a->to != b->to ? a->to < b->to : a->from < b->from; });
  std::vector<LinkSeries> grouped;
  if (sorted.size() > kMaxLinkRows) {
    grouped = GroupLinks(sorted);
    sorted.clear();
    for (const LinkSeries& l : grouped) sorted.push_back(&l);
  }
  double t_end = 0.0, t_start = INFINITY;
  for (const LinkSeries* l : sorted) {
    for (const std::vector<double>* v : {&l->sent_s, &l->dropped_s}) {
      if (v->empty()) continue;
      t_end = std::max(t_end, v->back());
      t_start = std::min(t_start, v->front());
    }
  }
  if (!std::isfinite(t_start)) t_start = 0.0;
  const TauCurve tau(o);

  Figure2D f;
  f.width_px = o.width_px;
  f.height_px = o.height_px;
  if (f.height_px <= 0) {
    // Two panels have a row per link: about 22 px per row at scale 1, the text kept at
    // the scale of a 1000 px high figure.
    const int rows = static_cast<int>(sorted.size());
    f.height_px = std::max(1000, 3 * (22 * rows + 90) + 110);
    f.scale = std::clamp(static_cast<float>(f.width_px) / 1600.0f, 0.75f, 3.0f);
  }
  f.title = Title(o.scenario, grouped.empty() ? "channel: realised delays and drops"
                                               : "channel: realised delays and drops (" +
                                                     std::to_string(links.size()) +
                                                     " links, grouped by receiver)");
  if (!grouped.empty() && grouped.front().to < 0) {
    f.title = Title(o.scenario, "channel: realised delays and drops (" +
                                    std::to_string(links.size()) + " links, in one row)");
  }
  f.columns = 1;
  std::vector<int> receivers;
  for (const LinkSeries* l : sorted) {
    if (std::find(receivers.begin(), receivers.end(), l->to) == receivers.end())
      receivers.push_back(l->to);
  }
  f.legend.push_back({"delivered", Hex(0x0072B2), LineStyle::kNone, Marker::kCircle, 2.0f});
  if (tau.valid())
    f.legend.push_back({"configured \xCF\x84(t)", kInk, LineStyle::kDashed, Marker::kNone, 1.8f});
  f.legend.push_back({"dropped", kInk, LineStyle::kNone, Marker::kCross, 2.0f});
  for (int id : receivers) {
    if (id < 0) continue;  // every link in one row: no receiver to name
    f.legend.push_back({"to " + VehicleName(id), VehicleColor(id), LineStyle::kSolid,
                        Marker::kNone, 6.0f});
  }
  f.panels.push_back(
      ZoomPanel(sorted, o, tau, t_start, std::min(t_end, t_start + o.zoom_s)));
  f.panels.push_back(DelayErrorPanel(sorted, o, tau));
  f.panels.push_back(DropPanel(sorted, o.outages, t_start, t_end));
  return f;
}

}  // namespace shoal::render

namespace shoal::render {
namespace {

std::string Fmt(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

}  // namespace

Figure2D AcousticDelayFigure(const AcousticPoints& points,
                             const std::vector<AcousticModelLine>& models,
                             const AcousticOptions& o) {
  Figure2D f;
  f.width_px = o.width_px;
  f.height_px = o.height_px;
  f.title = Title(o.scenario, "acoustic links: delay against range");
  Panel p;
  p.title = "delivered messages: delay against the sender\xE2\x80\x93receiver range at the send time";
  p.note = "range from the logged states; realised = drawn delay rounded up to a control tick; "
           "dotted: the top of the model's jitter band";
  SetAxis(&p.x, "range", "m");
  SetAxis(&p.y, "delay", "s");
  double reach = 0.0;
  for (double r : points.range_m) reach = std::isfinite(r) ? std::max(reach, r) : reach;
  const Color model_colors[3] = {kInk, Hex(0xCC79A7), Hex(0x009E73)};
  for (std::size_t m = 0; m < models.size() && m < 3; ++m) {
    const AcousticModelLine& a = models[m];
    // To a little beyond the farthest message (the data, not an empty axis to max_range_m).
    const double end = reach > 0 && (a.max_range_m <= 0 || 1.15 * reach < a.max_range_m)
                           ? 1.15 * reach
                           : (a.max_range_m > 0 ? a.max_range_m : 1.0);
    const double d0 = a.processing_s, d1 = end / a.sound_speed_mps + a.processing_s;
    Series line;
    line.label = "model " + a.label + ": range / " + Fmt(a.sound_speed_mps) + " m/s + " +
                 Fmt(a.processing_s) + " s";
    line.x = {0.0, end};
    line.y = {d0, d1};
    line.color = model_colors[m];
    line.line = LineStyle::kDashed;
    line.line_width_px = 1.8f;
    p.series.push_back(std::move(line));
    if (a.jitter_s > 0) {
      Series top;
      top.label = "+ jitter " + Fmt(a.jitter_s) + " s";
      top.x = {0.0, end};
      top.y = {d0 + a.jitter_s, d1 + a.jitter_s};
      top.color = model_colors[m];
      top.line = LineStyle::kDotted;
      top.line_width_px = 1.5f;
      p.series.push_back(std::move(top));
    }
  }
  Series realised, drawn;
  realised.label = "realised delay";
  drawn.label = "drawn delay";
  realised.line = drawn.line = LineStyle::kNone;
  realised.marker = drawn.marker = Marker::kCircle;
  realised.marker_size_px = 4.0f;
  drawn.marker_size_px = 5.0f;
  realised.color = Hex(0x999999, 0.8f);
  drawn.color = Hex(0x0072B2);
  realised.x = drawn.x = points.range_m;
  realised.y = points.realised_delay_s;
  drawn.y = points.drawn_delay_s;
  if (!realised.x.empty()) {
    p.series.insert(p.series.begin(), std::move(drawn));
    p.series.insert(p.series.begin(), std::move(realised));
  }
  p.x.min = 0.0;
  f.panels.push_back(std::move(p));
  return f;
}

}  // namespace shoal::render
