// Figure2D: layout of a grid of panels, OpenGL geometry, CPU text.
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include "render/decimate.h"
#include "render/figure.h"
#include "render/geometry.h"
#include "render/gl_canvas.h"
#include "render/legend.h"
#include "render/marker_layer.h"
#include "render/text.h"
#include "render/ticks.h"

namespace shoal::render {
namespace {

const Color kTitleColor{0.08f, 0.08f, 0.08f, 1.0f};
const Color kLabelColor{0.12f, 0.12f, 0.12f, 1.0f};
const Color kTickLabelColor{0.22f, 0.22f, 0.22f, 1.0f};
const Color kFrameColor{0.42f, 0.42f, 0.42f, 1.0f};
const Color kGridColor{0.88f, 0.88f, 0.88f, 1.0f};
const Color kMinorGridColor{0.95f, 0.95f, 0.95f, 1.0f};
const Color kNoDataColor{0.55f, 0.55f, 0.55f, 1.0f};
const Color kNoteColor{0.30f, 0.30f, 0.30f, 1.0f};

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct Sizes {
  float s = 1.0f;
  float title_px, panel_title_px, label_px, tick_px;
  float pad, tick_len, margin;
};

Sizes MakeSizes(float s) {
  Sizes z;
  z.s = s;
  z.title_px = 22.0f * s;
  z.panel_title_px = 15.5f * s;
  z.label_px = 14.5f * s;
  z.tick_px = 13.5f * s;
  z.pad = 4.0f * s;
  z.tick_len = 5.0f * s;
  z.margin = 12.0f * s;
  return z;
}

std::string AxisTitle(const Axis& a) {
  if (a.unit.empty()) return a.label;
  if (a.label.empty()) return "[" + a.unit + "]";
  return a.label + " [" + a.unit + "]";
}

// Data range of one axis (in data units).
struct Range {
  double lo = kNaN, hi = kNaN;
  bool valid() const { return std::isfinite(lo) && std::isfinite(hi); }
  void Add(double v) {
    if (!std::isfinite(v)) return;
    if (!(lo <= v)) lo = v;
    if (!(hi >= v)) hi = v;
  }
  void Add(const Range& r) {
    if (r.valid()) {
      Add(r.lo);
      Add(r.hi);
    }
  }
};

// Values beyond +-1e300 (and on a log axis below 1e-300) are treated as missing: their
// ranges and logarithms would overflow.
bool Usable(double v, bool log) {
  return std::isfinite(v) && std::fabs(v) <= 1e300 && (!log || v >= 1e-300);
}

// Maps data values to pixels along one axis (log10 first on a log axis).
struct AxisMap {
  double lo = 0, hi = 1;  // in transformed units (log10 on a log axis)
  double p0 = 0, p1 = 1;  // pixels of lo and hi
  bool log = false;
  double T(double v) const { return !Usable(v, log) ? kNaN : log ? std::log10(v) : v; }
  double MapT(double t) const { return p0 + (t - lo) * (p1 - p0) / (hi - lo); }
  double Map(double v) const { return MapT(T(v)); }
};

// Automatic range: tight or padded, expanded when degenerate.
void FinishRange(Range* r, bool log, double pad_fraction) {
  if (!r->valid()) {
    *r = log ? Range{1.0, 10.0} : Range{0.0, 1.0};
    return;
  }
  double lo = log ? std::log10(r->lo) : r->lo, hi = log ? std::log10(r->hi) : r->hi;
  if (hi - lo < 1e-12 * std::max(1.0, std::fabs(lo))) {
    const double d = log ? 0.5 : (lo != 0.0 ? 0.1 * std::fabs(lo) : 1.0);
    lo -= d;
    hi += d;
  } else {
    const double pad = pad_fraction * (hi - lo);
    lo -= pad;
    hi += pad;
  }
  if (log) {
    lo = std::max(lo, -307.0);
    hi = std::min(hi, 307.0);
  }
  r->lo = log ? std::pow(10.0, lo) : lo;
  r->hi = log ? std::pow(10.0, hi) : hi;
}

struct AxisTicks {
  std::vector<double> values;  // major, data units
  std::vector<double> minor;
  std::vector<std::string> labels;
  std::string exponent;  // "×10ⁿ" or empty
  float max_label_w = 0.0f;
};

AxisTicks MakeTicks(const Axis& axis, double lo, double hi, int max_ticks, const TextRenderer& text,
                    float tick_px) {
  AxisTicks t;
  if (!axis.ticks.empty()) {
    for (const Tick& k : axis.ticks) {
      if (k.value >= lo - 1e-12 * std::fabs(hi - lo) &&
          k.value <= hi + 1e-12 * std::fabs(hi - lo)) {
        t.values.push_back(k.value);
        t.labels.push_back(k.label);
      }
    }
  } else if (axis.log) {
    const TickSet ts = LogTicks(lo, hi, max_ticks);
    t.values = ts.major;
    t.minor = ts.minor;
    for (double v : ts.major) {
      t.labels.push_back(ts.step > 0  ? FormatLinearTick(v, ts.step)
                         : ts.decades ? FormatLogTick(v)
                                      : FormatPlainTick(v));
    }
  } else {
    const TickSet ts = LinearTicks(lo, hi, max_ticks);
    t.values = ts.major;
    double biggest = 0.0;
    for (double v : ts.major) biggest = std::max(biggest, std::fabs(v));
    if (ts.step > 0 && biggest / ts.step >= 1e6) {
      // A small range far from zero (e.g. epoch seconds): labels relative to an offset, the
      // multiple of 10^k nearest to the first tick, 10^k just above the range.
      const double unit = std::pow(10.0, std::floor(std::log10(hi - lo)) + 1.0);
      const double offset = std::round(ts.major.front() / unit) * unit;
      for (double v : ts.major) t.labels.push_back(FormatLinearTick(v - offset, ts.step));
      const std::string o = FormatLinearTick(offset, unit);
      t.exponent = offset > 0 ? "+" + o : o;
    } else {
      const int e = CommonExponent(ts);
      const double f = std::pow(10.0, -e);
      for (double v : ts.major) t.labels.push_back(FormatLinearTick(v * f, ts.step * f));
      if (e != 0) t.exponent = ExponentLabel(e);
    }
  }
  for (const std::string& l : t.labels)
    t.max_label_w = std::max(t.max_label_w, text.Width(l, tick_px));
  return t;
}

// Screen geometry of one series after decimation.
struct SeriesGeometry {
  std::vector<std::vector<Vec2>> lines;
  std::vector<Vec2> markers;
  std::vector<float> marker_alpha;  // per marker, for translucent series; else empty
};

struct PanelState {
  const Panel* panel = nullptr;
  int row = 0, col = 0;
  Rect cell, plot;
  Range xr, yr;  // final ranges, data units
  bool has_data = false;
  bool show_x_ticklabels = true, show_x_label = true;
  AxisTicks xt, yt;
  AxisMap xm, ym;
  std::vector<SeriesGeometry> geom;
  std::vector<LegendEntry> legend_entries;
  LegendBox legend;
  bool legend_outside = false;
  float legend_x = 0, legend_y = 0;
  // Insets around the plot within the cell.
  float top = 0, bottom = 0, left = 0, right = 0;
};

// y range over the points whose x is inside [xlo, xhi].
void YRange(const Panel& p, double xlo, double xhi, Range* yr) {
  for (const Series& s : p.series) {
    for (std::size_t i = 0; i < s.x.size(); ++i) {
      if (!Usable(s.x[i], p.x.log) || !Usable(s.y[i], p.y.log)) continue;
      if (s.x[i] < xlo || s.x[i] > xhi) continue;
      yr->Add(s.y[i]);
    }
  }
}

void AddExplicitTicks(const Axis& a, Range* r) {
  if (a.ticks.size() < 1) return;
  double lo = a.ticks.front().value, hi = lo;
  for (const Tick& t : a.ticks) {
    lo = std::min(lo, t.value);
    hi = std::max(hi, t.value);
  }
  double half = 0.5;
  if (a.ticks.size() >= 2) half = 0.5 * (hi - lo) / static_cast<double>(a.ticks.size() - 1);
  if (a.log) {
    r->Add(lo);
    r->Add(hi);
  } else {
    r->Add(lo - half);
    r->Add(hi + half);
  }
}

// Decimated line runs of one series (tx, ty: transformed data values).
void BuildLines(const PanelState& ps, const std::vector<double>& tx, const std::vector<double>& ty,
                SeriesGeometry* g) {
  const std::size_t n = tx.size();
  const double W = ps.plot.w();
  const auto sx = [&](double t) {
    return static_cast<float>(std::clamp(ps.xm.MapT(t), -1e5, 1e5));
  };
  const auto sy = [&](double t) {
    return static_cast<float>(std::clamp(ps.ym.MapT(t), -1e5, 1e5));
  };
  IndexRuns runs;
  if (IsSortedX(tx.data(), n) && ps.xm.p1 > ps.xm.p0) {
    const double px_per_x = W / (ps.xm.hi - ps.xm.lo);
    runs = DecimateMinMax(tx.data(), ty.data(), n, ps.xm.lo, px_per_x,
                          static_cast<int>(std::ceil(W)));
  } else {
    std::vector<double> px(n), py(n);
    for (std::size_t i = 0; i < n; ++i) {
      px[i] = std::isfinite(tx[i]) && std::isfinite(ty[i]) ? ps.xm.MapT(tx[i]) : kNaN;
      py[i] = std::isfinite(tx[i]) && std::isfinite(ty[i]) ? ps.ym.MapT(ty[i]) : kNaN;
    }
    runs = DecimateByDistance(px.data(), py.data(), n, 0.5);
  }
  std::vector<float> lx, ly;
  for (std::size_t r = 0; r < runs.runs(); ++r) {
    lx.clear();
    ly.clear();
    for (std::size_t j = 0; j < runs.run_size(r); ++j) {
      const std::uint32_t i = runs.index[runs.start[r] + j];
      lx.push_back(sx(tx[i]));
      ly.push_back(sy(ty[i]));
    }
    // Fewer, longer segments where the line is straight to within a fifth of a pixel.
    SimplifyPolyline(&lx, &ly, 0.2f);
    std::vector<Vec2> line(lx.size());
    for (std::size_t j = 0; j < lx.size(); ++j) line[j] = {lx[j], ly[j]};
    g->lines.push_back(std::move(line));
  }
}

// Decimated markers of one series. Pixel coordinates are shifted by r so that markers
// overlapping the plot's edge are kept; a translucent series gets the opacity of all the
// markers that fell on a pixel.
void BuildMarkers(const PanelState& ps, const Series& s, float scale,
                  const std::vector<double>& tx, const std::vector<double>& ty,
                  SeriesGeometry* g) {
  const std::size_t n = tx.size();
  const double r = 0.5 * s.marker_size_px * scale;
  std::vector<double> px(n), py(n);
  for (std::size_t i = 0; i < n; ++i) {
    const bool ok = std::isfinite(tx[i]) && std::isfinite(ty[i]);
    px[i] = ok ? ps.xm.MapT(tx[i]) - ps.plot.x0 + r : kNaN;
    py[i] = ok ? ps.ym.MapT(ty[i]) - ps.plot.y0 + r : kNaN;
  }
  std::vector<std::uint32_t> counts;
  // Opaque markers: one per third of a marker (dense clouds look the same, with far
  // fewer stamps); translucent ones: one per pixel, with the count.
  const bool translucent = s.color.a < 1.0f;
  const double cell = translucent ? 1.0 : std::max(1.0, s.marker_size_px * scale / 3.0);
  const auto kept = DecimateScatter(px.data(), py.data(), n, ps.plot.w() + 2 * r,
                                    ps.plot.h() + 2 * r, cell, translucent ? &counts : nullptr);
  g->markers.reserve(kept.size());
  for (std::size_t j = 0; j < kept.size(); ++j) {
    const std::uint32_t i = kept[j];
    g->markers.push_back({static_cast<float>(px[i] - r + ps.plot.x0),
                          static_cast<float>(py[i] - r + ps.plot.y0)});
    if (!counts.empty()) {
      // k translucent markers on one pixel: 1 - (1 - a)^k.
      g->marker_alpha.push_back(1.0f - std::pow(1.0f - s.color.a, static_cast<float>(counts[j])));
    }
  }
}

// Builds the decimated screen geometry of every series of a panel.
void BuildGeometry(PanelState* ps, float scale) {
  const Panel& p = *ps->panel;
  ps->geom.assign(p.series.size(), {});
  std::vector<double> tx, ty;
  for (std::size_t k = 0; k < p.series.size(); ++k) {
    const Series& s = p.series[k];
    const std::size_t n = s.x.size();
    tx.resize(n);
    ty.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      tx[i] = ps->xm.T(s.x[i]);
      ty[i] = ps->ym.T(s.y[i]);
    }
    if (s.line != LineStyle::kNone) BuildLines(*ps, tx, ty, &ps->geom[k]);
    if (s.marker != Marker::kNone) BuildMarkers(*ps, s, scale, tx, ty, &ps->geom[k]);
  }
}

// How many drawn things (segments, markers, reference lines) a rectangle would hide.
std::size_t CountHidden(const PanelState& ps, const Rect& r) {
  std::size_t n = 0;
  for (const SeriesGeometry& g : ps.geom) {
    for (const auto& line : g.lines) {
      for (std::size_t i = 0; i + 1 < line.size(); ++i)
        n += SegmentHitsRect(line[i], line[i + 1], r);
    }
    for (const Vec2& m : g.markers) n += r.Contains(m.x, m.y);
  }
  for (const RefLine& h : ps.panel->hlines) {
    const double y = ps.ym.Map(h.value);
    n += std::isfinite(y) && y >= r.y0 && y <= r.y1;
  }
  for (const RefLine& v : ps.panel->vlines) {
    const double x = ps.xm.Map(v.value);
    n += std::isfinite(x) && x >= r.x0 && x <= r.x1;
  }
  return n;
}

// Best inside position of the legend; returns the number of hidden things there.
std::size_t PlaceInside(PanelState* ps, float inset) {
  const Rect& p = ps->plot;
  const float w = ps->legend.width(), h = ps->legend.height();
  const float left = p.x0 + inset, right = p.x1 - inset - w;
  const float top = p.y0 + inset, bottom = p.y1 - inset - h;
  const float cx = 0.5f * (p.x0 + p.x1 - w), cy = 0.5f * (p.y0 + p.y1 - h);
  const Vec2 candidates[8] = {{right, top}, {left, top},  {right, bottom}, {left, bottom},
                              {cx, top},    {cx, bottom}, {right, cy},     {left, cy}};
  std::size_t best = std::numeric_limits<std::size_t>::max();
  for (const Vec2& c : candidates) {
    const Rect r{c.x - 3.0f, c.y - 3.0f, c.x + w + 3.0f, c.y + h + 3.0f};
    const std::size_t hidden = CountHidden(*ps, r);
    if (hidden < best) {
      best = hidden;
      ps->legend_x = c.x;
      ps->legend_y = c.y;
    }
    if (hidden == 0) break;
  }
  return best;
}

class Plot2D {
 public:
  Plot2D(const Figure2D& f, TextRenderer* text) : f_(f), text_(text) {}

