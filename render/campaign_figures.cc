#include "render/campaign_figures.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace shoal::render {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Okabe-Ito colours (colour-blind safe): pass bluish green, fail vermillion; crashed or
// hung runs a dark purple apart from both; the exact margin blue, Theorem 3 near black.
const Color kPassColor = Hex(0x009E73);
const Color kFailColor = Hex(0xD55E00);
const Color kCrashColor = Hex(0x5B2A86);
const Color kExactColor = Hex(0x0072B2);
const Color kTheorem3Color = Hex(0x222222);

std::string Fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

std::string WithUnit(double v, const std::string& unit) {
  return Fmt("%.4g", v) + (unit.empty() ? "" : " " + unit);
}

enum Outcome { kPassed = 0, kFailed = 1, kOther = 2 };

Outcome OutcomeOf(const std::string& s) {
  if (s == "pass") return kPassed;
  if (s == "fail") return kFailed;
  return kOther;
}

bool Fail(std::string* err, const std::string& what) {
  if (err) *err = what;
  return false;
}

bool ValidateMap(const StabilityMapData& d, std::string* err) {
  const std::size_t n = d.x_values.size();
  if (n == 0) return Fail(err, "stability map: no points (x_values is empty)");
  if (d.outcome.size() != n) {
    return Fail(err, "stability map: outcome has " + std::to_string(d.outcome.size()) +
                         " entries for " + std::to_string(n) + " points (give one per point)");
  }
  if (d.has_y && d.y_values.size() != n) {
    return Fail(err, "stability map: y_values has " + std::to_string(d.y_values.size()) +
                         " entries for " + std::to_string(n) + " points (give one per point)");
  }
  if (d.has_y) {
    for (const auto* c : {&d.exact_margin, &d.theorem3}) {
      if (!c->empty() && c->size() != d.curve_at.size()) {
        return Fail(err, "stability map: a theory curve has " + std::to_string(c->size()) +
                             " values for " + std::to_string(d.curve_at.size()) +
                             " curve_at values (give one per value, NaN where undefined)");
      }
    }
  }
  return true;
}

bool Usable(double v, bool log) { return std::isfinite(v) && (!log || v > 0.0); }

// The delay axis' range: the points' range, widened to the theory values unless they lie
// far beyond it (then they are clipped, and *clipped says so): more than one span of the
// points (linear) or one factor of their ratio (log) past either end.
void FitDelayRange(const std::vector<double>& points, const std::vector<double>& theory,
                   Axis* axis, bool* clipped) {
  const bool log = axis->log;
  double lo = INFINITY, hi = -INFINITY;
  for (double v : points) {
    if (Usable(v, log)) lo = std::min(lo, v), hi = std::max(hi, v);
  }
  if (!(lo <= hi)) return;  // nothing usable: the renderer reports it
  auto to = [log](double v) { return log ? std::log10(v) : v; };
  auto from = [log](double u) { return log ? std::pow(10.0, u) : u; };
  double ulo = to(lo), uhi = to(hi);
  const double span = uhi > ulo ? uhi - ulo : std::max(std::fabs(ulo) * 0.5, 0.5);
  const double reach_lo = ulo - span, reach_hi = uhi + span;
  *clipped = false;
  for (double v : theory) {
    if (!Usable(v, log)) continue;
    const double u = to(v);
    if (u < reach_lo || u > reach_hi) {
      *clipped = true;
      continue;
    }
    ulo = std::min(ulo, u);
    uhi = std::max(uhi, u);
  }
  const double pad = 0.05 * (uhi > ulo ? uhi - ulo : span);
  axis->min = from(ulo - pad);
  axis->max = from(uhi + pad);
  if (!log && lo >= 0.0 && axis->min < 0.0 && ulo >= 0.0) axis->min = 0.0;
}

// "exact delay margin; undefined at 3 of 20 values (not drawn)".
std::string CurveLabel(const std::string& name, const std::vector<double>& v, bool clipped) {
  std::size_t undefined = 0;
  for (double x : v) undefined += std::isfinite(x) ? 0 : 1;
  std::string label = name;
  if (undefined == v.size()) {
    label += ": undefined at every value";
  } else if (undefined > 0) {
    label += "; undefined at " + std::to_string(undefined) + " of " + std::to_string(v.size()) +
             " values (not drawn)";
  }
  if (clipped) label += "; partly beyond the plotted range";
  return label;
}

