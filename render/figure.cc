// Palette, validation and PNG output of shoal_render.
#include "render/figure.h"

#include <zlib.h>

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>

// stb_image_write, compiled here (all functions static) so that its PNG writer deflates
// with zlib: stb's own deflate took 250-600 ms per 1600x1000 figure, zlib level 3 about
// 45 ms for a file of the same size.
namespace {
unsigned char* ZlibCompress(unsigned char* data, int len, int* out_len, int quality) {
  uLongf bound = compressBound(static_cast<uLong>(len));
  auto* out = static_cast<unsigned char*>(std::malloc(bound));
  if (!out) return nullptr;
  if (compress2(out, &bound, data, static_cast<uLong>(len), quality) != Z_OK) {
    std::free(out);
    return nullptr;
  }
  *out_len = static_cast<int>(bound);
  return out;
}
}  // namespace
#define STBIW_ZLIB_COMPRESS ZlibCompress
#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STB_IMAGE_WRITE_STATIC
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wall"
#pragma GCC diagnostic ignored "-Wextra"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wsign-compare"
#include <stb_image_write.h>
#pragma GCC diagnostic pop

namespace shoal::render {

Color Hex(std::uint32_t rgb, float alpha) {
  return Color{static_cast<float>((rgb >> 16) & 0xFF) / 255.0f,
               static_cast<float>((rgb >> 8) & 0xFF) / 255.0f,
               static_cast<float>(rgb & 0xFF) / 255.0f, alpha};
}

Color VehicleColor(int id) {
  // Okabe & Ito (2008), colour-universal design; the yellow (F0E442) is replaced by a
  // darker mustard that stays visible on white.
  static const std::uint32_t kOkabeIto[7] = {0x0072B2, 0xD55E00, 0x009E73, 0xCC79A7,
                                             0xE69F00, 0x56B4E9, 0xB8A000};
  // Then nine of Kelly's (1965) colours of maximum contrast and of the ColorBrewer
  // "Paired"/"Dark2" sets, chosen greedily to be as far as possible (CIELAB) from the seven
  // above and from each other, at lightness 30-75 so that they show on white and differ
  // from the leader's near black. Every pair of the 16 is at least 20 Delta-E apart
  // (render_test checks it); Paul Tol's muted set, used before, had pairs 14 apart.
  static const std::uint32_t kMore[9] = {0x654522, 0xBE0032, 0xC2B280, 0x6A3D9A, 0x225555,
                                         0x66A61E, 0xF99379, 0x225522, 0x882255};
  if (id < 0) return Hex(0x888888);
  if (id == 0) return Hex(0x222222);
  const int k = (id - 1) % 16;
  return k < 7 ? Hex(kOkabeIto[k]) : Hex(kMore[k - 7]);
}

std::string VehicleName(int id) { return id == 0 ? "leader" : "follower " + std::to_string(id); }

bool ParseImageSize(const std::string& text, int* width, int* height) {
  const auto number = [](const char** p, int* out) {
    int digits = 0;
    long v = 0;
    for (; std::isdigit(static_cast<unsigned char>(**p)) && digits < 9; ++*p, ++digits) {
      v = v * 10 + (**p - '0');
    }
    *out = static_cast<int>(v);
    return digits > 0 && digits <= 8;
  };
  const char* p = text.c_str();
  int w = 0, h = 0;
  if (!number(&p, &w) || (*p != 'x' && *p != 'X')) return false;
  ++p;
  if (!number(&p, &h) || *p != '\0') return false;
  *width = w;
  *height = h;
  return true;
}

namespace {

bool Fail(std::string* err, const std::string& msg) {
  if (err) *err = msg;
  return false;
}

std::string Quoted(const std::string& s) { return s.empty() ? "" : " ('" + s + "')"; }

bool CheckSize(int w, int h, std::string* err) {
  if (w < 200 || h < 150) {
    return Fail(err, "figure size " + std::to_string(w) + "x" + std::to_string(h) +
                         " is too small; use at least 200x150 pixels (e.g. 1600x1000)");
  }
  if (w > 16384 || h > 16384) {
    return Fail(err, "figure size " + std::to_string(w) + "x" + std::to_string(h) +
                         " is too large; use at most 16384 pixels per side");
  }
  return true;
}

bool CheckScale(float scale, std::string* err) {
  if (!std::isfinite(scale) || scale < 0.0f || scale > 10.0f) {
    return Fail(err, "figure scale " + std::to_string(scale) +
                         " is out of range; use 0 (automatic) or a value in (0, 10]");
  }
  return true;
}

bool CheckWidth(float w, const std::string& what, std::string* err) {
  if (!std::isfinite(w) || w <= 0.0f || w > 100.0f) {
    return Fail(err, what + " is " + std::to_string(w) + "; use a value in (0, 100] pixels");
  }
  return true;
}

bool CheckAxis(const Axis& a, const std::string& where, std::string* err) {
  const bool has_min = !std::isnan(a.min), has_max = !std::isnan(a.max);
  if ((has_min && !std::isfinite(a.min)) || (has_max && !std::isfinite(a.max))) {
    return Fail(err, where + ": the range limits must be finite numbers or NaN (automatic)");
  }
  if (has_min && has_max && !(a.min < a.max)) {
    return Fail(err, where + ": min (" + std::to_string(a.min) + ") must be less than max (" +
                         std::to_string(a.max) + ")");
  }
  if (a.log && ((has_min && a.min <= 0.0) || (has_max && a.max <= 0.0))) {
    return Fail(err, where + ": a log axis needs a range above 0");
  }
  for (const Tick& t : a.ticks) {
    if (!std::isfinite(t.value) || (a.log && t.value <= 0.0)) {
      return Fail(err, where + ": tick '" + t.label + "' has an invalid value" +
                           (a.log ? " (a log axis needs values above 0)" : ""));
    }
  }
  return true;
}

}  // namespace

bool Validate(const Figure2D& f, std::string* err) {
  if (!CheckSize(f.width_px, f.height_px, err) || !CheckScale(f.scale, err)) return false;
  if (f.panels.empty()) return Fail(err, "the figure has no panels; add at least one Panel");
  if (f.columns < 1) {
    return Fail(err, "columns is " + std::to_string(f.columns) + "; use at least 1");
  }
  std::size_t drawable = 0;
  for (std::size_t p = 0; p < f.panels.size(); ++p) {
    const Panel& panel = f.panels[p];
    const std::string where = "panel " + std::to_string(p + 1) + Quoted(panel.title);
    if (!CheckAxis(panel.x, where + ", x axis", err) ||
        !CheckAxis(panel.y, where + ", y axis", err)) {
      return false;
    }
    for (std::size_t s = 0; s < panel.series.size(); ++s) {
      const Series& series = panel.series[s];
      const std::string sw = where + ", series " + std::to_string(s + 1) + Quoted(series.label);
      if (series.x.size() != series.y.size()) {
        return Fail(err, sw + ": x has " + std::to_string(series.x.size()) + " values but y has " +
                             std::to_string(series.y.size()) + "; give both the same length");
      }
      if (series.x.empty()) {
        return Fail(err, sw + ": the series is empty; leave it out or give it data");
      }
      if (series.line == LineStyle::kNone && series.marker == Marker::kNone) {
        return Fail(err, sw + ": neither a line nor a marker; set line or marker");
      }
      if (series.line != LineStyle::kNone &&
          !CheckWidth(series.line_width_px, sw + ": line width", err)) {
        return false;
      }
      if (series.marker != Marker::kNone &&
          !CheckWidth(series.marker_size_px, sw + ": marker size", err)) {
        return false;
      }
      for (std::size_t i = 0; i < series.x.size(); ++i) {
        const auto usable = [](double v, bool log) {
          return std::isfinite(v) && std::fabs(v) <= 1e300 && (!log || v >= 1e-300);
        };
        if (usable(series.x[i], panel.x.log) && usable(series.y[i], panel.y.log)) {
          ++drawable;
          break;
        }
      }
    }
  }
  if (drawable == 0) {
    return Fail(err,
                "nothing to draw: no series has a usable point (finite, within "
                "+-1e300, and on a log axis above 0); check the data");
  }
  return true;
}

bool Validate(const Figure3D& f, std::string* err) {
  if (!CheckSize(f.width_px, f.height_px, err) || !CheckScale(f.scale, err)) return false;
  if (std::isinf(f.azimuth_deg) || !std::isfinite(f.elevation_deg) ||
      std::fabs(f.elevation_deg) >= 89.0) {
    return Fail(err,
                "camera elevation must be within (-89, 89) degrees and the azimuth finite "
                "(or NaN: automatic)");
  }
  std::size_t drawable = 0;
  const auto finite = [](const Point3& p) {
    return std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]);
  };
  for (std::size_t i = 0; i < f.lines.size(); ++i) {
    const Polyline3D& l = f.lines[i];
    const std::string where = "line " + std::to_string(i + 1) + Quoted(l.label);
    if (l.points.empty()) return Fail(err, where + ": no points; leave it out or give it data");
    if (l.line != LineStyle::kNone && !CheckWidth(l.line_width_px, where + ": line width", err)) {
      return false;
    }
    for (const Point3& p : l.points) {
      if (finite(p)) {
        ++drawable;
        break;
      }
    }
  }
  for (std::size_t i = 0; i < f.snapshots.size(); ++i) {
    const Snapshot& s = f.snapshots[i];
    const std::string where = "snapshot " + std::to_string(i + 1) + Quoted(s.label);
    if (s.points.empty()) return Fail(err, where + ": no points; leave it out or give it data");
    if (!s.colors.empty() && s.colors.size() != s.points.size()) {
      return Fail(err, where + ": " + std::to_string(s.colors.size()) + " colours for " +
                           std::to_string(s.points.size()) +
                           " points; give one colour per point or none");
    }
    for (const auto& e : s.edges) {
      const int n = static_cast<int>(s.points.size());
      if (e.first < 0 || e.second < 0 || e.first >= n || e.second >= n) {
        return Fail(
            err, where + ": edge (" + std::to_string(e.first) + ", " + std::to_string(e.second) +
                     ") refers to a point that does not exist (" + std::to_string(n) + " points)");
      }
    }
    if (!CheckWidth(s.marker_size_px, where + ": marker size", err)) return false;
    for (const Point3& p : s.points) {
      if (finite(p)) {
        ++drawable;
        break;
      }
    }
  }
  if (drawable == 0) {
    return Fail(err, "nothing to draw: no line or snapshot has a finite point; check the data");
  }
  return true;
}

