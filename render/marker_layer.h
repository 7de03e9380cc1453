// Many small markers drawn on the CPU into a premultiplied RGBA layer that the GL canvas
// then draws as one textured rectangle (internal to shoal_render). llvmpipe spends a few
// microseconds per triangle, so a scatter of 10^5 markers as polygons takes seconds; a
// stamp of a pre-computed anti-aliased coverage mask takes well under a microsecond.
#pragma once

#include <cstdint>
#include <map>
#include <tuple>
#include <vector>

#include "render/figure.h"

namespace shoal::render {

class MarkerLayer {
 public:
  /// A w x h layer, transparent.
  MarkerLayer(int w, int h);

  int width() const { return w_; }
  int height() const { return h_; }
  bool empty() const { return !touched_; }

  /// Composites marker `m` of outer size `size_px` centred at (x, y) (layer pixels, pixel
  /// centres at +0.5) over the layer ("over" operator).
  void Stamp(Marker m, float size_px, float x, float y, const Color& c);

  /// Premultiplied 8-bit RGBA, rows top to bottom.
  std::vector<std::uint8_t> ToBytes() const;

  /// Coverage (0..1) of marker m of size `size_px` centred at (cx, cy) over the pixel
  /// [px, px+1) x [py, py+1), by 8x8 supersampling. Exposed for tests.
  static float Coverage(Marker m, float size_px, float cx, float cy, int px, int py);

 private:
  struct Mask {
    int x0 = 0, y0 = 0, w = 0, h = 0;  // offset of the mask's corner from the centre pixel
    std::vector<float> a;
  };
  const Mask& GetMask(Marker m, float size_px, int sub_x, int sub_y);

  int w_, h_;
  bool touched_ = false;
  std::vector<float> rgba_;  // premultiplied
  std::map<std::tuple<int, int, int, int>, Mask> masks_;
};

}  // namespace shoal::render