void AddPointSeries(const StabilityMapData& d, const std::vector<double>& ys, Panel* p) {
  struct Class {
    const char* name;
    Color color;
    Marker marker;
    float size;
  };
  const Class classes[3] = {{"pass", kPassColor, Marker::kCircle, 11.0f},
                            {"fail", kFailColor, Marker::kCross, 13.0f},
                            {"crashed / timeout", kCrashColor, Marker::kTriangle, 13.0f}};
  for (int c = 0; c < 3; ++c) {
    Series s;
    for (std::size_t i = 0; i < d.x_values.size(); ++i) {
      if (OutcomeOf(d.outcome[i]) != c) continue;
      s.x.push_back(d.x_values[i]);
      s.y.push_back(ys[i]);
    }
    if (s.x.empty()) continue;
    s.label = std::string(classes[c].name) + " (" + std::to_string(s.x.size()) + ")";
    s.color = classes[c].color;
    s.line = LineStyle::kNone;
    s.marker = classes[c].marker;
    s.marker_size_px = classes[c].size;
    p->series.push_back(std::move(s));
  }
}

// The bound as a polyline over the non-delay axis, broken where it is undefined; small
// markers so that a value between two undefined ones still shows.
Series CurveSeries(const StabilityMapData& d, const std::vector<double>& bound, bool theorem3) {
  Series s;
  s.color = theorem3 ? kTheorem3Color : kExactColor;
  s.line = theorem3 ? LineStyle::kDashed : LineStyle::kSolid;
  s.line_width_px = 2.5f;
  s.marker = theorem3 ? Marker::kSquare : Marker::kCircle;
  s.marker_size_px = 5.0f;
  std::vector<std::size_t> order(d.curve_at.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return d.curve_at[a] < d.curve_at[b]; });
  for (std::size_t i : order) {
    const double at = d.curve_at[i], b = std::isfinite(bound[i]) ? bound[i] : kNaN;
    s.x.push_back(d.delay_on_y ? at : b);
    s.y.push_back(d.delay_on_y ? b : at);
  }
  return s;
}

void SetMapAxis(const MapAxis& m, Axis* a) {
  a->label = m.label;
  a->unit = m.unit;
  a->log = m.log;
}

void TwoAxisMap(const StabilityMapData& d, Panel* p) {
  SetMapAxis(d.x, &p->x);
  SetMapAxis(d.y, &p->y);
  AddPointSeries(d, d.y_values, p);
  std::vector<double> theory = d.exact_margin;
  theory.insert(theory.end(), d.theorem3.begin(), d.theorem3.end());
  bool clipped = false;
  FitDelayRange(d.delay_on_y ? d.y_values : d.x_values, theory, d.delay_on_y ? &p->y : &p->x,
                &clipped);
  // The other axis: the points and the curve's values, padded so that edge points show.
  std::vector<double> other = d.delay_on_y ? d.x_values : d.y_values;
  other.insert(other.end(), d.curve_at.begin(), d.curve_at.end());
  bool unused = false;
  FitDelayRange(other, {}, d.delay_on_y ? &p->x : &p->y, &unused);
  if (!d.exact_margin.empty()) {
    Series s = CurveSeries(d, d.exact_margin, false);
    s.label = CurveLabel("exact delay margin (constant delay)", d.exact_margin, clipped);
    p->series.push_back(std::move(s));
  }
  if (!d.theorem3.empty()) {
    Series s = CurveSeries(d, d.theorem3, true);
    s.label = CurveLabel("Theorem 3 certified delay", d.theorem3, clipped);
    p->series.push_back(std::move(s));
  }
}

// One axis: the outcome as a category on y, the two bounds as vertical lines.
void OneAxisMap(const StabilityMapData& d, Panel* p) {
  SetMapAxis(d.x, &p->x);
  p->y.label = "outcome";
  p->y.min = -0.6;
  p->y.max = 2.6;
  p->y.ticks = {{0.0, "crashed / timeout"}, {1.0, "fail"}, {2.0, "pass"}};
  std::vector<double> ys(d.x_values.size());
  for (std::size_t i = 0; i < ys.size(); ++i) ys[i] = 2.0 - OutcomeOf(d.outcome[i]);
  AddPointSeries(d, ys, p);
  std::vector<double> theory;
  if (!d.exact_margin.empty()) theory.push_back(d.exact_margin.front());
  if (!d.theorem3.empty()) theory.push_back(d.theorem3.front());
  bool clipped = false;
  FitDelayRange(d.x_values, theory, &p->x, &clipped);
  auto add = [&](const std::vector<double>& v, const char* name, Color c, LineStyle line) {
    if (v.empty()) return;
    const double b = v.front();
    std::string label = std::string(name) + (std::isfinite(b) ? " " + WithUnit(b, d.x.unit)
                                                               : ": undefined (not drawn)");
    if (std::isfinite(b) && (b < p->x.min || b > p->x.max)) label += ", beyond the plotted range";
    if (std::isfinite(b)) {
      p->vlines.push_back({b, c, line, 2.5f, label});
    } else {  // still in the legend, to say that it is undefined
      p->series.push_back({label, {kNaN}, {kNaN}, c, line, 2.5f, Marker::kNone, 7.0f});
    }
  };
  add(d.exact_margin, "exact delay margin", kExactColor, LineStyle::kSolid);
  add(d.theorem3, "Theorem 3 certified delay", kTheorem3Color, LineStyle::kDashed);
}


