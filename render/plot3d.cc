// Figure3D: a perspective view of 3-D polylines and formation snapshots inside a box with
// back panes, grid lines, ticks and labels.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>

#include "render/decimate.h"
#include "render/figure.h"
#include "render/geometry.h"
#include "render/gl_canvas.h"
#include "render/legend.h"
#include "render/text.h"
#include "render/ticks.h"

namespace shoal::render {
namespace {

using V3 = std::array<double, 3>;

const Color kTitleColor{0.08f, 0.08f, 0.08f, 1.0f};
const Color kLabelColor{0.12f, 0.12f, 0.12f, 1.0f};
const Color kTickLabelColor{0.22f, 0.22f, 0.22f, 1.0f};
const Color kPaneColor{0.955f, 0.957f, 0.962f, 1.0f};
const Color kPaneEdgeColor{0.70f, 0.70f, 0.72f, 1.0f};
const Color kGridColor{0.85f, 0.85f, 0.87f, 1.0f};
const Color kAxisColor{0.35f, 0.35f, 0.35f, 1.0f};
const Color kSeaColor{0.35f, 0.62f, 0.85f, 0.16f};
const Color kSeaEdgeColor{0.35f, 0.62f, 0.85f, 0.7f};

constexpr double kPi = 3.14159265358979323846;

V3 Sub(const V3& a, const V3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double Dot(const V3& a, const V3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
V3 Cross(const V3& a, const V3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
V3 Normalized(const V3& a) {
  const double n = std::sqrt(Dot(a, a));
  return n > 0 ? V3{a[0] / n, a[1] / n, a[2] / n} : a;
}
bool Finite(const Point3& p) {
  return std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]);
}

Color Mix(const Color& a, const Color& b, float t) {
  return {a.r + (b.r - a.r) * t, a.g + (b.g - a.g) * t, a.b + (b.b - a.b) * t, 1.0f};
}

struct Projected {
  float x = 0, y = 0, z = 0;
  bool ok = false;
};

struct AxisLabels {
  std::vector<double> world;  // positions along the world axis
  std::vector<std::string> labels;
  int axis = 0;       // world axis index
  V3 edge_a, edge_b;  // display coordinates of the labelled edge's ends
  V3 outward;         // display direction away from the box
  std::string title;
  // Screen placement.
  Vec2 dir{0, 0};
  std::vector<Vec2> label_pos;  // centres
  std::vector<Vec2> tick_at;
  Vec2 title_pos{0, 0};
  bool title_rotated = false;
};

class Plot3D {
 public:
  Plot3D(const Figure3D& f, TextRenderer* text) : f_(f), text_(text) {}
  bool Render(Image* out, std::string* err);

 private:
  V3 World(const Point3& p) const {
    return {sign_[0] * p[perm_[0]], sign_[1] * p[perm_[1]], sign_[2] * p[perm_[2]]};
  }
  V3 Display(const V3& w) const {
    return {(w[0] - c_[0]) * sc_[0], (w[1] - c_[1]) * sc_[1], (w[2] - c_[2]) * sc_[2]};
  }
  // Camera-space (x, y, depth) of a display point.
  V3 Camera(const V3& q) const {
    const V3 v = Sub(q, eye_);
    return {Dot(v, right_), Dot(v, up_), Dot(v, fwd_)};
  }
  Projected Project(const V3& q) const {
    const V3 c = Camera(q);
    Projected p;
    if (!(c[2] > 1e-6)) return p;
    p.x = static_cast<float>(ox_ + k_ * c[0] / c[2]);
    p.y = static_cast<float>(oy_ - k_ * c[1] / c[2]);
    p.z = static_cast<float>(((1.0 / c[2]) - inv_near_) / (inv_far_ - inv_near_) * 2.0 - 1.0);
    p.ok = std::isfinite(p.x) && std::isfinite(p.y);
    return p;
  }
  Vec2 P2(const V3& q) const {
    const Projected p = Project(q);
    return {p.x, p.y};
  }

  void SetUpWorld();
  void SetAxisTitles();
  void SetUpCamera();
  void Fit(const Rect& area);
  void MakeAxes();
  void PlaceAxisLabels();
  Rect LabelBounds() const;
  void BuildLines();
  void PlaceLegend(const Rect& area);

  void DrawGeometry(GlCanvas* gl);
  void DrawBox(GlCanvas* gl);
  void DrawData(GlCanvas* gl);
  void DrawMarkers(GlCanvas* gl);
  void DrawSeaSurface(GlCanvas* gl);
  void Segment(const V3& a, const V3& b, float w, const Color& c, Mesh* mesh) const {
    const Vec2 l[2] = {P2(a), P2(b)};
    StrokePolyline(l, nullptr, 2, w, LineStyle::kSolid, c, mesh);
  }
  void DrawText(Image* img);
  void Halo(Image* img, const std::string& s, float x, float y, const TextStyle& st, HAlign h,
            VAlign v);

  const Figure3D& f_;
  TextRenderer* text_;
  float s_ = 1.0f;
  float tick_px_ = 13.5f, label_px_ = 14.5f, title_px_ = 22.0f;
  int perm_[3] = {0, 1, 2};
  double sign_[3] = {1, 1, 1};
  std::string axis_title_[3];
  double lo_[3] = {0, 0, 0}, hi_[3] = {1, 1, 1};  // world box
  double c_[3] = {0, 0, 0}, sc_[3] = {1, 1, 1};
  double half_[3] = {1, 1, 1};  // display half-extents of the box
  bool sea_ = false;            // the sea surface is drawn
  V3 eye_{}, fwd_{}, right_{}, up_{};
  double k_ = 1, ox_ = 0, oy_ = 0, inv_near_ = 1, inv_far_ = 0.5;
  int back_[3] = {0, 0, 0};  // per axis: -1 if the back pane is at the low end, +1 at the high end
  std::array<AxisLabels, 3> axes_;
  std::vector<std::vector<std::vector<Projected>>> lines_;  // per polyline, runs
  std::vector<std::vector<std::vector<Vec2>>> shadows_;
  LegendMetrics lm_;
  LegendBox legend_;
  float legend_x_ = 0, legend_y_ = 0;
  float title_y_ = 0;
};

void Plot3D::SetUpWorld() {
  if (f_.z_down) {
    // NED -> (east, north, up): right-handed, up on the screen.
    perm_[0] = 1;
    perm_[1] = 0;
    perm_[2] = 2;
    sign_[0] = 1;
    sign_[1] = 1;
    sign_[2] = -1;
  }
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  const auto add = [&](const Point3& p) {
    if (!Finite(p)) return;
    const V3 w = World(p);
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], w[k]);
      hi[k] = std::max(hi[k], w[k]);
    }
  };
  for (const Polyline3D& l : f_.lines) {
    for (const Point3& p : l.points) add(p);
  }
  for (const Snapshot& s : f_.snapshots) {
    for (const Point3& p : s.points) add(p);
  }
  double lmax = 0.0;
  for (int k = 0; k < 3; ++k) lmax = std::max(lmax, hi[k] - lo[k]);
  if (!(lmax > 0.0)) lmax = 2.0;
  for (int k = 0; k < 3; ++k) {
    double l = hi[k] - lo[k];
    if (l < 1e-9 * lmax) {
      const double d = std::max(0.05 * lmax, 1.0);
      lo[k] -= d;
      hi[k] += d;
      l = hi[k] - lo[k];
    }
    const double pad = 0.03 * std::max(l, 0.25 * lmax);
    lo_[k] = lo[k] - pad;
    hi_[k] = hi[k] + pad;
  }
  lmax = 0.0;
  for (int k = 0; k < 3; ++k) lmax = std::max(lmax, hi_[k] - lo_[k]);
  for (int k = 0; k < 3; ++k) {
    const double l = hi_[k] - lo_[k];
    const double shown = f_.equal_aspect ? std::max(l, 0.25 * lmax) : lmax;
    c_[k] = 0.5 * (lo_[k] + hi_[k]);
    sc_[k] = 2.0 * shown / (l * lmax);  // display extent: [-shown/lmax, shown/lmax]
    half_[k] = shown / lmax;
  }
  SetAxisTitles();
  sea_ = f_.z_down && f_.sea_surface && lo_[2] <= 0.0 && hi_[2] >= 0.0;
}

