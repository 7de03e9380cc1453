#include "render/text.h"

#include <stb_truetype.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>

namespace shoal::render {

std::vector<std::uint32_t> DecodeUtf8(const std::string& s) {
  std::vector<std::uint32_t> out;
  out.reserve(s.size());
  std::size_t i = 0;
  while (i < s.size()) {
    const auto c = static_cast<unsigned char>(s[i]);
    int extra = 0;
    std::uint32_t cp = 0;
    if (c < 0x80) {
      cp = c;
    } else if ((c & 0xE0) == 0xC0) {
      cp = c & 0x1F;
      extra = 1;
    } else if ((c & 0xF0) == 0xE0) {
      cp = c & 0x0F;
      extra = 2;
    } else if ((c & 0xF8) == 0xF0) {
      cp = c & 0x07;
      extra = 3;
    } else {
      out.push_back(0xFFFD);
      ++i;
      continue;
    }
    bool ok = true;
    for (int k = 1; ok && k <= extra; ++k) {
      if (i + k >= s.size()) {
        ok = false;
        break;
      }
      const auto cc = static_cast<unsigned char>(s[i + k]);
      if ((cc & 0xC0) != 0x80) {
        ok = false;
        break;
      }
      cp = (cp << 6) | (cc & 0x3F);
    }
    if (!ok) {
      out.push_back(0xFFFD);
      ++i;
      continue;
    }
    out.push_back(cp);
    i += static_cast<std::size_t>(extra) + 1;
  }
  return out;
}

struct TextRenderer::Face {
  std::vector<unsigned char> data;
  stbtt_fontinfo info{};
  int ascent = 0, descent = 0, line_gap = 0;
  int cap_height = 0;
  bool bold = false;
  mutable std::unordered_map<std::uint32_t, int> glyph_of;

  int GlyphIndex(std::uint32_t cp) const {
    auto it = glyph_of.find(cp);
    if (it != glyph_of.end()) return it->second;
    const int g = stbtt_FindGlyphIndex(&info, static_cast<int>(cp));
    glyph_of.emplace(cp, g);
    return g;
  }
  float Scale(float size_px) const { return stbtt_ScaleForMappingEmToPixels(&info, size_px); }
};

TextRenderer::TextRenderer() = default;
TextRenderer::~TextRenderer() = default;

namespace {

bool ReadFile(const std::string& path, std::vector<unsigned char>* out) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  out->assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  return !out->empty();
}

}  // namespace

bool TextRenderer::Load(const std::string& regular_path, const std::string& bold_path,
                        std::string* err) {
  const auto load = [&](const std::string& path, bool bold, std::unique_ptr<Face>* out) {
    auto f = std::make_unique<Face>();
    f->bold = bold;
    if (!ReadFile(path, &f->data)) {
      if (err) {
        *err = "cannot read font file '" + path +
               "'; install the Debian package fonts-dejavu-core or set the figure's font path";
      }
      return false;
    }
    const int offset = stbtt_GetFontOffsetForIndex(f->data.data(), 0);
    if (offset < 0 || !stbtt_InitFont(&f->info, f->data.data(), offset)) {
      if (err) *err = "'" + path + "' is not a TrueType font stb_truetype can read";
      return false;
    }
    stbtt_GetFontVMetrics(&f->info, &f->ascent, &f->descent, &f->line_gap);
    int x0, y0, x1, y1;
    if (stbtt_GetCodepointBox(&f->info, 'H', &x0, &y0, &x1, &y1)) {
      f->cap_height = y1;
    } else {
      f->cap_height = f->ascent * 7 / 10;
    }
    *out = std::move(f);
    return true;
  };
  cache_.clear();
  return load(regular_path, false, &regular_) && load(bold_path, true, &bold_);
}

const TextRenderer::Face& TextRenderer::face(bool bold) const { return bold ? *bold_ : *regular_; }

float TextRenderer::Width(const std::string& text, float size_px, bool bold) const {
  const Face& f = face(bold);
  const float scale = f.Scale(size_px);
  const auto cps = DecodeUtf8(text);
  float w = 0.0f;
  int prev = -1;
  for (std::uint32_t cp : cps) {
    const int g = f.GlyphIndex(cp);
    int adv = 0, lsb = 0;
    stbtt_GetGlyphHMetrics(&f.info, g, &adv, &lsb);
    if (prev >= 0) w += scale * static_cast<float>(stbtt_GetGlyphKernAdvance(&f.info, prev, g));
    w += scale * static_cast<float>(adv);
    prev = g;
  }
  return w;
}