// ------------------------------------------------------------------------- soak figure

// Minutes, or hours beyond three hours of mission.
struct TimeUnit {
  double per_s = 1.0 / 60.0;
  const char* name = "min";
};

TimeUnit TimeUnitFor(const SoakFigureData& d) {
  double end = 0.0;
  for (const SoakPhase& ph : d.phases) end = std::max(end, ph.t1_s);
  for (const auto* t : {&d.error_t_s, &d.lateness_t_s, &d.delay_error_t_s, &d.logged_t_s}) {
    if (!t->empty()) end = std::max(end, t->back());
  }
  if (end > 3.0 * 3600.0) return {1.0 / 3600.0, "h"};
  return {};
}

std::vector<double> Scaled(const std::vector<double>& v, double k) {
  std::vector<double> out(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) out[i] = v[i] * k;
  return out;
}

Series Line(const std::string& label, const std::vector<double>& t, const std::vector<double>& y,
            const TimeUnit& u, double y_scale, Color c) {
  Series s;
  s.label = label;
  s.x = Scaled(t, u.per_s);
  s.y = Scaled(y, y_scale);
  s.color = c;
  s.line_width_px = 2.0f;
  return s;
}

RefLine Target(double v, const std::string& label) {
  return {v, Hex(0xB00020), LineStyle::kDashed, 1.8f, label};
}

const Color kPhaseA = Hex(0x808080, 0.07f);
const Color kPhaseB = Hex(0x808080, 0.16f);
const Color kPhaseFailed = Hex(0xE0102A, 0.22f);

// "base_s = 0.3": the key's last part (the full key is in the figure's legend).
std::string PhaseLabel(const std::string& key, const std::string& value) {
  if (key.empty()) return value;
  const std::size_t dot = key.rfind('.');
  return (dot == std::string::npos ? key : key.substr(dot + 1)) + " = " + value;
}

// Each phase as a band, alternately light and darker grey, failed ones red; labelled (in
// the top panel only) with the phase's value.
void AddPhaseBands(const SoakFigureData& d, const TimeUnit& u, bool labelled, Panel* p) {
  for (std::size_t k = 0; k < d.phases.size(); ++k) {
    const SoakPhase& ph = d.phases[k];
    Band b;
    b.x0 = ph.t0_s * u.per_s;
    b.x1 = ph.t1_s * u.per_s;
    b.color = !ph.passed ? kPhaseFailed : (k % 2 == 0 ? kPhaseA : kPhaseB);
    if (labelled) b.label = (ph.passed ? "" : "\xE2\x9C\x97 ") + PhaseLabel(d.phase_key, ph.value);
    p->bands.push_back(std::move(b));
  }
}

// "failed: phase 3 (0.5): lateness p99 ...; phase 5 (...)": the top panel's note.
std::string FailedPhasesNote(const SoakFigureData& d) {
  std::string note;
  for (std::size_t k = 0; k < d.phases.size(); ++k) {
    const SoakPhase& ph = d.phases[k];
    if (ph.passed) continue;
    note += (note.empty() ? "failed: phase " : "; phase ") + std::to_string(k + 1) + " (" +
            d.phase_key + (d.phase_key.empty() ? "" : " = ") + ph.value + ")";
    if (!ph.why.empty()) note += ": " + ph.why;
  }
  return note;
}

Panel TimePanel(const std::string& label, const std::string& unit, const TimeUnit& u) {
  Panel p;
  p.x.label = "mission time";
  p.x.unit = u.name;
  p.y.label = label;
  p.y.unit = unit;
  p.legend = LegendPlacement::kAuto;
  return p;
}

