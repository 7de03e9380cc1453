// Tessellation of strokes and markers into triangles in pixel space (internal to
// shoal_render). Coordinates: x right, y down, in pixels of the final image; z is the
// normalised depth in [-1, 1] (3-D figures) or 0.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "render/figure.h"

namespace shoal::render {

struct Vec2 {
  float x = 0.0f, y = 0.0f;
};

/// Interleaved triangle list: 3 floats of position and 4 bytes of colour per vertex.
struct Mesh {
  std::vector<float> xyz;
  std::vector<std::uint8_t> rgba;

  std::size_t vertices() const { return xyz.size() / 3; }
  bool empty() const { return xyz.empty(); }
  void clear() {
    xyz.clear();
    rgba.clear();
  }
  void Vertex(float x, float y, float z, const std::uint8_t c[4]) {
    xyz.insert(xyz.end(), {x, y, z});
    rgba.insert(rgba.end(), {c[0], c[1], c[2], c[3]});
  }
  void Triangle(Vec2 a, Vec2 b, Vec2 c, float za, float zb, float zc, const std::uint8_t col[4]) {
    Vertex(a.x, a.y, za, col);
    Vertex(b.x, b.y, zb, col);
    Vertex(c.x, c.y, zc, col);
  }
};

void ToBytes(const Color& c, std::uint8_t out[4]);

/// Dash pattern (on, off lengths in pixels) of a line style at a line width; {0, 0} for
/// solid lines.
void DashPattern(LineStyle style, float width_px, float* on_px, float* off_px);

/// A stroked polyline of `n` points (z may be null: depth 0) with bevel joins and butt ends,
/// solid or dashed. Consecutive duplicate points are skipped. `phase` carries the dash
/// phase between calls (may be null).
void StrokePolyline(const Vec2* p, const float* z, std::size_t n, float width_px, LineStyle style,
                    const Color& color, Mesh* mesh, float* phase = nullptr);

/// A filled (or, for cross / plus / bar, stroked) marker of outer size `size_px` centred at c.
void AddMarker(Vec2 c, float z, Marker marker, float size_px, const Color& color, Mesh* mesh);

/// A filled disc and a ring (annulus between r_in and r_out).
void AddDisc(Vec2 c, float z, float radius, const Color& color, Mesh* mesh);
void AddRing(Vec2 c, float z, float r_in, float r_out, const Color& color, Mesh* mesh);

/// Axis-aligned filled rectangle [x0, x1] x [y0, y1].
void AddRect(float x0, float y0, float x1, float y1, float z, const Color& color, Mesh* mesh);

/// Outline of a rectangle, the line centred on its border.
void AddRectOutline(float x0, float y0, float x1, float y1, float width_px, const Color& color,
                    Mesh* mesh);

/// A convex polygon (fan from the first vertex).
void AddConvexPolygon(const Vec2* p, const float* z, std::size_t n, const Color& color, Mesh* mesh);

}  // namespace shoal::render
