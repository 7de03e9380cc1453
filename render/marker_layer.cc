#include "render/marker_layer.h"

#include <algorithm>
#include <cmath>

namespace shoal::render {
namespace {

constexpr int kSub = 4;  // sub-pixel positions per axis

// Distance from p to the segment a-b.
float SegmentDistance(float px, float py, float ax, float ay, float bx, float by) {
  const float dx = bx - ax, dy = by - ay;
  const float len2 = dx * dx + dy * dy;
  float t = len2 > 0 ? ((px - ax) * dx + (py - ay) * dy) / len2 : 0.0f;
  t = std::clamp(t, 0.0f, 1.0f);
  const float qx = ax + t * dx - px, qy = ay + t * dy - py;
  return std::sqrt(qx * qx + qy * qy);
}

// The same shapes as AddMarker (geometry.cc), as inside tests relative to the centre.
bool Inside(Marker m, float size, float dx, float dy) {
  const float r = 0.5f * size;
  switch (m) {
    case Marker::kNone:
      return false;
    case Marker::kCircle:
      return dx * dx + dy * dy <= r * r;
    case Marker::kRing: {
      const float r_in = r - std::max(1.5f, size / 4.5f);
      const float d2 = dx * dx + dy * dy;
      return d2 <= r * r && d2 >= r_in * r_in;
    }
    case Marker::kSquare: {
      const float s = 0.85f * r;
      return std::fabs(dx) <= s && std::fabs(dy) <= s;
    }
    case Marker::kDiamond: {
      const float s = 1.1f * r;
      return std::fabs(dx) / (0.8f * s) + std::fabs(dy) / s <= 1.0f;
    }
    case Marker::kTriangle: {
      const float s = 1.15f * r;
      // Vertices (0, -s), (0.866 s, 0.5 s), (-0.866 s, 0.5 s); y down.
      if (dy > 0.5f * s) return false;
      const float k = 0.866f / 1.5f;  // half-width per unit of depth from the apex
      return std::fabs(dx) <= k * (dy + s);
    }
    case Marker::kCross:
    case Marker::kPlus: {
      const float w = std::max(1.5f, size / 4.5f);
      if (m == Marker::kCross) {
        const float s = 0.8f * r;
        return SegmentDistance(dx, dy, -s, -s, s, s) <= 0.5f * w ||
               SegmentDistance(dx, dy, -s, s, s, -s) <= 0.5f * w;
      }
      return (std::fabs(dy) <= 0.5f * w && std::fabs(dx) <= r) ||
             (std::fabs(dx) <= 0.5f * w && std::fabs(dy) <= r);
    }
    case Marker::kVBar: {
      const float w = std::max(1.5f, size / 5.0f);
      return std::fabs(dx) <= 0.5f * w && std::fabs(dy) <= r;
    }
  }
  return false;
}

}  // namespace

MarkerLayer::MarkerLayer(int w, int h)
    : w_(std::max(0, w)),
      h_(std::max(0, h)),
      rgba_(static_cast<std::size_t>(w_) * static_cast<std::size_t>(h_) * 4, 0.0f) {}

float MarkerLayer::Coverage(Marker m, float size_px, float cx, float cy, int px, int py) {
  int in = 0;
  for (int j = 0; j < 8; ++j) {
    for (int i = 0; i < 8; ++i) {
      const float sx = static_cast<float>(px) + (static_cast<float>(i) + 0.5f) / 8.0f;
      const float sy = static_cast<float>(py) + (static_cast<float>(j) + 0.5f) / 8.0f;
      in += Inside(m, size_px, sx - cx, sy - cy);
    }
  }
  return static_cast<float>(in) / 64.0f;
}

const MarkerLayer::Mask& MarkerLayer::GetMask(Marker m, float size_px, int sub_x, int sub_y) {
  const auto key = std::make_tuple(static_cast<int>(m),
                                   static_cast<int>(std::lround(size_px * 8.0f)), sub_x, sub_y);
  auto it = masks_.find(key);
  if (it != masks_.end()) return it->second;
  // Centre at (0.5 + sub/kSub) inside pixel (0, 0).
  const float cx = (static_cast<float>(sub_x) + 0.5f) / kSub;
  const float cy = (static_cast<float>(sub_y) + 0.5f) / kSub;
  const int reach = static_cast<int>(std::ceil(0.5f * size_px * 1.2f)) + 1;
  Mask mask;
  mask.x0 = -reach;
  mask.y0 = -reach;
  mask.w = mask.h = 2 * reach + 1;
  mask.a.assign(static_cast<std::size_t>(mask.w * mask.h), 0.0f);
  for (int j = 0; j < mask.h; ++j) {
    for (int i = 0; i < mask.w; ++i) {
      mask.a[static_cast<std::size_t>(j * mask.w + i)] =
          Coverage(m, size_px, cx, cy, mask.x0 + i, mask.y0 + j);
    }
  }
  return masks_.emplace(key, std::move(mask)).first->second;
}

void MarkerLayer::Stamp(Marker m, float size_px, float x, float y, const Color& c) {
  if (m == Marker::kNone || !std::isfinite(x) || !std::isfinite(y)) return;
  if (x < -size_px || y < -size_px || x > static_cast<float>(w_) + size_px ||
      y > static_cast<float>(h_) + size_px) {
    return;
  }
  // Pixel holding the centre and the sub-pixel position of the centre inside it.
  const float fx = std::floor(x), fy = std::floor(y);
  const int ix = static_cast<int>(fx), iy = static_cast<int>(fy);
  const int sx = std::min(kSub - 1, static_cast<int>((x - fx) * kSub));
  const int sy = std::min(kSub - 1, static_cast<int>((y - fy) * kSub));
  const Mask& mask = GetMask(m, size_px, sx, sy);
  const float alpha = std::clamp(c.a, 0.0f, 1.0f);
  for (int j = 0; j < mask.h; ++j) {
    const int py = iy + mask.y0 + j;
    if (py < 0 || py >= h_) continue;
    for (int i = 0; i < mask.w; ++i) {
      const int px = ix + mask.x0 + i;
      if (px < 0 || px >= w_) continue;
      const float a = mask.a[static_cast<std::size_t>(j * mask.w + i)] * alpha;
      if (a <= 0.0f) continue;
      float* p = &rgba_[(static_cast<std::size_t>(py) * static_cast<std::size_t>(w_) +
                         static_cast<std::size_t>(px)) *
                        4];
      const float keep = 1.0f - a;
      p[0] = c.r * a + p[0] * keep;
      p[1] = c.g * a + p[1] * keep;
      p[2] = c.b * a + p[2] * keep;
      p[3] = a + p[3] * keep;
    }
  }
  touched_ = true;
}

std::vector<std::uint8_t> MarkerLayer::ToBytes() const {
  std::vector<std::uint8_t> out(rgba_.size());
  for (std::size_t i = 0; i < rgba_.size(); ++i) {
    out[i] = static_cast<std::uint8_t>(std::lround(std::clamp(rgba_[i], 0.0f, 1.0f) * 255.0f));
  }
  return out;
}

}  // namespace shoal::render
