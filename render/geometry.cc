#include "render/geometry.h"

#include <algorithm>
#include <cmath>

namespace shoal::render {
namespace {

constexpr float kPi = 3.14159265358979f;

std::uint8_t Byte(float v) {
  return static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
}

Vec2 Add(Vec2 a, Vec2 b) { return {a.x + b.x, a.y + b.y}; }
Vec2 Sub(Vec2 a, Vec2 b) { return {a.x - b.x, a.y - b.y}; }
Vec2 Mul(Vec2 a, float s) { return {a.x * s, a.y * s}; }

void Quad(Vec2 a, Vec2 b, Vec2 c, Vec2 d, float za, float zb, float zc, float zd,
          const std::uint8_t col[4], Mesh* m) {
  m->Triangle(a, b, c, za, zb, zc, col);
  m->Triangle(a, c, d, za, zc, zd, col);
}

// A regular polygon approximating a disc, as a fan from its first vertex (n - 2 triangles).
void Fan(Vec2 c, float z, float r, int segments, const std::uint8_t col[4], Mesh* m) {
  const Vec2 first{c.x + r, c.y};
  Vec2 prev{c.x + r * std::cos(2.0f * kPi / static_cast<float>(segments)),
            c.y + r * std::sin(2.0f * kPi / static_cast<float>(segments))};
  for (int k = 2; k < segments; ++k) {
    const float a = 2.0f * kPi * static_cast<float>(k) / static_cast<float>(segments);
    const Vec2 cur{c.x + r * std::cos(a), c.y + r * std::sin(a)};
    m->Triangle(first, prev, cur, z, z, z, col);
    prev = cur;
  }
}

// Enough sides that the polygon deviates from the circle by well under 0.1 px.
int DiscSegments(float r) { return std::clamp(static_cast<int>(std::ceil(r * 2.0f)) + 4, 8, 48); }

// A solid polyline (no dashes): quads per segment, joins filled.
void StrokeSolid(const Vec2* p, const float* z, std::size_t n, float width,
                 const std::uint8_t col[4], Mesh* m) {
  const float h = 0.5f * width;
  const bool round = width >= 3.0f;
  bool have_prev = false;
  Vec2 prev_n{0, 0};
  std::size_t i = 0;
  // First point.
  while (i + 1 < n) {
    // Find next distinct point.
    std::size_t j = i + 1;
    while (j < n && std::fabs(p[j].x - p[i].x) < 1e-4f && std::fabs(p[j].y - p[i].y) < 1e-4f) ++j;
    if (j >= n) break;
    const Vec2 a = p[i], b = p[j];
    const float za = z ? z[i] : 0.0f, zb = z ? z[j] : 0.0f;
    const Vec2 d = Sub(b, a);
    const float len = std::sqrt(d.x * d.x + d.y * d.y);
    const Vec2 nrm{-d.y / len * h, d.x / len * h};
    Quad(Add(a, nrm), Add(b, nrm), Sub(b, nrm), Sub(a, nrm), za, zb, zb, za, col, m);
    if (have_prev) {
      const float cross = prev_n.x * nrm.y - prev_n.y * nrm.x;
      const float dot = prev_n.x * nrm.x + prev_n.y * nrm.y;
      // Only where the direction changes noticeably (> ~8 degrees).
      if (std::fabs(cross) > 0.14f * h * h || dot < 0.0f) {
        if (round) {
          Fan(a, za, h, DiscSegments(h), col, m);
        } else {
          m->Triangle(a, Add(a, prev_n), Add(a, nrm), za, za, za, col);
          m->Triangle(a, Sub(a, prev_n), Sub(a, nrm), za, za, za, col);
        }
      }
    }
    prev_n = nrm;
    have_prev = true;
    i = j;
  }
}

}  // namespace

void ToBytes(const Color& c, std::uint8_t out[4]) {
  out[0] = Byte(c.r);
  out[1] = Byte(c.g);
  out[2] = Byte(c.b);
  out[3] = Byte(c.a);
}

void DashPattern(LineStyle style, float width_px, float* on_px, float* off_px) {
  switch (style) {
    case LineStyle::kDashed:
      *on_px = 3.0f * width_px + 3.0f;
      *off_px = 2.0f * width_px + 2.0f;
      return;
    case LineStyle::kDotted:
      *on_px = std::max(1.0f, width_px);
      *off_px = 1.5f * width_px + 1.5f;
      return;
    default:
      *on_px = 0.0f;
      *off_px = 0.0f;
  }
}

void StrokePolyline(const Vec2* p, const float* z, std::size_t n, float width_px, LineStyle style,
                    const Color& color, Mesh* mesh, float* phase) {
  if (n < 2 || style == LineStyle::kNone || !(width_px > 0.0f)) return;
  std::uint8_t col[4];
  ToBytes(color, col);
  float on = 0.0f, off = 0.0f;
  DashPattern(style, width_px, &on, &off);
  if (on <= 0.0f) {
    StrokeSolid(p, z, n, width_px, col, mesh);
    return;
  }
  // Split into "on" pieces by arc length; each piece is stroked as a solid polyline.
  const float period = on + off;
  float s = phase ? std::fmod(*phase, period) : 0.0f;  // position within the pattern
  std::vector<Vec2> piece;
  std::vector<float> piece_z;
  const auto flush = [&] {
    if (piece.size() >= 2)
      StrokeSolid(piece.data(), piece_z.data(), piece.size(), width_px, col, mesh);
    piece.clear();
    piece_z.clear();
  };
  for (std::size_t i = 0; i + 1 < n; ++i) {
    const Vec2 a = p[i], b = p[i + 1];
    const float za = z ? z[i] : 0.0f, zb = z ? z[i + 1] : 0.0f;
    const Vec2 d = Sub(b, a);
    const float len = std::sqrt(d.x * d.x + d.y * d.y);
    if (len < 1e-6f) continue;
    float t = 0.0f;
    while (t < len) {
      const bool is_on = s < on;
      const float remaining = is_on ? on - s : period - s;
      const float step = std::min(remaining, len - t);
      if (is_on) {
        const float f0 = t / len, f1 = (t + step) / len;
        if (piece.empty()) {
          piece.push_back(Add(a, Mul(d, f0)));
          piece_z.push_back(za + (zb - za) * f0);
        }
        piece.push_back(Add(a, Mul(d, f1)));
        piece_z.push_back(za + (zb - za) * f1);
      }
      t += step;
      s += step;
      if (is_on && s >= on - 1e-6f) flush();
      if (s >= period - 1e-6f) s = 0.0f;
    }
  }
  flush();
  if (phase) *phase = s;
}

void AddDisc(Vec2 c, float z, float radius, const Color& color, Mesh* mesh) {
  std::uint8_t col[4];
  ToBytes(color, col);
  Fan(c, z, radius, DiscSegments(radius), col, mesh);
}

void AddRing(Vec2 c, float z, float r_in, float r_out, const Color& color, Mesh* mesh) {
  std::uint8_t col[4];
  ToBytes(color, col);
  const int seg = DiscSegments(r_out);
  for (int k = 0; k < seg; ++k) {
    const float a0 = 2.0f * kPi * static_cast<float>(k) / static_cast<float>(seg);
    const float a1 = 2.0f * kPi * static_cast<float>(k + 1) / static_cast<float>(seg);
    const Vec2 i0{c.x + r_in * std::cos(a0), c.y + r_in * std::sin(a0)};
    const Vec2 i1{c.x + r_in * std::cos(a1), c.y + r_in * std::sin(a1)};
    const Vec2 o0{c.x + r_out * std::cos(a0), c.y + r_out * std::sin(a0)};
    const Vec2 o1{c.x + r_out * std::cos(a1), c.y + r_out * std::sin(a1)};
    Quad(i0, o0, o1, i1, z, z, z, z, col, mesh);
  }
}

void AddRect(float x0, float y0, float x1, float y1, float z, const Color& color, Mesh* mesh) {
  std::uint8_t col[4];
  ToBytes(color, col);
  Quad({x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}, z, z, z, z, col, mesh);
}

void AddRectOutline(float x0, float y0, float x1, float y1, float w, const Color& color,
                    Mesh* mesh) {
  const float h = 0.5f * w;
  AddRect(x0 - h, y0 - h, x1 + h, y0 + h, 0, color, mesh);
  AddRect(x0 - h, y1 - h, x1 + h, y1 + h, 0, color, mesh);
  AddRect(x0 - h, y0 + h, x0 + h, y1 - h, 0, color, mesh);
  AddRect(x1 - h, y0 + h, x1 + h, y1 - h, 0, color, mesh);
}

void AddConvexPolygon(const Vec2* p, const float* z, std::size_t n, const Color& color,
                      Mesh* mesh) {
  if (n < 3) return;
  std::uint8_t col[4];
  ToBytes(color, col);
  for (std::size_t k = 1; k + 1 < n; ++k) {
    mesh->Triangle(p[0], p[k], p[k + 1], z ? z[0] : 0, z ? z[k] : 0, z ? z[k + 1] : 0, col);
  }
}

void AddMarker(Vec2 c, float z, Marker marker, float size, const Color& color, Mesh* mesh) {
  const float r = 0.5f * size;
  switch (marker) {
    case Marker::kNone:
      return;
    case Marker::kCircle:
      AddDisc(c, z, r, color, mesh);
      return;
    case Marker::kRing:
      AddRing(c, z, r - std::max(1.5f, size / 4.5f), r, color, mesh);
      return;
    case Marker::kSquare: {
      const float s = r * 0.85f;
      const Vec2 q[4] = {
          {c.x - s, c.y - s}, {c.x + s, c.y - s}, {c.x + s, c.y + s}, {c.x - s, c.y + s}};
      const float zz[4] = {z, z, z, z};
      AddConvexPolygon(q, zz, 4, color, mesh);
      return;
    }
    case Marker::kDiamond: {
      const float s = r * 1.1f;
      const Vec2 q[4] = {
          {c.x, c.y - s}, {c.x + s * 0.8f, c.y}, {c.x, c.y + s}, {c.x - s * 0.8f, c.y}};
      const float zz[4] = {z, z, z, z};
      AddConvexPolygon(q, zz, 4, color, mesh);
      return;
    }
    case Marker::kTriangle: {
      const float s = r * 1.15f;
      const Vec2 q[3] = {
          {c.x, c.y - s}, {c.x + s * 0.866f, c.y + s * 0.5f}, {c.x - s * 0.866f, c.y + s * 0.5f}};
      const float zz[3] = {z, z, z};
      AddConvexPolygon(q, zz, 3, color, mesh);
      return;
    }
    case Marker::kCross:
    case Marker::kPlus: {
      const float w = std::max(1.5f, size / 4.5f);
      const float s = marker == Marker::kCross ? r * 0.8f : r;
      Vec2 l1[2], l2[2];
      if (marker == Marker::kCross) {
        l1[0] = {c.x - s, c.y - s};
        l1[1] = {c.x + s, c.y + s};
        l2[0] = {c.x - s, c.y + s};
        l2[1] = {c.x + s, c.y - s};
      } else {
        l1[0] = {c.x - s, c.y};
        l1[1] = {c.x + s, c.y};
        l2[0] = {c.x, c.y - s};
        l2[1] = {c.x, c.y + s};
      }
      const float zz[2] = {z, z};
      StrokePolyline(l1, zz, 2, w, LineStyle::kSolid, color, mesh);
      StrokePolyline(l2, zz, 2, w, LineStyle::kSolid, color, mesh);
      return;
    }
    case Marker::kVBar: {
      const float w = std::max(1.5f, size / 5.0f);
      const Vec2 l[2] = {{c.x, c.y - r}, {c.x, c.y + r}};
      const float zz[2] = {z, z};
      StrokePolyline(l, zz, 2, w, LineStyle::kSolid, color, mesh);
      return;
    }
  }
}

}  // namespace shoal::render