// Axis titles with the unit, and how much an axis is stretched against the longest one
// (so that a reader does not take a stretched depth for a steep dive).
void Plot3D::SetAxisTitles() {
  const std::string unit = f_.unit.empty() ? "" : " [" + f_.unit + "]";
  const std::string data_titles[3] = {f_.x_label, f_.y_label, f_.z_label};
  double metres_per_unit_max = 0.0;
  for (int k = 0; k < 3; ++k) metres_per_unit_max = std::max(metres_per_unit_max, 1.0 / sc_[k]);
  for (int k = 0; k < 3; ++k) {
    axis_title_[k] = data_titles[perm_[k]] + unit;
    const double stretch = metres_per_unit_max * sc_[k];
    if (stretch > 1.05) {
      char buf[48];
      std::snprintf(buf, sizeof buf, ", stretched \xC3\x97%.2g", stretch);  // ×
      axis_title_[k] += buf;
    }
  }
}

// Automatic bearing: 300 degrees, or 60 degrees off the main horizontal direction of the
// lines' points when there is one.
double AutoAzimuthDeg(const Figure3D& f) {
  double n = 0, mx = 0, my = 0;
  for (const Polyline3D& l : f.lines) {
    for (const Point3& p : l.points) {
      if (!Finite(p)) continue;
      n += 1;
      mx += p[0];
      my += p[1];
    }
  }
  const double kDefault = 300.0;
  if (n < 2) return kDefault;
  mx /= n;
  my /= n;
  double sxx = 0, syy = 0, sxy = 0;
  for (const Polyline3D& l : f.lines) {
    for (const Point3& p : l.points) {
      if (!Finite(p)) continue;
      sxx += (p[0] - mx) * (p[0] - mx);
      syy += (p[1] - my) * (p[1] - my);
      sxy += (p[0] - mx) * (p[1] - my);
    }
  }
  const double tr = sxx + syy, det = sxx * syy - sxy * sxy;
  const double disc = std::sqrt(std::max(0.0, 0.25 * tr * tr - det));
  const double l1 = 0.5 * tr + disc, l2 = 0.5 * tr - disc;
  if (!(l1 > 0) || l1 < 1.5 * 1.5 * std::max(l2, 0.0)) return kDefault;  // std devs < 1.5x apart
  // Main direction as a bearing from +x towards +y.
  const double main = std::atan2(2.0 * sxy, sxx - syy) * 0.5 * 180.0 / kPi;
  // Of the four views at 60 degrees to it, the one nearest the default.
  double best = kDefault, best_d = 1e9;
  for (double c : {main + 60, main - 60, main + 120, main - 120}) {
    const double b = std::fmod(std::fmod(c, 360.0) + 360.0, 360.0);
    const double d = std::fabs(std::remainder(b - kDefault, 360.0));
    if (d < best_d) {
      best_d = d;
      best = b;
    }
  }
  return best;
}