  bool Render(Image* out, std::string* err);

 private:
  void ComputeRanges();
  void Layout(const std::vector<float>& outside_legend_w);
  void PlaceCells(const Rect& grid);
  void CollectLegendEntries();
  void PlaceLegends();
  void DrawGrid(const PanelState& ps, GlCanvas* gl);
  void DrawSeries(const PanelState& ps, GlCanvas* gl);
  void DrawFrame(const PanelState& ps, GlCanvas* gl);
  float NotePx() const { return 12.5f * z_.s; }
  void DrawGeometry(GlCanvas* gl);
  void DrawText(Image* img);
  void DrawBandLabels(const PanelState& ps, Image* img);

  const Figure2D& f_;
  TextRenderer* text_;
  Sizes z_;
  LegendMetrics lm_;
  std::vector<PanelState> ps_;
  int rows_ = 1, cols_ = 1;
  float title_y_ = 0, legend_row_y_ = 0;
  LegendRow legend_row_;
};

void Plot2D::ComputeRanges() {
  // x ranges first (linked: the union), then y over the visible x.
  Range linked;
  for (PanelState& ps : ps_) {
    const Panel& p = *ps.panel;
    Range xr;
    bool any = false;
    for (const Series& s : p.series) {
      for (std::size_t i = 0; i < s.x.size(); ++i) {
        if (!Usable(s.x[i], p.x.log) || !Usable(s.y[i], p.y.log)) continue;
        xr.Add(s.x[i]);
        any = true;
      }
    }
    ps.has_data = any;
    for (const RefLine& v : p.vlines) {
      if (Usable(v.value, p.x.log)) xr.Add(v.value);
    }
    AddExplicitTicks(p.x, &xr);
    ps.xr = xr;
    linked.Add(xr);
  }
  for (PanelState& ps : ps_) {
    const Panel& p = *ps.panel;
    Range xr = f_.link_x ? linked : ps.xr;
    // x is tight, except that markers keep clear of the frame: pad by the largest marker
    // radius, in pixels of a plot about as wide as the panel's share of the figure.
    float marker_r = 0.0f;
    for (const Series& s : p.series) {
      if (s.marker != Marker::kNone) marker_r = std::max(marker_r, 0.5f * s.marker_size_px * z_.s);
    }
    const float approx_w = 0.85f * static_cast<float>(f_.width_px) / static_cast<float>(cols_);
    double pad = marker_r > 0.0f ? (marker_r + 1.0f) / approx_w : 0.0;
    // Curves (x not sorted, e.g. a path in a plane) get the same margin as y.
    for (const Series& s : p.series) {
      if (s.line != LineStyle::kNone && !IsSortedX(s.x.data(), s.x.size()))
        pad = std::max(pad, 0.04);
    }
    FinishRange(&xr, p.x.log, pad);
    if (!std::isnan(p.x.min)) xr.lo = p.x.min;
    if (!std::isnan(p.x.max)) xr.hi = p.x.max;
    if (!(xr.lo < xr.hi)) xr.hi = xr.lo + 1.0;
    ps.xr = xr;
    Range yr;
    YRange(p, xr.lo, xr.hi, &yr);
    for (const RefLine& h : p.hlines) {
      if (Usable(h.value, p.y.log)) yr.Add(h.value);
    }
    AddExplicitTicks(p.y, &yr);
    FinishRange(&yr, p.y.log, p.y.ticks.empty() ? 0.04 : 0.0);
    if (!std::isnan(p.y.min)) yr.lo = p.y.min;
    if (!std::isnan(p.y.max)) yr.hi = p.y.max;
    if (!(yr.lo < yr.hi)) yr.hi = p.y.log ? yr.lo * 10.0 : yr.lo + 1.0;
    ps.yr = yr;
  }
}

// The densest y ticks (at most 9) at least 2.2 lines apart on a plot ph pixels high; if
// those are fewer than 3, the sparsest of at least 3 that are 1.5 lines apart.
AxisTicks ChooseYTicks(const Axis& ya, const Range& yr, float ph, const TextRenderer& text,
                       float tick_px) {
  if (!ya.ticks.empty()) return MakeTicks(ya, yr.lo, yr.hi, 2, text, tick_px);
  const float tick_lh = text.LineHeight(tick_px);
  const double tlo = ya.log ? std::log10(yr.lo) : yr.lo;
  const double thi = ya.log ? std::log10(yr.hi) : yr.hi;
  std::vector<AxisTicks> sets;
  std::vector<double> gaps;
  for (int n = 9; n >= 2; --n) {
    sets.push_back(MakeTicks(ya, yr.lo, yr.hi, n, text, tick_px));
    double gap = INFINITY;
    const auto& v = sets.back().values;
    for (std::size_t k = 1; k < v.size(); ++k) {
      const double a = ya.log ? std::log10(v[k - 1]) : v[k - 1];
      const double b = ya.log ? std::log10(v[k]) : v[k];
      gap = std::min(gap, (b - a) / (thi - tlo) * ph);
    }
    gaps.push_back(gap);
  }
  for (std::size_t k = 0; k < sets.size(); ++k) {
    if (gaps[k] >= 2.2 * tick_lh && sets[k].values.size() >= 3) return sets[k];
  }
  for (std::size_t k = sets.size(); k-- > 0;) {
    if (gaps[k] >= 1.5 * tick_lh && sets[k].values.size() >= 3) return sets[k];
  }
  for (std::size_t k = 0; k < sets.size(); ++k) {
    if (gaps[k] >= 1.5 * tick_lh) return sets[k];
  }
  return sets.back();
}

// The densest x ticks whose labels do not touch on a plot pw pixels wide.
AxisTicks ChooseXTicks(const Axis& xa, const Range& xr, float pw, const TextRenderer& text,
                       float tick_px, float s) {
  int n = std::clamp(static_cast<int>(pw / (45.0f * s)) + 1, 2, 14);
  for (;; --n) {
    AxisTicks t = MakeTicks(xa, xr.lo, xr.hi, n, text, tick_px);
    if (n <= 2 || !xa.ticks.empty()) return t;
    AxisMap m{xa.log ? std::log10(xr.lo) : xr.lo, xa.log ? std::log10(xr.hi) : xr.hi, 0, pw,
              xa.log};
    bool fits = true;
    for (std::size_t k = 1; k < t.values.size() && fits; ++k) {
      const double gap = m.Map(t.values[k]) - m.Map(t.values[k - 1]);
      const float wk =
          0.5f * (text.Width(t.labels[k], tick_px) + text.Width(t.labels[k - 1], tick_px));
      fits = gap >= wk + 12.0f * s;
    }
    if (fits) return t;
  }
}

// Pixels of the axis range [lo, hi] from p_lo to p_hi (swapped on a reversed axis).
AxisMap MakeMap(const Axis& a, const Range& r, float p_lo, float p_hi) {
  if (a.reversed) std::swap(p_lo, p_hi);
  return {a.log ? std::log10(r.lo) : r.lo, a.log ? std::log10(r.hi) : r.hi, p_lo, p_hi, a.log};
}

void Plot2D::Layout(const std::vector<float>& outside_w) {
  const float W = static_cast<float>(f_.width_px), H = static_cast<float>(f_.height_px);
  float y = z_.margin;
  if (!f_.title.empty()) {
    title_y_ = y;
    y += text_->LineHeight(z_.title_px, true) + 4.0f * z_.s;
  }
  if (!f_.legend.empty()) {
    legend_row_ = LegendRow(f_.legend, lm_, *text_, z_.margin, W - z_.margin);
    legend_row_y_ = y;
    y += legend_row_.height() + 4.0f * z_.s;
  }
  PlaceCells(Rect{z_.margin, y, W - z_.margin, H - z_.margin});
  // y ticks from the plot heights, then left insets aligned per column.
  const float label_lh = text_->LineHeight(z_.label_px);
  std::vector<float> col_left(static_cast<std::size_t>(cols_), 0.0f);
  for (PanelState& ps : ps_) {
    const float ph = ps.cell.h() - ps.top - ps.bottom;
    ps.yt = ChooseYTicks(ps.panel->y, ps.yr, ph, *text_, z_.tick_px);
    float left = ps.yt.max_label_w + z_.tick_len + z_.pad + 2.0f * z_.s;
    if (!AxisTitle(ps.panel->y).empty()) left += label_lh + z_.pad;
    auto c = static_cast<std::size_t>(ps.col);
    col_left[c] = std::max(col_left[c], left);
  }
  // x ticks from the plot widths; right insets for the last label and outside legends.
  std::vector<float> col_right(static_cast<std::size_t>(cols_), 0.0f);
  for (std::size_t i = 0; i < ps_.size(); ++i) {
    PanelState& ps = ps_[i];
    ps.left = col_left[static_cast<std::size_t>(ps.col)];
    float right = 8.0f * z_.s + outside_w[i];
    const float pw = ps.cell.w() - ps.left - right;
    const Axis& xa = ps.panel->x;
    ps.xt = ChooseXTicks(xa, ps.xr, pw, *text_, z_.tick_px, z_.s);
    // Half of the last (rightmost) label may stick out to the right of the plot.
    if (ps.show_x_ticklabels && !ps.xt.values.empty() && outside_w[i] == 0.0f) {
      const double v = xa.reversed ? ps.xt.values.front() : ps.xt.values.back();
      const AxisMap m = MakeMap(xa, ps.xr, 0.0f, pw);
      const float from_right = pw - static_cast<float>(m.Map(v));
      const std::string& l = xa.reversed ? ps.xt.labels.front() : ps.xt.labels.back();
      right = std::max(right, 0.5f * text_->Width(l, z_.tick_px) - from_right + 2.0f * z_.s);
    }
    auto c = static_cast<std::size_t>(ps.col);
    col_right[c] = std::max(col_right[c], right);
  }
  for (PanelState& ps : ps_) {
    ps.right = col_right[static_cast<std::size_t>(ps.col)];
    ps.plot = {std::round(ps.cell.x0 + ps.left), std::round(ps.cell.y0 + ps.top),
               std::round(ps.cell.x1 - ps.right), std::round(ps.cell.y1 - ps.bottom)};
    if (ps.plot.x1 < ps.plot.x0 + 10) ps.plot.x1 = ps.plot.x0 + 10;
    if (ps.plot.y1 < ps.plot.y0 + 10) ps.plot.y1 = ps.plot.y0 + 10;
    ps.xm = MakeMap(ps.panel->x, ps.xr, ps.plot.x0, ps.plot.x1);
    ps.ym = MakeMap(ps.panel->y, ps.yr, ps.plot.y1, ps.plot.y0);
  }
}

// Cells of the grid in `grid`, and the vertical insets of their plots (fonts only),
// aligned per row.
void Plot2D::PlaceCells(const Rect& grid) {
  const float hgap = 20.0f * z_.s, vgap = 8.0f * z_.s;
  const float cw = (grid.w() - hgap * static_cast<float>(cols_ - 1)) / static_cast<float>(cols_);
  const float ch = (grid.h() - vgap * static_cast<float>(rows_ - 1)) / static_cast<float>(rows_);
  const float tick_lh = text_->LineHeight(z_.tick_px);
  const float label_lh = text_->LineHeight(z_.label_px);
  const float title_lh = text_->LineHeight(z_.panel_title_px, true);
  const float note_lh = text_->LineHeight(NotePx());
  std::vector<float> row_top(static_cast<std::size_t>(rows_), 0.0f);
  std::vector<float> row_bottom(static_cast<std::size_t>(rows_), 0.0f);
  for (std::size_t i = 0; i < ps_.size(); ++i) {
    PanelState& ps = ps_[i];
    const float x0 = grid.x0 + static_cast<float>(ps.col) * (cw + hgap);
    const float y0 = grid.y0 + static_cast<float>(ps.row) * (ch + vgap);
    ps.cell = {x0, y0, x0 + cw, y0 + ch};
    const bool below = i + static_cast<std::size_t>(cols_) < ps_.size();
    ps.show_x_ticklabels = !f_.link_x || !below;
    ps.show_x_label = ps.show_x_ticklabels && !AxisTitle(ps.panel->x).empty();
    const bool needs_title_row = !ps.panel->title.empty();
    ps.top = needs_title_row ? title_lh + 3.0f * z_.s : 0.5f * tick_lh + z_.pad;
    if (!ps.panel->note.empty()) ps.top += note_lh + 2.0f * z_.s;
    ps.bottom = z_.tick_len + z_.pad;
    if (ps.show_x_ticklabels) ps.bottom += tick_lh;
    if (ps.show_x_label) ps.bottom += label_lh + z_.pad;
    if (!ps.show_x_ticklabels) ps.bottom = std::max(ps.bottom, 0.5f * tick_lh + z_.pad);
    auto r = static_cast<std::size_t>(ps.row);
    row_top[r] = std::max(row_top[r], ps.top);
    row_bottom[r] = std::max(row_bottom[r], ps.bottom);
  }
  for (PanelState& ps : ps_) {
    ps.top = row_top[static_cast<std::size_t>(ps.row)];
    ps.bottom = row_bottom[static_cast<std::size_t>(ps.row)];
  }
}

bool Plot2D::Render(Image* out, std::string* err) {
  float s = f_.scale;
  if (s <= 0.0f) {
    s = std::sqrt(static_cast<float>(f_.width_px) * static_cast<float>(f_.height_px) /
                  (1600.0f * 1000.0f));
    s = std::clamp(s, 0.75f, 3.0f);
  }
  z_ = MakeSizes(s);
  lm_ = MakeLegendMetrics(*text_, s);
  cols_ = std::min<int>(f_.columns, static_cast<int>(f_.panels.size()));
  rows_ = (static_cast<int>(f_.panels.size()) + cols_ - 1) / cols_;
  ps_.resize(f_.panels.size());
  for (std::size_t i = 0; i < ps_.size(); ++i) {
    ps_[i].panel = &f_.panels[i];
    ps_[i].row = static_cast<int>(i) / cols_;
    ps_[i].col = static_cast<int>(i) % cols_;
  }
  ComputeRanges();
  CollectLegendEntries();
  PlaceLegends();

  GlCanvas gl;
  if (!gl.Init(f_.width_px, f_.height_px, err)) return false;
  gl.Clear(Color{1, 1, 1, 1});
  DrawGeometry(&gl);
  if (!gl.Read(out, err)) return false;
  DrawText(out);
  return true;
}

void Plot2D::CollectLegendEntries() {
  for (PanelState& ps : ps_) {
    const Panel& p = *ps.panel;
    if (p.legend == LegendPlacement::kNone) continue;
    for (const Series& se : p.series) {
      if (!se.label.empty()) {
        ps.legend_entries.push_back({se.label, se.color, se.line, se.marker, se.line_width_px});
      }
    }
    for (const std::vector<RefLine>* lines : {&p.hlines, &p.vlines}) {
      for (const RefLine& r : *lines) {
        if (!r.label.empty()) {
          ps.legend_entries.push_back({r.label, r.color, r.line, Marker::kNone, r.line_width_px});
        }
      }
    }
  }
}

// Lays the figure out, then puts each panel's legend inside or outside (which changes
// the layout once) and builds the geometry of the final layout.
void Plot2D::PlaceLegends() {
  std::vector<float> outside(ps_.size(), 0.0f);
  Layout(outside);
  bool any_outside = false;
  const float inset = 6.0f * z_.s;
  for (std::size_t i = 0; i < ps_.size(); ++i) {
    PanelState& ps = ps_[i];
    if (ps.legend_entries.empty()) continue;
    int columns = 1;
    ps.legend = LegendBox(ps.legend_entries, lm_, *text_, columns);
    while (ps.legend.height() > ps.plot.h() - 2 * inset && columns < 4) {
      ps.legend = LegendBox(ps.legend_entries, lm_, *text_, ++columns);
    }
    const LegendPlacement where = ps.panel->legend;
    bool go_outside = where == LegendPlacement::kOutside;
    if (where == LegendPlacement::kAuto) {
      BuildGeometry(&ps, z_.s);
      const bool fits_inside = ps.legend.width() < ps.plot.w() - 2 * inset &&
                               ps.legend.height() < ps.plot.h() - 2 * inset;
      go_outside = !fits_inside || PlaceInside(&ps, inset) > 0;
      // Outside only if the plot keeps most of its width.
      if (go_outside && ps.legend.width() + 12.0f * z_.s > 0.45f * ps.cell.w()) go_outside = false;
    }
    if (!go_outside) continue;
    // As few columns as fit the plot's height.
    int columns_out = 1;
    ps.legend = LegendBox(ps.legend_entries, lm_, *text_, 1);
    while (ps.legend.height() > ps.plot.h() && columns_out < 8) {
      ps.legend = LegendBox(ps.legend_entries, lm_, *text_, ++columns_out);
    }
    outside[i] = ps.legend.width() + 12.0f * z_.s;
    ps.legend_outside = true;
    any_outside = true;
  }
  if (any_outside) {
    // The whole column makes room, so that its plots stay aligned.
    std::vector<float> col_w(static_cast<std::size_t>(cols_), 0.0f);
    for (std::size_t i = 0; i < ps_.size(); ++i) {
      auto c = static_cast<std::size_t>(ps_[i].col);
      col_w[c] = std::max(col_w[c], outside[i]);
    }
    for (std::size_t i = 0; i < ps_.size(); ++i)
      outside[i] = col_w[static_cast<std::size_t>(ps_[i].col)];
    Layout(outside);
  }
  for (PanelState& ps : ps_) {
    // Geometry built for the legend's placement is still valid unless the layout changed.
    if (any_outside || ps.geom.size() != ps.panel->series.size()) BuildGeometry(&ps, z_.s);
    if (ps.legend.empty()) continue;
    if (ps.legend_outside) {
      ps.legend_x = ps.plot.x1 + 12.0f * z_.s;
      ps.legend_y = ps.plot.y0;
    } else {
      PlaceInside(&ps, inset);
    }
  }
}

// The pixels of a band within the plot; false if it is not drawable or not visible.
bool BandRect(const PanelState& ps, const Band& b, Rect* r) {
  const Rect& p = ps.plot;
  const double xa = ps.xm.Map(b.x0), xb = ps.xm.Map(b.x1);
  if (!std::isfinite(xa) || !std::isfinite(xb)) return false;
  r->x0 = std::max(p.x0, static_cast<float>(std::min(xa, xb)));
  r->x1 = std::min(p.x1, static_cast<float>(std::max(xa, xb)));
  r->y0 = p.y0;
  r->y1 = p.y1;
  if (std::isfinite(b.y0) && std::isfinite(b.y1)) {
    const double ya = ps.ym.Map(b.y0), yb = ps.ym.Map(b.y1);
    if (!std::isfinite(ya) || !std::isfinite(yb)) return false;
    r->y0 = std::max(p.y0, static_cast<float>(std::min(ya, yb)));
    r->y1 = std::min(p.y1, static_cast<float>(std::max(ya, yb)));
  }
  return r->x1 > r->x0 && r->y1 > r->y0;
}

// A crisp 1-pixel line position: the centre of the pixel containing v.
float Snap(float v) { return std::floor(v) + 0.5f; }

void Plot2D::DrawGeometry(GlCanvas* gl) {
  if (!legend_row_.empty()) {
    Mesh mesh;
    legend_row_.DrawShapes(legend_row_y_, &mesh);
    gl->Draw(mesh);
  }
  for (const PanelState& ps : ps_) {
    DrawGrid(ps, gl);
    DrawSeries(ps, gl);
    DrawFrame(ps, gl);
  }
}

// Grid and reference lines, under the data, clipped to the plot (the clip stays set).
void Plot2D::DrawGrid(const PanelState& ps, GlCanvas* gl) {
  Mesh mesh;
  const Rect& p = ps.plot;
  const float grid_w = std::max(1.0f, std::round(z_.s));
  const auto vline = [&](double v, const Color& c) {
    const float x = Snap(static_cast<float>(ps.xm.Map(v)));
    AddRect(x - 0.5f * grid_w, p.y0, x + 0.5f * grid_w, p.y1, 0, c, &mesh);
  };
  const auto hline = [&](double v, const Color& c) {
    const float y = Snap(static_cast<float>(ps.ym.Map(v)));
    AddRect(p.x0, y - 0.5f * grid_w, p.x1, y + 0.5f * grid_w, 0, c, &mesh);
  };
  for (double v : ps.xt.minor) vline(v, kMinorGridColor);
  for (double v : ps.yt.minor) hline(v, kMinorGridColor);
  for (double v : ps.xt.values) vline(v, kGridColor);
  for (double v : ps.yt.values) hline(v, kGridColor);
  gl->SetClip(p.x0, p.y0, p.x1, p.y1);
  gl->Draw(mesh);
  mesh.clear();
  for (const Band& b : ps.panel->bands) {
    Rect r;
    if (BandRect(ps, b, &r)) AddRect(r.x0, r.y0, r.x1, r.y1, 0, b.color, &mesh);
  }
  if (!mesh.empty()) {
    gl->Draw(mesh);
    mesh.clear();
  }
  for (const RefLine& h : ps.panel->hlines) {
    const double y = ps.ym.Map(h.value);
    if (!std::isfinite(y)) continue;
    const Vec2 l[2] = {{p.x0, static_cast<float>(y)}, {p.x1, static_cast<float>(y)}};
    StrokePolyline(l, nullptr, 2, h.line_width_px * z_.s, h.line, h.color, &mesh);
  }
  for (const RefLine& v : ps.panel->vlines) {
    const double x = ps.xm.Map(v.value);
    if (!std::isfinite(x)) continue;
    const Vec2 l[2] = {{static_cast<float>(x), p.y0}, {static_cast<float>(x), p.y1}};
    StrokePolyline(l, nullptr, 2, v.line_width_px * z_.s, v.line, v.color, &mesh);
  }
  gl->Draw(mesh);
}

// Series, in order (later ones on top), lines blended once per pixel; markers are stamped
// on the CPU into a layer shared by consecutive marker-only series. Clears the clip.
void Plot2D::DrawSeries(const PanelState& ps, GlCanvas* gl) {
  Mesh mesh;
  const Rect& p = ps.plot;
  const Panel& panel = *ps.panel;
  const int lw = static_cast<int>(p.w()), lh = static_cast<int>(p.h());
  std::unique_ptr<MarkerLayer> layer;
  const auto flush_layer = [&] {
    if (layer && !layer->empty()) {
      gl->DrawLayer(static_cast<int>(p.x0), static_cast<int>(p.y0), lw, lh, layer->ToBytes());
    }
    layer.reset();
  };
  for (std::size_t k = 0; k < panel.series.size(); ++k) {
    const Series& s = panel.series[k];
    const SeriesGeometry& g = ps.geom[k];
    if (!g.lines.empty()) {
      flush_layer();
      for (const auto& line : g.lines) {
        float phase = 0.0f;
        StrokePolyline(line.data(), nullptr, line.size(), s.line_width_px * z_.s, s.line, s.color,
                       &mesh, &phase);
      }
      gl->Draw(mesh, GlCanvas::Depth::kOff, s.color.a < 1.0f);
      mesh.clear();
    }
    if (!g.markers.empty()) {
      if (!layer) layer = std::make_unique<MarkerLayer>(lw, lh);
      Color c = s.color;
      for (std::size_t j = 0; j < g.markers.size(); ++j) {
        if (!g.marker_alpha.empty()) c.a = g.marker_alpha[j];
        layer->Stamp(s.marker, s.marker_size_px * z_.s, g.markers[j].x - p.x0,
                     g.markers[j].y - p.y0, c);
      }
    }
  }
  flush_layer();
  gl->ClearClip();
}

// Frame, tick marks and the panel's legend box.
void Plot2D::DrawFrame(const PanelState& ps, GlCanvas* gl) {
  Mesh mesh;
  const Rect& p = ps.plot;
  const float frame_w = std::max(1.0f, std::round(z_.s));
  const float fx0 = Snap(p.x0) - 1.0f, fy0 = Snap(p.y0) - 1.0f;
  const float fx1 = Snap(p.x1), fy1 = Snap(p.y1);
  AddRectOutline(fx0, fy0, fx1, fy1, frame_w, kFrameColor, &mesh);
  for (double v : ps.xt.values) {
    const float x = Snap(static_cast<float>(ps.xm.Map(v)));
    AddRect(x - 0.5f * frame_w, fy1, x + 0.5f * frame_w, fy1 + z_.tick_len, 0, kFrameColor,
            &mesh);
  }
  for (double v : ps.yt.values) {
    const float y = Snap(static_cast<float>(ps.ym.Map(v)));
    AddRect(fx0 - z_.tick_len, y - 0.5f * frame_w, fx0, y + 0.5f * frame_w, 0, kFrameColor,
            &mesh);
  }
  gl->Draw(mesh);
  mesh.clear();
  if (!ps.legend.empty()) {
    ps.legend.DrawShapes(ps.legend_x, ps.legend_y, &mesh);
    gl->Draw(mesh);
  }
}

void Plot2D::DrawText(Image* img) {
  const float W = static_cast<float>(f_.width_px);
  if (!f_.title.empty()) {
    text_->Draw(img, f_.title, 0.5f * W, title_y_, {z_.title_px, true, kTitleColor},
                HAlign::kCenter, VAlign::kTop);
  }
  if (!legend_row_.empty()) legend_row_.DrawLabels(legend_row_y_, text_, img);
  const TextStyle tick{z_.tick_px, false, kTickLabelColor};
  const TextStyle label{z_.label_px, false, kLabelColor};
  const float label_lh = text_->LineHeight(z_.label_px);
  for (const PanelState& ps : ps_) {
    const Rect& p = ps.plot;
    const Panel& panel = *ps.panel;
    float title_bottom = p.y0 - 5.0f * z_.s;
    if (!panel.note.empty()) {
      // One line, shrunk if it is wider than the plot.
      const float w = text_->Width(panel.note, NotePx());
      const float px = w > p.w() ? NotePx() * p.w() / w : NotePx();
      text_->Draw(img, panel.note, 0.5f * (p.x0 + p.x1), title_bottom, {px, false, kNoteColor},
                  HAlign::kCenter, VAlign::kBottom);
      title_bottom -= text_->LineHeight(NotePx()) + 2.0f * z_.s;
    }
    if (!panel.title.empty()) {
      text_->Draw(img, panel.title, 0.5f * (p.x0 + p.x1), title_bottom,
                  {z_.panel_title_px, true, kTitleColor}, HAlign::kCenter, VAlign::kBottom);
    }
    // y tick labels, right-aligned left of the tick marks.
    for (std::size_t k = 0; k < ps.yt.values.size(); ++k) {
      const float y = static_cast<float>(ps.ym.Map(ps.yt.values[k]));
      text_->Draw(img, ps.yt.labels[k], p.x0 - 1.0f - z_.tick_len - z_.pad, y, tick, HAlign::kRight,
                  VAlign::kMiddle);
    }
    if (!ps.yt.exponent.empty()) {
      text_->Draw(img, ps.yt.exponent, p.x0, p.y0 - 5.0f * z_.s, tick, HAlign::kLeft,
                  VAlign::kBottom);
    }
    const std::string ytitle = AxisTitle(panel.y);
    if (!ytitle.empty()) {
      const float x = p.x0 - ps.left + 2.0f * z_.s;
      text_->Draw(img, ytitle, x, 0.5f * (p.y0 + p.y1), label, HAlign::kLeft, VAlign::kMiddle,
                  true);
    }
    const float tick_top = p.y1 + z_.tick_len + z_.pad;
    if (ps.show_x_ticklabels) {
      for (std::size_t k = 0; k < ps.xt.values.size(); ++k) {
        const float x = static_cast<float>(ps.xm.Map(ps.xt.values[k]));
        text_->Draw(img, ps.xt.labels[k], x, tick_top, tick, HAlign::kCenter, VAlign::kTop);
      }
      if (!ps.xt.exponent.empty()) {
        text_->Draw(img, ps.xt.exponent, p.x1, tick_top + text_->LineHeight(z_.tick_px), tick,
                    HAlign::kRight, VAlign::kTop);
      }
    }
    if (ps.show_x_label) {
      const float y = ps.cell.y1 - label_lh;
      text_->Draw(img, AxisTitle(panel.x), 0.5f * (p.x0 + p.x1), y, label, HAlign::kCenter,
                  VAlign::kTop);
    }
    if (!ps.has_data) {
      text_->Draw(img, "no data", 0.5f * (p.x0 + p.x1), 0.5f * (p.y0 + p.y1),
                  {z_.label_px, false, kNoDataColor}, HAlign::kCenter, VAlign::kMiddle);
    }
    DrawBandLabels(ps, img);
    if (!ps.legend.empty()) ps.legend.DrawLabels(ps.legend_x, ps.legend_y, text_, img);
  }
}

void Plot2D::DrawBandLabels(const PanelState& ps, Image* img) {
  for (const Band& b : ps.panel->bands) {
    Rect r;
    if (b.label.empty() || !BandRect(ps, b, &r)) continue;
    text_->Draw(img, b.label, r.x0 + 3.0f * z_.s, r.y0 + 3.0f * z_.s,
                {NotePx(), false, kNoteColor}, HAlign::kLeft, VAlign::kTop);
  }
}

}  // namespace

bool RenderImage(const Figure2D& figure, Image* out, std::string* err) {
  if (!out) {
    if (err) *err = "RenderImage: no output image given";
    return false;
  }
  if (!Validate(figure, err)) return false;
  TextRenderer text;
  if (!text.Load(figure.font_path, figure.bold_font_path, err)) return false;
  Plot2D plot(figure, &text);
  return plot.Render(out, err);
}

}  // namespace shoal::render