float TextRenderer::LineHeight(float size_px, bool bold) const {
  const Face& f = face(bold);
  return f.Scale(size_px) * static_cast<float>(f.ascent - f.descent);
}

float TextRenderer::Ascent(float size_px, bool bold) const {
  const Face& f = face(bold);
  return f.Scale(size_px) * static_cast<float>(f.ascent);
}

float TextRenderer::CapHeight(float size_px, bool bold) const {
  const Face& f = face(bold);
  return f.Scale(size_px) * static_cast<float>(f.cap_height);
}

const TextRenderer::Glyph& TextRenderer::GetGlyph(const Face& f, int glyph, float size_px,
                                                  int subpixel) {
  const auto size_key = static_cast<std::uint64_t>(std::lround(size_px * 16.0f)) & 0xFFFFF;
  const std::uint64_t key = (static_cast<std::uint64_t>(f.bold) << 62) | (size_key << 40) |
                            (static_cast<std::uint64_t>(subpixel & 3) << 32) |
                            static_cast<std::uint32_t>(glyph);
  auto it = cache_.find(key);
  if (it != cache_.end()) return it->second;
  Glyph g;
  const float scale = f.Scale(size_px);
  const float shift = static_cast<float>(subpixel) * 0.25f;
  int x0, y0, x1, y1;
  stbtt_GetGlyphBitmapBoxSubpixel(&f.info, glyph, scale, scale, shift, 0.0f, &x0, &y0, &x1, &y1);
  g.w = std::max(0, x1 - x0);
  g.h = std::max(0, y1 - y0);
  g.xoff = x0;
  g.yoff = y0;
  if (g.w > 0 && g.h > 0) {
    g.alpha.assign(static_cast<std::size_t>(g.w * g.h), 0);
    stbtt_MakeGlyphBitmapSubpixel(&f.info, g.alpha.data(), g.w, g.h, g.w, scale, scale, shift, 0.0f,
                                  glyph);
  }
  return cache_.emplace(key, std::move(g)).first->second;
}

void TextRenderer::RenderLine(const Face& f, const std::vector<std::uint32_t>& cps, float size_px,
                              std::vector<std::uint8_t>* alpha, int* w, int* h, float* baseline) {
  const float scale = f.Scale(size_px);
  struct Placed {
    int glyph;
    float x;
  };
  std::vector<Placed> placed;
  float pen = 0.0f;
  int prev = -1;
  for (std::uint32_t cp : cps) {
    const int g = f.GlyphIndex(cp);
    if (prev >= 0) pen += scale * static_cast<float>(stbtt_GetGlyphKernAdvance(&f.info, prev, g));
    placed.push_back({g, pen});
    int adv = 0, lsb = 0;
    stbtt_GetGlyphHMetrics(&f.info, g, &adv, &lsb);
    pen += scale * static_cast<float>(adv);
    prev = g;
  }
  const int margin = static_cast<int>(std::ceil(size_px * 0.5f)) + 2;
  *w = static_cast<int>(std::ceil(pen)) + 2 * margin;
  const float asc = scale * static_cast<float>(f.ascent);
  const float desc = -scale * static_cast<float>(f.descent);
  *h = static_cast<int>(std::ceil(asc + desc)) + 2 * margin;
  const int base = margin + static_cast<int>(std::lround(asc));
  *baseline = static_cast<float>(base);
  alpha->assign(static_cast<std::size_t>(*w) * static_cast<std::size_t>(*h), 0);
  for (const Placed& p : placed) {
    const float px = p.x + static_cast<float>(margin);
    int ix = static_cast<int>(std::floor(px));
    int sub = static_cast<int>(std::lround((px - static_cast<float>(ix)) * 4.0f));
    if (sub == 4) {
      sub = 0;
      ++ix;
    }
    const Glyph& g = GetGlyph(f, p.glyph, size_px, sub);
    for (int r = 0; r < g.h; ++r) {
      const int y = base + g.yoff + r;
      if (y < 0 || y >= *h) continue;
      for (int c = 0; c < g.w; ++c) {
        const int x = ix + g.xoff + c;
        if (x < 0 || x >= *w) continue;
        std::uint8_t& d = (*alpha)[static_cast<std::size_t>(y) * static_cast<std::size_t>(*w) +
                                   static_cast<std::size_t>(x)];
        d = static_cast<std::uint8_t>(
            std::min(255, d + g.alpha[static_cast<std::size_t>(r * g.w + c)]));
      }
    }
  }
}