void Plot3D::SetUpCamera() {
  const double az_deg = std::isnan(f_.azimuth_deg) ? AutoAzimuthDeg(f_) : f_.azimuth_deg;
  const double az = az_deg * kPi / 180.0, el = f_.elevation_deg * kPi / 180.0;
  V3 horizontal;
  if (f_.z_down) {
    horizontal = {std::sin(az), std::cos(az), 0.0};  // bearing from north towards east
  } else {
    horizontal = {std::cos(az), std::sin(az), 0.0};  // from +x towards +y
  }
  const V3 dir{horizontal[0] * std::cos(el), horizontal[1] * std::cos(el), std::sin(el)};
  const double dist = 4.5;  // mild perspective
  eye_ = {dir[0] * dist, dir[1] * dist, dir[2] * dist};
  fwd_ = Normalized({-dir[0], -dir[1], -dir[2]});
  right_ = Normalized(Cross(fwd_, V3{0, 0, 1}));
  up_ = Cross(right_, fwd_);
  for (int k = 0; k < 3; ++k) back_[k] = eye_[k] > 0 ? -1 : 1;
  // Depth range of the box.
  double zmin = INFINITY, zmax = 0;
  for (int i = 0; i < 8; ++i) {
    const V3 q{(i & 1 ? 1 : -1) * half_[0], (i & 2 ? 1 : -1) * half_[1],
               (i & 4 ? 1 : -1) * half_[2]};
    const double z = Camera(q)[2];
    zmin = std::min(zmin, z);
    zmax = std::max(zmax, z);
  }
  inv_near_ = 1.0 / (0.8 * zmin);
  inv_far_ = 1.0 / (1.25 * zmax);
}

void Plot3D::Fit(const Rect& area) {
  double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
  for (int i = 0; i < 8; ++i) {
    const V3 q{(i & 1 ? 1 : -1) * half_[0], (i & 2 ? 1 : -1) * half_[1],
               (i & 4 ? 1 : -1) * half_[2]};
    const V3 c = Camera(q);
    x0 = std::min(x0, c[0] / c[2]);
    x1 = std::max(x1, c[0] / c[2]);
    y0 = std::min(y0, c[1] / c[2]);
    y1 = std::max(y1, c[1] / c[2]);
  }
  k_ = std::min(area.w() / (x1 - x0), area.h() / (y1 - y0));
  ox_ = 0.5 * (area.x0 + area.x1) - k_ * 0.5 * (x0 + x1);
  oy_ = 0.5 * (area.y0 + area.y1) + k_ * 0.5 * (y0 + y1);
}

void Plot3D::MakeAxes() {
  // Front floor edges carry the two horizontal axes; a side vertical edge the third.
  const double floor_z = -half_[2];
  const double front[2] = {back_[0] < 0 ? half_[0] : -half_[0],
                           back_[1] < 0 ? half_[1] : -half_[1]};
  const double backv[2] = {-front[0], -front[1]};
  // Axis 0 (world x): the floor edge at y = front y.
  axes_[0].axis = 0;
  axes_[0].edge_a = {-half_[0], front[1], floor_z};
  axes_[0].edge_b = {half_[0], front[1], floor_z};
  axes_[0].outward = {0, front[1] > 0 ? 1.0 : -1.0, 0};
  axes_[1].axis = 1;
  axes_[1].edge_a = {front[0], -half_[1], floor_z};
  axes_[1].edge_b = {front[0], half_[1], floor_z};
  axes_[1].outward = {front[0] > 0 ? 1.0 : -1.0, 0, 0};
  // Vertical: of the two silhouette corners, the one further left on the screen.
  const V3 c1{front[0], backv[1], floor_z}, c2{backv[0], front[1], floor_z};
  const V3 corner = P2(c1).x <= P2(c2).x ? c1 : c2;
  axes_[2].axis = 2;
  axes_[2].edge_a = {corner[0], corner[1], -half_[2]};
  axes_[2].edge_b = {corner[0], corner[1], half_[2]};
  axes_[2].outward = Normalized({corner[0] > 0 ? 1.0 : -1.0, corner[1] > 0 ? 1.0 : -1.0, 0});
  for (int k = 0; k < 3; ++k) axes_[k].title = axis_title_[k];
}

