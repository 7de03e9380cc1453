// Anti-aliased text on an RGBA image with stb_truetype (internal to shoal_render).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "render/figure.h"

namespace shoal::render {

/// Decodes UTF-8 into code points; invalid bytes become U+FFFD.
std::vector<std::uint32_t> DecodeUtf8(const std::string& s);

enum class HAlign { kLeft, kCenter, kRight };
/// kTop / kBottom: the font's ascent / descent line; kMiddle: half the cap height above the
/// baseline (centres digits and capitals); kBaseline: the baseline.
enum class VAlign { kTop, kMiddle, kBaseline, kBottom };

struct TextStyle {
  float size_px = 14.0f;  // em size
  bool bold = false;
  Color color{0.1f, 0.1f, 0.1f, 1.0f};
};

/// Two faces (regular, bold) of a TrueType font and a cache of rasterised glyphs.
class TextRenderer {
 public:
  TextRenderer();
  ~TextRenderer();
  TextRenderer(const TextRenderer&) = delete;
  TextRenderer& operator=(const TextRenderer&) = delete;

  /// Loads the two font files; false with a message if either cannot be read or parsed.
  bool Load(const std::string& regular_path, const std::string& bold_path, std::string* err);

  /// Advance width of a line of text in pixels.
  float Width(const std::string& text, float size_px, bool bold = false) const;
  /// Ascent + descent (the height of a line box) in pixels.
  float LineHeight(float size_px, bool bold = false) const;
  float Ascent(float size_px, bool bold = false) const;
  float CapHeight(float size_px, bool bold = false) const;

  /// Draws one line of text anchored at (x, y) with the given alignment. rotated: turned
  /// 90 degrees counter-clockwise (reads bottom to top); alignment then refers to the
  /// rotated box (h: its width is the line height, v: its height is the text width).
  void Draw(Image* image, const std::string& text, float x, float y, const TextStyle& style,
            HAlign h, VAlign v, bool rotated = false);

 private:
  struct Face;
  struct Glyph {
    int w = 0, h = 0, xoff = 0, yoff = 0;
    std::vector<std::uint8_t> alpha;
  };
  const Face& face(bool bold) const;
  const Glyph& GetGlyph(const Face& f, int glyph, float size_px, int subpixel);
  // Rasterises the line into an alpha buffer whose origin is (left, top of ascent).
  void RenderLine(const Face& f, const std::vector<std::uint32_t>& cps, float size_px,
                  std::vector<std::uint8_t>* alpha, int* w, int* h, float* baseline);

  std::unique_ptr<Face> regular_, bold_;
  std::unordered_map<std::uint64_t, Glyph> cache_;
};

}  // namespace shoal::render
