// Legend boxes shared by 2-D and 3-D figures (internal to shoal_render).
#pragma once

#include <string>
#include <vector>

#include "render/figure.h"
#include "render/geometry.h"
#include "render/text.h"

namespace shoal::render {

struct Rect {
  float x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  float w() const { return x1 - x0; }
  float h() const { return y1 - y0; }
  bool Contains(float x, float y) const { return x >= x0 && x <= x1 && y >= y0 && y <= y1; }
};

/// True if the segment a-b touches the rectangle.
bool SegmentHitsRect(Vec2 a, Vec2 b, const Rect& r);

/// Sizes of a legend's parts at a figure scale.
struct LegendMetrics {
  float font_px = 14.0f;
  float pad_px = 8.0f;
  float sample_px = 30.0f;  // length of the line sample
  float gap_px = 8.0f;      // between sample and label
  float row_px = 20.0f;
  float col_gap_px = 18.0f;
  float scale = 1.0f;
};
LegendMetrics MakeLegendMetrics(const TextRenderer& text, float scale);

/// A boxed legend of entries in `columns` columns, filled column by column.
class LegendBox {
 public:
  LegendBox() = default;
  LegendBox(std::vector<LegendEntry> entries, const LegendMetrics& m, const TextRenderer& text,
            int columns);
  bool empty() const { return entries_.empty(); }
  float width() const { return width_; }
  float height() const { return height_; }
  /// Geometry (box, border, samples) into `mesh`, with the box's top-left corner at (x, y).
  void DrawShapes(float x, float y, Mesh* mesh) const;
  void DrawLabels(float x, float y, TextRenderer* text, Image* image) const;

 private:
  std::vector<LegendEntry> entries_;
  LegendMetrics m_;
  int columns_ = 1, rows_ = 0;
  std::vector<float> col_width_;
  float width_ = 0, height_ = 0;
};

/// A legend sample (line and/or marker) centred at (cx, cy), `length` pixels long.
void DrawLegendSample(const LegendEntry& e, float cx, float cy, float length, float scale,
                      Mesh* mesh);

/// A row (wrapped into several) of legend entries without a box, centred in [x0, x1], as
/// used under a figure's title.
class LegendRow {
 public:
  LegendRow() = default;
  LegendRow(std::vector<LegendEntry> entries, const LegendMetrics& m, const TextRenderer& text,
            float x0, float x1);
  bool empty() const { return entries_.empty(); }
  float height() const { return static_cast<float>(lines_.size()) * m_.row_px; }
  void DrawShapes(float y, Mesh* mesh) const;
  void DrawLabels(float y, TextRenderer* text, Image* image) const;

 private:
  struct Item {
    std::size_t entry;
    float x;  // left of the sample
  };
  std::vector<LegendEntry> entries_;
  LegendMetrics m_;
  std::vector<std::vector<Item>> lines_;
};

}  // namespace shoal::render