void Plot3D::PlaceAxisLabels() {
  const float tick_len = 6.0f * s_, pad = 5.0f * s_;
  const float lh = text_->LineHeight(tick_px_);
  for (AxisLabels& a : axes_) {
    const int k = a.axis;
    // Ticks in data units (value = sign * world).
    const double dlo = sign_[k] > 0 ? lo_[k] : -hi_[k];
    const double dhi = sign_[k] > 0 ? hi_[k] : -lo_[k];
    const Vec2 pa = P2(a.edge_a), pb = P2(a.edge_b);
    const float edge_px = std::hypot(pb.x - pa.x, pb.y - pa.y);
    const Vec2 along{(pb.x - pa.x) / std::max(edge_px, 1e-3f),
                     (pb.y - pa.y) / std::max(edge_px, 1e-3f)};
    for (int n = 7;; --n) {
      const TickSet ts = LinearTicks(dlo, dhi, n);
      a.world.clear();
      a.labels.clear();
      float need = 0.0f;
      for (double v : ts.major) {
        a.world.push_back(sign_[k] * v);
        a.labels.push_back(FormatLinearTick(v, ts.step));
        // Space a label takes along the edge.
        const float w = text_->Width(a.labels.back(), tick_px_);
        need = std::max(need, std::fabs(along.x) * w + std::fabs(along.y) * lh);
      }
      const float spacing =
          ts.major.size() > 1 ? edge_px * static_cast<float>(ts.step / (dhi - dlo)) : edge_px;
      if (n <= 2 || spacing >= need + 20.0f * s_) break;
    }
    // Screen direction away from the box at the edge's middle.
    const V3 mid{0.5 * (a.edge_a[0] + a.edge_b[0]), 0.5 * (a.edge_a[1] + a.edge_b[1]),
                 0.5 * (a.edge_a[2] + a.edge_b[2])};
    const V3 out{mid[0] + 0.2 * a.outward[0], mid[1] + 0.2 * a.outward[1],
                 mid[2] + 0.2 * a.outward[2]};
    const Vec2 m0 = P2(mid), m1 = P2(out);
    float dx = m1.x - m0.x, dy = m1.y - m0.y;
    const float dn = std::hypot(dx, dy);
    a.dir = dn > 0 ? Vec2{dx / dn, dy / dn} : Vec2{0, 1};
    const auto extent = [](float w, float h, Vec2 d) {
      const float ex = std::fabs(d.x) > 1e-6f ? 0.5f * w / std::fabs(d.x) : INFINITY;
      const float ey = std::fabs(d.y) > 1e-6f ? 0.5f * h / std::fabs(d.y) : INFINITY;
      return std::min(ex, ey);
    };
    a.label_pos.clear();
    a.tick_at.clear();
    float max_reach = 0.0f;
    for (std::size_t i = 0; i < a.world.size(); ++i) {
      V3 w = a.edge_a;
      w[static_cast<std::size_t>(k)] = (a.world[i] - c_[k]) * sc_[k];
      const Vec2 p = P2(w);
      a.tick_at.push_back(p);
      const float wl = text_->Width(a.labels[i], tick_px_);
      const float e = extent(wl, lh * 0.8f, a.dir);
      const float r = tick_len + pad + e;
      a.label_pos.push_back({p.x + a.dir.x * r, p.y + a.dir.y * r});
      max_reach = std::max(max_reach, r + e);
    }
    // The title beyond the tick labels; vertical axes get a rotated title.
    const Vec2 mp = P2(mid);
    a.title_rotated = k == 2;
    const float tw = text_->Width(a.title, label_px_), th = text_->LineHeight(label_px_);
    const float e = a.title_rotated ? extent(th, tw, a.dir) : extent(tw, th, a.dir);
    const float r = max_reach + 2.0f * pad + e;
    a.title_pos = {mp.x + a.dir.x * r, mp.y + a.dir.y * r};
  }
}

Rect Plot3D::LabelBounds() const {
  Rect b{INFINITY, INFINITY, -INFINITY, -INFINITY};
  const auto add = [&](float x0, float y0, float x1, float y1) {
    b.x0 = std::min(b.x0, x0);
    b.y0 = std::min(b.y0, y0);
    b.x1 = std::max(b.x1, x1);
    b.y1 = std::max(b.y1, y1);
  };
  for (int i = 0; i < 8; ++i) {
    const V3 q{(i & 1 ? 1 : -1) * half_[0], (i & 2 ? 1 : -1) * half_[1],
               (i & 4 ? 1 : -1) * half_[2]};
    const Vec2 p = P2(q);
    add(p.x, p.y, p.x, p.y);
  }
  const float lh = text_->LineHeight(tick_px_);
  for (const AxisLabels& a : axes_) {
    for (std::size_t i = 0; i < a.labels.size(); ++i) {
      const float w = text_->Width(a.labels[i], tick_px_);
      add(a.label_pos[i].x - 0.5f * w, a.label_pos[i].y - 0.5f * lh, a.label_pos[i].x + 0.5f * w,
          a.label_pos[i].y + 0.5f * lh);
    }
    const float tw = text_->Width(a.title, label_px_), th = text_->LineHeight(label_px_);
    const float hw = 0.5f * (a.title_rotated ? th : tw), hh = 0.5f * (a.title_rotated ? tw : th);
    add(a.title_pos.x - hw, a.title_pos.y - hh, a.title_pos.x + hw, a.title_pos.y + hh);
  }
  return b;
}

