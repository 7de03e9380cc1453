#include "render/legend.h"

#include <algorithm>
#include <cmath>

namespace shoal::render {

bool SegmentHitsRect(Vec2 a, Vec2 b, const Rect& r) {
  // Liang-Barsky clipping of the segment against the rectangle.
  float t0 = 0.0f, t1 = 1.0f;
  const float dx = b.x - a.x, dy = b.y - a.y;
  const float p[4] = {-dx, dx, -dy, dy};
  const float q[4] = {a.x - r.x0, r.x1 - a.x, a.y - r.y0, r.y1 - a.y};
  for (int k = 0; k < 4; ++k) {
    if (p[k] == 0.0f) {
      if (q[k] < 0.0f) return false;
      continue;
    }
    const float t = q[k] / p[k];
    if (p[k] < 0.0f) {
      t0 = std::max(t0, t);
    } else {
      t1 = std::min(t1, t);
    }
    if (t0 > t1) return false;
  }
  return true;
}

LegendMetrics MakeLegendMetrics(const TextRenderer& text, float scale) {
  LegendMetrics m;
  m.scale = scale;
  m.font_px = 14.0f * scale;
  m.pad_px = 8.0f * scale;
  m.sample_px = 30.0f * scale;
  m.gap_px = 8.0f * scale;
  m.row_px = std::ceil(text.LineHeight(m.font_px) * 1.25f);
  m.col_gap_px = 18.0f * scale;
  return m;
}

LegendBox::LegendBox(std::vector<LegendEntry> entries, const LegendMetrics& m,
                     const TextRenderer& text, int columns)
    : entries_(std::move(entries)), m_(m) {
  if (entries_.empty()) return;
  columns_ = std::max(1, std::min<int>(columns, static_cast<int>(entries_.size())));
  rows_ = (static_cast<int>(entries_.size()) + columns_ - 1) / columns_;
  col_width_.assign(static_cast<std::size_t>(columns_), 0.0f);
  for (std::size_t i = 0; i < entries_.size(); ++i) {
    const auto c = static_cast<std::size_t>(static_cast<int>(i) / rows_);
    const float w = m_.sample_px + m_.gap_px + text.Width(entries_[i].label, m_.font_px);
    col_width_[c] = std::max(col_width_[c], w);
  }
  width_ = 2.0f * m_.pad_px;
  for (std::size_t c = 0; c < col_width_.size(); ++c) {
    width_ += col_width_[c] + (c > 0 ? m_.col_gap_px : 0.0f);
  }
  width_ = std::ceil(width_);
  height_ = std::ceil(2.0f * m_.pad_px - 0.25f * m_.row_px + static_cast<float>(rows_) * m_.row_px);
}

void DrawLegendSample(const LegendEntry& e, float cx, float cy, float length, float scale,
                      Mesh* mesh) {
  if (e.line != LineStyle::kNone) {
    const float w = std::clamp(e.line_width_px, 1.0f, 5.0f) * scale;
    // Start a dash pattern so that the sample is symmetric.
    float on = 0, off = 0;
    DashPattern(e.line, w, &on, &off);
    float len = length;
    if (on > 0) {
      const float period = on + off;
      const float n = std::max(1.0f, std::floor((length + off) / period));
      len = n * period - off;
    }
    const Vec2 p[2] = {{cx - 0.5f * len, cy}, {cx + 0.5f * len, cy}};
    StrokePolyline(p, nullptr, 2, w, e.line, e.color, mesh);
  }
  // A marker without a line is the whole sample: drawn larger, so that a ring reads as one.
  const float size = (e.line == LineStyle::kNone ? 11.0f : 8.0f) * scale;
  if (e.marker != Marker::kNone) AddMarker({cx, cy}, 0.0f, e.marker, size, e.color, mesh);
}

void LegendBox::DrawShapes(float x, float y, Mesh* mesh) const {
  if (entries_.empty()) return;
  AddRect(x, y, x + width_, y + height_, 0.0f, Color{1.0f, 1.0f, 1.0f, 0.9f}, mesh);
  AddRectOutline(x + 0.5f, y + 0.5f, x + width_ - 0.5f, y + height_ - 0.5f, 1.0f,
                 Color{0.75f, 0.75f, 0.75f, 1.0f}, mesh);
  float cx = x + m_.pad_px;
  for (int c = 0; c < columns_; ++c) {
    for (int r = 0; r < rows_; ++r) {
      const std::size_t i = static_cast<std::size_t>(c * rows_ + r);
      if (i >= entries_.size()) break;
      const float cy = y + m_.pad_px + (static_cast<float>(r) + 0.375f) * m_.row_px;
      DrawLegendSample(entries_[i], cx + 0.5f * m_.sample_px, cy, m_.sample_px, m_.scale, mesh);
    }
    cx += col_width_[static_cast<std::size_t>(c)] + m_.col_gap_px;
  }
}

void LegendBox::DrawLabels(float x, float y, TextRenderer* text, Image* image) const {
  float cx = x + m_.pad_px;
  TextStyle style;
  style.size_px = m_.font_px;
  for (int c = 0; c < columns_; ++c) {
    for (int r = 0; r < rows_; ++r) {
      const std::size_t i = static_cast<std::size_t>(c * rows_ + r);
      if (i >= entries_.size()) break;
      const float cy = y + m_.pad_px + (static_cast<float>(r) + 0.375f) * m_.row_px;
      text->Draw(image, entries_[i].label, cx + m_.sample_px + m_.gap_px, cy, style, HAlign::kLeft,
                 VAlign::kMiddle);
    }
    cx += col_width_[static_cast<std::size_t>(c)] + m_.col_gap_px;
  }
}

LegendRow::LegendRow(std::vector<LegendEntry> entries, const LegendMetrics& m,
                     const TextRenderer& text, float x0, float x1)
    : entries_(std::move(entries)), m_(m) {
  const float item_gap = 2.0f * m_.col_gap_px;
  std::vector<Item> line;
  float line_w = 0.0f;
  std::vector<float> widths;
  const auto finish = [&] {
    if (line.empty()) return;
    const float left = 0.5f * (x0 + x1 - line_w);
    for (Item& it : line) it.x += left;
    lines_.push_back(line);
    line.clear();
    line_w = 0.0f;
  };
  for (std::size_t i = 0; i < entries_.size(); ++i) {
    const float w = m_.sample_px + m_.gap_px + text.Width(entries_[i].label, m_.font_px);
    const float needed = line.empty() ? w : line_w + item_gap + w;
    if (!line.empty() && needed > x1 - x0) finish();
    const float at = line.empty() ? 0.0f : line_w + item_gap;
    line.push_back({i, at});
    line_w = at + w;
  }
  finish();
}

void LegendRow::DrawShapes(float y, Mesh* mesh) const {
  for (std::size_t l = 0; l < lines_.size(); ++l) {
    const float cy = y + (static_cast<float>(l) + 0.5f) * m_.row_px;
    for (const Item& it : lines_[l]) {
      DrawLegendSample(entries_[it.entry], it.x + 0.5f * m_.sample_px, cy, m_.sample_px, m_.scale,
                       mesh);
    }
  }
}

void LegendRow::DrawLabels(float y, TextRenderer* text, Image* image) const {
  TextStyle style;
  style.size_px = m_.font_px;
  for (std::size_t l = 0; l < lines_.size(); ++l) {
    const float cy = y + (static_cast<float>(l) + 0.5f) * m_.row_px;
    for (const Item& it : lines_[l]) {
      text->Draw(image, entries_[it.entry].label, it.x + m_.sample_px + m_.gap_px, cy, style,
                 HAlign::kLeft, VAlign::kMiddle);
    }
  }
}

}  // namespace shoal::render