bool WritePng(const Image& image, const std::string& path, std::string* err) {
  if (image.width <= 0 || image.height <= 0 ||
      image.rgba.size() != static_cast<std::size_t>(image.width) * image.height * 4) {
    return Fail(err, "cannot write '" + path + "': the image is empty or inconsistent");
  }
  // RGB: the figures are opaque, and 3 channels encode faster and smaller.
  std::vector<std::uint8_t> rgb(static_cast<std::size_t>(image.width) * image.height * 3);
  for (std::size_t i = 0, j = 0; i < image.rgba.size(); i += 4, j += 3) {
    rgb[j] = image.rgba[i];
    rgb[j + 1] = image.rgba[i + 1];
    rgb[j + 2] = image.rgba[i + 2];
  }
  // No PNG row filter: the fastest, and for flat-coloured figures as small as the best
  // filter; zlib level 3.
  static const bool configured = [] {
    stbi_write_force_png_filter = 0;
    stbi_write_png_compression_level = 3;
    return true;
  }();
  (void)configured;
  errno = 0;
  if (!stbi_write_png(path.c_str(), image.width, image.height, 3, rgb.data(), image.width * 3)) {
    const std::string reason = errno != 0 ? std::strerror(errno) : "write failed";
    return Fail(err, "cannot write PNG '" + path + "': " + reason +
                         "; check that the directory exists and is writable");
  }
  return true;
}

bool RenderPng(const Figure2D& figure, const std::string& path, std::string* err) {
  Image image;
  return RenderImage(figure, &image, err) && WritePng(image, path, err);
}

bool RenderPng(const Figure3D& figure, const std::string& path, std::string* err) {
  Image image;
  return RenderImage(figure, &image, err) && WritePng(image, path, err);
}

}  // namespace shoal::render