void Plot3D::BuildLines() {
  lines_.assign(f_.lines.size(), {});
  shadows_.assign(f_.lines.size(), {});
  std::vector<double> px, py;
  std::vector<Projected> proj;
  for (std::size_t li = 0; li < f_.lines.size(); ++li) {
    const Polyline3D& l = f_.lines[li];
    const std::size_t n = l.points.size();
    proj.assign(n, {});
    px.assign(n, NAN);
    py.assign(n, NAN);
    for (std::size_t i = 0; i < n; ++i) {
      if (!Finite(l.points[i])) continue;
      proj[i] = Project(Display(World(l.points[i])));
      if (!proj[i].ok) continue;
      px[i] = proj[i].x;
      py[i] = proj[i].y;
    }
    const IndexRuns runs = DecimateByDistance(px.data(), py.data(), n, 0.35);
    for (std::size_t r = 0; r < runs.runs(); ++r) {
      std::vector<Projected> run;
      std::vector<Vec2> shadow;
      for (std::size_t j = 0; j < runs.run_size(r); ++j) {
        const std::uint32_t i = runs.index[runs.start[r] + j];
        run.push_back(proj[i]);
        if (f_.floor_shadows) {
          V3 q = Display(World(l.points[i]));
          q[2] = -half_[2];
          shadow.push_back(P2(q));
        }
      }
      lines_[li].push_back(std::move(run));
      if (f_.floor_shadows) shadows_[li].push_back(std::move(shadow));
    }
  }
}

void Plot3D::PlaceLegend(const Rect& area) {
  std::vector<LegendEntry> entries;
  for (const Polyline3D& l : f_.lines) {
    if (!l.label.empty())
      entries.push_back({l.label, l.color, l.line, Marker::kNone, l.line_width_px});
  }
  for (const LegendEntry& e : f_.extra_legend) entries.push_back(e);
  if (sea_) {
    Color c = kSeaColor;
    c.a = 0.45f;
    entries.push_back({"sea surface, z = 0", c, LineStyle::kSolid, Marker::kNone, 8.0f});
  }
  if (entries.empty()) return;
  legend_ = LegendBox(entries, lm_, *text_, 1);
  const float w = legend_.width(), h = legend_.height();
  const Vec2 candidates[4] = {{area.x1 - w, area.y0},
                              {area.x0, area.y0},
                              {area.x1 - w, area.y1 - h},
                              {area.x0, area.y1 - h}};
  std::size_t best = std::numeric_limits<std::size_t>::max();
  for (const Vec2& c : candidates) {
    const Rect r{c.x - 4, c.y - 4, c.x + w + 4, c.y + h + 4};
    std::size_t hidden = 0;
    for (const auto& runs : lines_) {
      for (const auto& run : runs) {
        for (std::size_t i = 0; i + 1 < run.size(); ++i) {
          hidden += SegmentHitsRect({run[i].x, run[i].y}, {run[i + 1].x, run[i + 1].y}, r);
        }
      }
    }
    // Box edges and labels count too, less than data.
    for (int i = 0; i < 8; ++i) {
      const V3 q{(i & 1 ? 1 : -1) * half_[0], (i & 2 ? 1 : -1) * half_[1],
                 (i & 4 ? 1 : -1) * half_[2]};
      const Vec2 p = P2(q);
      hidden += r.Contains(p.x, p.y) ? 1 : 0;
    }
    for (const AxisLabels& a : axes_) {
      for (const Vec2& p : a.label_pos) hidden += r.Contains(p.x, p.y) ? 1 : 0;
      hidden += r.Contains(a.title_pos.x, a.title_pos.y) ? 1 : 0;
    }
    if (hidden < best) {
      best = hidden;
      legend_x_ = c.x;
      legend_y_ = c.y;
    }
  }
}