// Log scale when the positive values span more than two decades.
bool WantsLog(const std::vector<double>& v) {
  double lo = INFINITY, hi = 0.0;
  for (double x : v) {
    if (!(x > 0.0) || !std::isfinite(x)) {
      if (x <= 0.0) return false;
      continue;
    }
    lo = std::min(lo, x);
    hi = std::max(hi, x);
  }
  return hi > 0.0 && hi / lo > 100.0;
}

void AddTimingPanels(const SoakFigureData& d, const TimeUnit& u, std::vector<Panel>* out) {
  if (!d.lateness_t_s.empty()) {
    Panel p = TimePanel("loop lateness p99", "ms", u);
    p.series.push_back(Line("lateness p99", d.lateness_t_s, d.lateness_p99_s, u, 1e3,
                            VehicleColor(1)));
    if (d.lateness_p99_max_s > 0) {
      p.hlines.push_back(Target(d.lateness_p99_max_s * 1e3,
                                "target " + Fmt("%.3g", d.lateness_p99_max_s * 1e3) + " ms"));
    }
    out->push_back(std::move(p));
  }
  if (!d.delay_error_t_s.empty()) {
    Panel p = TimePanel("delay error p99", "ms", u);
    p.series.push_back(Line("delay error p99", d.delay_error_t_s, d.delay_error_p99_s, u, 1e3,
                            VehicleColor(3)));
    if (d.delay_error_p99_max_s > 0) {
      p.hlines.push_back(Target(d.delay_error_p99_max_s * 1e3,
                                "target " + Fmt("%.3g", d.delay_error_p99_max_s * 1e3) + " ms"));
    }
    out->push_back(std::move(p));
  }
}

std::vector<Panel> SoakPanels(const SoakFigureData& d, const TimeUnit& u) {
  std::vector<Panel> panels;
  if (!d.error_t_s.empty()) {
    Panel p = TimePanel("worst position error", "m", u);
    p.series.push_back(Line("worst position error", d.error_t_s, d.worst_position_error_m, u,
                            1.0, VehicleColor(0)));
    p.y.log = WantsLog(d.worst_position_error_m);
    if (d.position_tol_m > 0) {
      p.hlines.push_back(Target(d.position_tol_m, "tolerance " + WithUnit(d.position_tol_m, "m")));
    }
    panels.push_back(std::move(p));
  }
  AddTimingPanels(d, u, &panels);
  Panel rss = TimePanel("resident memory", "MiB", u);
  for (std::size_t k = 0; k < d.rss.size(); ++k) {
    if (d.rss[k].t_s.empty()) continue;
    rss.series.push_back(Line(d.rss[k].name, d.rss[k].t_s, d.rss[k].rss_mib, u, 1.0,
                              VehicleColor(static_cast<int>(k) + 1)));
  }
  if (!rss.series.empty()) panels.push_back(std::move(rss));
  if (!d.logged_t_s.empty()) {
    Panel p = TimePanel("states logged", "per min", u);
    p.series.push_back(
        Line("logged", d.logged_t_s, d.logged_per_min, u, 1.0, VehicleColor(2)));
    if (d.expected_per_min.size() == d.logged_t_s.size()) {
      Series s = Line("expected", d.logged_t_s, d.expected_per_min, u, 1.0, Hex(0x555555));
      s.line = LineStyle::kDashed;
      p.series.push_back(std::move(s));
    }
    panels.push_back(std::move(p));
  }
  return panels;
}

bool ValidateSoak(const SoakFigureData& d, std::string* err) {
  auto same = [&](const std::vector<double>& t, const std::vector<double>& y, const char* what) {
    if (t.size() == y.size()) return true;
    return Fail(err, std::string("soak figure: ") + what + " has " + std::to_string(y.size()) +
                         " values for " + std::to_string(t.size()) + " times");
  };
  if (!same(d.error_t_s, d.worst_position_error_m, "worst_position_error_m") ||
      !same(d.lateness_t_s, d.lateness_p99_s, "lateness_p99_s") ||
      !same(d.delay_error_t_s, d.delay_error_p99_s, "delay_error_p99_s") ||
      !same(d.logged_t_s, d.logged_per_min, "logged_per_min")) {
    return false;
  }
  if (!d.expected_per_min.empty() && !same(d.logged_t_s, d.expected_per_min, "expected_per_min")) {
    return false;
  }
  for (const auto& r : d.rss) {
    if (!same(r.t_s, r.rss_mib, ("rss of " + r.name).c_str())) return false;
  }
  return true;
}