void TextRenderer::Draw(Image* image, const std::string& text, float x, float y,
                        const TextStyle& style, HAlign h, VAlign v, bool rotated) {
  if (text.empty() || !image || image->width <= 0) return;
  const Face& f = face(style.bold);
  const float scale = f.Scale(style.size_px);
  const auto cps = DecodeUtf8(text);
  std::vector<std::uint8_t> alpha;
  int bw = 0, bh = 0;
  float base = 0.0f;
  RenderLine(f, cps, style.size_px, &alpha, &bw, &bh, &base);
  const float width = Width(text, style.size_px, style.bold);
  const float asc = scale * static_cast<float>(f.ascent);
  const float desc = -scale * static_cast<float>(f.descent);
  const float cap = scale * static_cast<float>(f.cap_height);
  const int margin = static_cast<int>(std::ceil(style.size_px * 0.5f)) + 2;

  // Destination of buffer pixel (c, r): unrotated (left + c, top + r); rotated
  // (left + r, top + bw - 1 - c).
  int left = 0, top = 0;
  if (!rotated) {
    float box_left = x;
    if (h == HAlign::kCenter) box_left = x - 0.5f * width;
    if (h == HAlign::kRight) box_left = x - width;
    float baseline_y = y;
    if (v == VAlign::kTop) baseline_y = y + asc;
    if (v == VAlign::kMiddle) baseline_y = y + 0.5f * cap;
    if (v == VAlign::kBottom) baseline_y = y - desc;
    left = static_cast<int>(std::lround(box_left)) - margin;
    top = static_cast<int>(std::lround(baseline_y)) - static_cast<int>(base);
  } else {
    const float box_w = asc + desc;
    float box_left = x;
    if (h == HAlign::kCenter) box_left = x - 0.5f * box_w;
    if (h == HAlign::kRight) box_left = x - box_w;
    float box_top = y;
    if (v == VAlign::kMiddle) box_top = y - 0.5f * width;
    if (v == VAlign::kBottom || v == VAlign::kBaseline) box_top = y - width;
    // Row (base - asc) of the buffer is the box's left edge; the text's end (column
    // margin + width) is the box's top.
    left = static_cast<int>(std::lround(box_left)) - static_cast<int>(std::lround(base - asc));
    top = static_cast<int>(std::lround(box_top)) -
          (bw - 1 - margin - static_cast<int>(std::lround(width)));
  }

  const float cr = style.color.r * 255.0f, cg = style.color.g * 255.0f, cb = style.color.b * 255.0f;
  const float ca = std::clamp(style.color.a, 0.0f, 1.0f) / 255.0f;
  const int W = image->width, H = image->height;
  for (int r = 0; r < bh; ++r) {
    for (int c = 0; c < bw; ++c) {
      const std::uint8_t a8 = alpha[static_cast<std::size_t>(r) * static_cast<std::size_t>(bw) +
                                    static_cast<std::size_t>(c)];
      if (a8 == 0) continue;
      const int dx = rotated ? left + r : left + c;
      const int dy = rotated ? top + (bw - 1 - c) : top + r;
      if (dx < 0 || dy < 0 || dx >= W || dy >= H) continue;
      std::uint8_t* p = &image->rgba[(static_cast<std::size_t>(dy) * static_cast<std::size_t>(W) +
                                      static_cast<std::size_t>(dx)) *
                                     4];
      const float a = static_cast<float>(a8) * ca;
      p[0] = static_cast<std::uint8_t>(std::lround(p[0] + (cr - p[0]) * a));
      p[1] = static_cast<std::uint8_t>(std::lround(p[1] + (cg - p[1]) * a));
      p[2] = static_cast<std::uint8_t>(std::lround(p[2] + (cb - p[2]) * a));
    }
  }
}

}  // namespace shoal::render