bool Plot3D::Render(Image* out, std::string* err) {
  s_ = f_.scale;
  if (s_ <= 0.0f) {
    s_ = std::sqrt(static_cast<float>(f_.width_px) * static_cast<float>(f_.height_px) /
                   (1400.0f * 1000.0f));
    s_ = std::clamp(s_, 0.75f, 3.0f);
  }
  tick_px_ = 13.5f * s_;
  label_px_ = 14.5f * s_;
  title_px_ = 22.0f * s_;
  lm_ = MakeLegendMetrics(*text_, s_);
  const float W = static_cast<float>(f_.width_px), H = static_cast<float>(f_.height_px);
  const float margin = 14.0f * s_;
  float top = margin;
  if (!f_.title.empty()) {
    title_y_ = top;
    top += text_->LineHeight(title_px_, true) + 6.0f * s_;
  }
  const Rect area{margin, top, W - margin, H - margin};

  SetUpWorld();
  SetUpCamera();
  // Fit the box, measure how far the labels stick out, and fit again inside what is left.
  Fit(area);
  MakeAxes();
  PlaceAxisLabels();
  for (int pass = 0; pass < 2; ++pass) {
    const Rect b = LabelBounds();
    // Label offsets do not scale with the box, so solve for the box size directly.
    Rect boxb{INFINITY, INFINITY, -INFINITY, -INFINITY};
    for (int i = 0; i < 8; ++i) {
      const V3 q{(i & 1 ? 1 : -1) * half_[0], (i & 2 ? 1 : -1) * half_[1],
                 (i & 4 ? 1 : -1) * half_[2]};
      const Vec2 p = P2(q);
      boxb.x0 = std::min(boxb.x0, p.x);
      boxb.x1 = std::max(boxb.x1, p.x);
      boxb.y0 = std::min(boxb.y0, p.y);
      boxb.y1 = std::max(boxb.y1, p.y);
    }
    const float extra_w = b.w() - boxb.w(), extra_h = b.h() - boxb.h();
    const double kx = (area.w() - extra_w) / boxb.w(), ky = (area.h() - extra_h) / boxb.h();
    const double grow = std::min(kx, ky);
    // New box rectangle, centred so that box plus labels are centred in the area.
    const float left_extra = boxb.x0 - b.x0, top_extra = boxb.y0 - b.y0;
    const float nbw = static_cast<float>(boxb.w() * grow),
                nbh = static_cast<float>(boxb.h() * grow);
    const float total_w = nbw + extra_w, total_h = nbh + extra_h;
    const float bx0 = area.x0 + 0.5f * (area.w() - total_w) + left_extra;
    const float by0 = area.y0 + 0.5f * (area.h() - total_h) + top_extra;
    Fit(Rect{bx0, by0, bx0 + nbw, by0 + nbh});
    MakeAxes();
    PlaceAxisLabels();
  }
  BuildLines();
  PlaceLegend(area);

  GlCanvas gl;
  if (!gl.Init(f_.width_px, f_.height_px, err)) return false;
  gl.Clear(Color{1, 1, 1, 1});
  DrawGeometry(&gl);
  if (!gl.Read(out, err)) return false;
  DrawText(out);
  return true;
}

void Plot3D::DrawGeometry(GlCanvas* gl) {
  DrawBox(gl);
  DrawData(gl);
  DrawMarkers(gl);
  DrawSeaSurface(gl);
  if (!legend_.empty()) {
    Mesh mesh;
    legend_.DrawShapes(legend_x_, legend_y_, &mesh);
    gl->Draw(mesh);
  }
}

// Back panes with grid lines, the lines' shadows on the floor, axis lines and ticks.
void Plot3D::DrawBox(GlCanvas* gl) {
  Mesh mesh;
  const float grid_w = std::max(1.0f, 1.0f * s_);
  // Back panes: x = back x, y = back y, the floor.
  const double bx = back_[0] * half_[0], by = back_[1] * half_[1], fz = -half_[2];
  const double hx = half_[0], hy = half_[1], hz = half_[2];
  const V3 panes[3][4] = {{{bx, -hy, -hz}, {bx, hy, -hz}, {bx, hy, hz}, {bx, -hy, hz}},
                          {{-hx, by, -hz}, {hx, by, -hz}, {hx, by, hz}, {-hx, by, hz}},
                          {{-hx, -hy, fz}, {hx, -hy, fz}, {hx, hy, fz}, {-hx, hy, fz}}};
  for (const auto& pane : panes) {
    Vec2 p[4];
    for (int i = 0; i < 4; ++i) p[i] = P2(pane[i]);
    AddConvexPolygon(p, nullptr, 4, kPaneColor, &mesh);
  }
  gl->Draw(mesh);
  mesh.clear();
  for (const AxisLabels& a : axes_) {
    const int k = a.axis;
    for (double wv : a.world) {
      const double d = (wv - c_[k]) * sc_[k];
      if (k == 0) {
        Segment({d, -hy, fz}, {d, hy, fz}, grid_w, kGridColor, &mesh);
        Segment({d, by, -hz}, {d, by, hz}, grid_w, kGridColor, &mesh);
      } else if (k == 1) {
        Segment({-hx, d, fz}, {hx, d, fz}, grid_w, kGridColor, &mesh);
        Segment({bx, d, -hz}, {bx, d, hz}, grid_w, kGridColor, &mesh);
      } else {
        Segment({bx, -hy, d}, {bx, hy, d}, grid_w, kGridColor, &mesh);
        Segment({-hx, by, d}, {hx, by, d}, grid_w, kGridColor, &mesh);
      }
    }
  }
  gl->Draw(mesh, GlCanvas::Depth::kOff, true);
  mesh.clear();
  for (const auto& pane : panes) {
    for (int i = 0; i < 4; ++i) Segment(pane[i], pane[(i + 1) % 4], grid_w, kPaneEdgeColor, &mesh);
  }
  gl->Draw(mesh);
  mesh.clear();
  for (std::size_t li = 0; li < shadows_.size(); ++li) {
    const Color c = Mix(f_.lines[li].color, kPaneColor, 0.75f);
    for (const auto& run : shadows_[li]) {
      StrokePolyline(run.data(), nullptr, run.size(), 1.6f * s_, LineStyle::kSolid, c, &mesh);
    }
    gl->Draw(mesh, GlCanvas::Depth::kOff, true);
    mesh.clear();
  }
  // Axis lines and tick marks (under the data).
  for (const AxisLabels& a : axes_) {
    Segment(a.edge_a, a.edge_b, 1.3f * s_, kAxisColor, &mesh);
    for (const Vec2& t : a.tick_at) {
      const Vec2 l[2] = {t, {t.x + a.dir.x * 6.0f * s_, t.y + a.dir.y * 6.0f * s_}};
      StrokePolyline(l, nullptr, 2, 1.3f * s_, LineStyle::kSolid, kAxisColor, &mesh);
    }
  }
  gl->Draw(mesh);
}