std::vector<LegendEntry> PhaseLegend(const SoakFigureData& d) {
  std::vector<LegendEntry> legend;
  const std::string what = d.phase_key.empty() ? "" : " (phases step " + d.phase_key + ")";
  legend.push_back({"phase passed" + what, Hex(0x808080, 0.45f), LineStyle::kNone, Marker::kSquare});
  bool failed = false;
  for (const SoakPhase& ph : d.phases) failed = failed || !ph.passed;
  if (failed) {
    legend.push_back({"phase failed", Hex(0xE0102A, 0.6f), LineStyle::kNone, Marker::kSquare});
  }
  legend.push_back({"target", Hex(0xB00020), LineStyle::kDashed, Marker::kNone, 1.8f});
  return legend;
}
std::string JoinNotes(const std::vector<std::string>& parts) {
  std::string out;
  for (const std::string& s : parts) {
    if (!s.empty()) out += (out.empty() ? "" : "   \xC2\xB7   ") + s;  // middle dot
  }
  return out;
}

std::vector<LegendEntry> LegendOf(const Panel& p) {
  std::vector<LegendEntry> legend;
  for (const Series& s : p.series) {
    if (!s.label.empty()) legend.push_back({s.label, s.color, s.line, s.marker, s.line_width_px});
  }
  for (const RefLine& r : p.vlines) {
    if (!r.label.empty()) legend.push_back({r.label, r.color, r.line, Marker::kNone, r.line_width_px});
  }
  return legend;
}

}  // namespace

bool StabilityMapFigure(const StabilityMapData& d, Figure2D* out, std::string* err) {
  if (!ValidateMap(d, err)) return false;
  Figure2D f;
  f.width_px = d.width_px;
  f.height_px = d.height_px;
  f.title = d.title.empty() ? "stability map" : d.title + " \xE2\x80\x94 stability map";
  Panel p;
  p.note = JoinNotes({d.subtitle, d.exact_note.empty() ? "" : "exact margin: " + d.exact_note,
                      d.theorem3_note.empty() ? "" : "Theorem 3: " + d.theorem3_note});
  if (d.has_y) {
    TwoAxisMap(d, &p);
  } else {
    OneAxisMap(d, &p);
  }
  // The legend under the title: inside the plot it would hide points of a full grid, and
  // right of it it would take the plot's width.
  f.legend = LegendOf(p);
  p.legend = LegendPlacement::kNone;
  f.panels.push_back(std::move(p));
  if (!Validate(f, err)) return false;
  *out = std::move(f);
  return true;
}

bool RenderStabilityMap(const StabilityMapData& d, const std::string& png_path,
                        std::string* err) {
  Figure2D f;
  return StabilityMapFigure(d, &f, err) && RenderPng(f, png_path, err);
}

bool SoakFigure(const SoakFigureData& d, Figure2D* out, std::string* err) {
  if (!ValidateSoak(d, err)) return false;
  const TimeUnit u = TimeUnitFor(d);
  Figure2D f;
  f.width_px = d.width_px;
  f.height_px = d.height_px;
  f.title = d.title.empty() ? "soak" : d.title;
  if (!d.verdict.empty()) f.title += " \xE2\x80\x94 " + d.verdict;
  f.link_x = true;
  f.panels = SoakPanels(d, u);
  if (f.panels.empty()) return Fail(err, "soak figure: no series to draw (every series is empty)");
  for (std::size_t k = 0; k < f.panels.size(); ++k) AddPhaseBands(d, u, k == 0, &f.panels[k]);
  // The time axis spans the phases: the first samples come a sampling interval after the
  // start, and the bands alone would not widen it.
  if (!d.phases.empty()) {
    double t0 = d.phases.front().t0_s, t1 = 0.0;
    for (const SoakPhase& ph : d.phases) t0 = std::min(t0, ph.t0_s), t1 = std::max(t1, ph.t1_s);
    for (Panel& p : f.panels) {
      double end = t1;
      for (const Series& s : p.series) {
        if (!s.x.empty()) end = std::max(end, s.x.back() / u.per_s);
      }
      p.x.min = t0 * u.per_s;
      p.x.max = end * u.per_s;
    }
  }
  f.panels.front().note = FailedPhasesNote(d);
  if (!d.phases.empty()) f.legend = PhaseLegend(d);
  if (!Validate(f, err)) return false;
  *out = std::move(f);
  return true;
}

bool RenderSoakFigure(const SoakFigureData& d, const std::string& png_path, std::string* err) {
  Figure2D f;
  return SoakFigure(d, &f, err) && RenderPng(f, png_path, err);
}

}  // namespace shoal::render