// Data with depth: the lines, then the snapshots' edges.
void Plot3D::DrawData(GlCanvas* gl) {
  Mesh mesh;
  for (std::size_t li = 0; li < lines_.size(); ++li) {
    const Polyline3D& l = f_.lines[li];
    for (const auto& run : lines_[li]) {
      std::vector<Vec2> p(run.size());
      std::vector<float> z(run.size());
      for (std::size_t i = 0; i < run.size(); ++i) {
        p[i] = {run[i].x, run[i].y};
        z[i] = run[i].z;
      }
      float phase = 0.0f;
      StrokePolyline(p.data(), z.data(), p.size(), l.line_width_px * s_, l.line, l.color, &mesh,
                     &phase);
    }
    gl->Draw(mesh, GlCanvas::Depth::kTestAndWrite);
    mesh.clear();
  }
  for (const Snapshot& snap : f_.snapshots) {
    for (const auto& e : snap.edges) {
      const Point3& a = snap.points[static_cast<std::size_t>(e.first)];
      const Point3& b = snap.points[static_cast<std::size_t>(e.second)];
      if (!Finite(a) || !Finite(b)) continue;
      const Projected pa = Project(Display(World(a))), pb = Project(Display(World(b)));
      if (!pa.ok || !pb.ok) continue;
      const Vec2 p[2] = {{pa.x, pa.y}, {pb.x, pb.y}};
      const float z[2] = {pa.z, pb.z};
      StrokePolyline(p, z, 2, snap.edge_width_px * s_, LineStyle::kSolid, snap.edge_color, &mesh);
    }
    gl->Draw(mesh, GlCanvas::Depth::kTestAndWrite, true);
    mesh.clear();
  }
}

// Snapshot discs, then the lines' start rings and end squares slightly towards the
// camera, each on a white halo. A start ring is wide enough to show a snapshot disc taken
// at the same point inside it.
void Plot3D::DrawMarkers(GlCanvas* gl) {
  Mesh mesh;
  const Color white{1, 1, 1, 1};
  for (const Snapshot& snap : f_.snapshots) {
    const float r = 0.5f * snap.marker_size_px * s_;
    for (std::size_t i = 0; i < snap.points.size(); ++i) {
      if (!Finite(snap.points[i])) continue;
      const Color c = snap.colors.empty() ? Color{0.5f, 0.5f, 0.5f, 1.0f} : snap.colors[i];
      const Projected p = Project(Display(World(snap.points[i])));
      if (!p.ok) continue;
      AddDisc({p.x, p.y}, p.z - 0.004f, r + 1.3f * s_, white, &mesh);
      AddDisc({p.x, p.y}, p.z - 0.006f, r, c, &mesh);
    }
  }
  const float ring_r = 8.5f * s_, ring_w = 2.6f * s_, square = 6.0f * s_;
  for (std::size_t li = 0; li < lines_.size(); ++li) {
    const Polyline3D& l = f_.lines[li];
    if (lines_[li].empty()) continue;
    const Projected a = lines_[li].front().front(), b = lines_[li].back().back();
    if (l.mark_start && a.ok) {
      AddRing({a.x, a.y}, a.z - 0.008f, ring_r - ring_w - 1.3f * s_, ring_r + 1.3f * s_, white,
              &mesh);
      AddRing({a.x, a.y}, a.z - 0.010f, ring_r - ring_w, ring_r, l.color, &mesh);
    }
    if (l.mark_end && b.ok) {
      const float h = square + 1.3f * s_;
      AddRect(b.x - h, b.y - h, b.x + h, b.y + h, b.z - 0.008f, white, &mesh);
      AddRect(b.x - square, b.y - square, b.x + square, b.y + square, b.z - 0.010f, l.color,
              &mesh);
    }
  }
  gl->Draw(mesh, GlCanvas::Depth::kTestAndWrite);
}

// The sea surface: a translucent plane at z = 0 over the box with its outline; what lies
// below it is seen through it, tinted.
void Plot3D::DrawSeaSurface(GlCanvas* gl) {
  if (!sea_) return;
  const double z = (0.0 - c_[2]) * sc_[2];
  const V3 q[4] = {{-half_[0], -half_[1], z},
                   {half_[0], -half_[1], z},
                   {half_[0], half_[1], z},
                   {-half_[0], half_[1], z}};
  Mesh mesh;
  Vec2 p[4];
  float pz[4];
  for (int i = 0; i < 4; ++i) {
    const Projected pr = Project(q[i]);
    p[i] = {pr.x, pr.y};
    pz[i] = pr.z;
  }
  AddConvexPolygon(p, pz, 4, kSeaColor, &mesh);
  gl->Draw(mesh, GlCanvas::Depth::kTest, true);
  mesh.clear();
  for (int i = 0; i < 4; ++i) Segment(q[i], q[(i + 1) % 4], 1.2f * s_, kSeaEdgeColor, &mesh);
  gl->Draw(mesh, GlCanvas::Depth::kOff, true);
}

void Plot3D::Halo(Image* img, const std::string& s, float x, float y, const TextStyle& st, HAlign h,
                  VAlign v) {
  TextStyle halo = st;
  halo.color = {1, 1, 1, 0.9f};
  for (int dx = -1; dx <= 1; ++dx) {
    for (int dy = -1; dy <= 1; ++dy) {
      if (dx != 0 || dy != 0)
        text_->Draw(img, s, x + static_cast<float>(dx), y + static_cast<float>(dy), halo, h, v);
    }
  }
  text_->Draw(img, s, x, y, st, h, v);
}

void Plot3D::DrawText(Image* img) {
  const float W = static_cast<float>(f_.width_px);
  if (!f_.title.empty()) {
    text_->Draw(img, f_.title, 0.5f * W, title_y_, {title_px_, true, kTitleColor}, HAlign::kCenter,
                VAlign::kTop);
  }
  const TextStyle tick{tick_px_, false, kTickLabelColor};
  const TextStyle label{label_px_, false, kLabelColor};
  // Axis titles first, then tick labels (vertical axis first); where two axes meet at a
  // corner, a tick label that would overlap one already placed is left out.
  std::vector<Rect> taken;
  const auto overlaps = [&](const Rect& r) {
    for (const Rect& t : taken) {
      if (r.x1 + 2 > t.x0 && r.x0 - 2 < t.x1 && r.y1 + 2 > t.y0 && r.y0 - 2 < t.y1) return true;
    }
    return false;
  };
  const float tick_lh = text_->LineHeight(tick_px_), label_lh = text_->LineHeight(label_px_);
  for (const AxisLabels& a : axes_) {
    text_->Draw(img, a.title, a.title_pos.x, a.title_pos.y, label, HAlign::kCenter, VAlign::kMiddle,
                a.title_rotated);
    const float tw = text_->Width(a.title, label_px_);
    const float hw = 0.5f * (a.title_rotated ? label_lh : tw);
    const float hh = 0.5f * (a.title_rotated ? tw : label_lh);
    taken.push_back(
        {a.title_pos.x - hw, a.title_pos.y - hh, a.title_pos.x + hw, a.title_pos.y + hh});
  }
  for (int k : {2, 0, 1}) {
    const AxisLabels& a = axes_[static_cast<std::size_t>(k)];
    for (std::size_t i = 0; i < a.labels.size(); ++i) {
      const float hw = 0.5f * text_->Width(a.labels[i], tick_px_), hh = 0.4f * tick_lh;
      const Rect r{a.label_pos[i].x - hw, a.label_pos[i].y - hh, a.label_pos[i].x + hw,
                   a.label_pos[i].y + hh};
      if (overlaps(r)) continue;
      taken.push_back(r);
      text_->Draw(img, a.labels[i], a.label_pos[i].x, a.label_pos[i].y, tick, HAlign::kCenter,
                  VAlign::kMiddle);
    }
  }
  // Snapshot labels: above-right, above-left, below-right or below-left of the first point,
  // whichever does not overlap a label already placed (or the legend); else none.
  const TextStyle snap_style{12.5f * s_, false, {0.25f, 0.25f, 0.25f, 1.0f}};
  if (!legend_.empty()) {
    taken.push_back(
        {legend_x_, legend_y_, legend_x_ + legend_.width(), legend_y_ + legend_.height()});
  }
  const float lh = text_->LineHeight(snap_style.size_px);
  for (const Snapshot& snap : f_.snapshots) {
    if (snap.label.empty() || !Finite(snap.points[0])) continue;
    const Projected p = Project(Display(World(snap.points[0])));
    if (!p.ok) continue;
    const float w = text_->Width(snap.label, snap_style.size_px);
    const float off = 0.5f * snap.marker_size_px * s_ + 3.0f * s_;
    const Rect candidates[4] = {{p.x + off, p.y - off - lh, p.x + off + w, p.y - off},
                                {p.x - off - w, p.y - off - lh, p.x - off, p.y - off},
                                {p.x + off, p.y + off, p.x + off + w, p.y + off + lh},
                                {p.x - off - w, p.y + off, p.x - off, p.y + off + lh}};
    for (const Rect& r : candidates) {
      bool clear = r.x0 >= 0 && r.y0 >= 0 && r.x1 <= static_cast<float>(f_.width_px) &&
                   r.y1 <= static_cast<float>(f_.height_px);
      for (const Rect& t : taken) {
        clear = clear && (r.x1 < t.x0 || r.x0 > t.x1 || r.y1 < t.y0 || r.y0 > t.y1);
      }
      if (!clear) continue;
      Halo(img, snap.label, r.x0, r.y0, snap_style, HAlign::kLeft, VAlign::kTop);
      taken.push_back(r);
      break;
    }
  }
  if (!legend_.empty()) legend_.DrawLabels(legend_x_, legend_y_, text_, img);
}

}  // namespace

bool RenderImage(const Figure3D& figure, Image* out, std::string* err) {
  if (!out) {
    if (err) *err = "RenderImage: no output image given";
    return false;
  }
  if (!Validate(figure, err)) return false;
  TextRenderer text;
  if (!text.Load(figure.font_path, figure.bold_font_path, err)) return false;
  Plot3D plot(figure, &text);
  return plot.Render(out, err);
}

}  // namespace shoal::render
