// shoal_render: tick rules and decimation with known answers and properties; figures
// rendered off-screen and checked by pixel statistics (never against stored images); bad
// input refused with a message.
#include <gtest/gtest.h>
#include <stb_image.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <set>
#include <string>
#include <thread>

#include "render/decimate.h"
#include "render/figure.h"
#include "render/shoal_figures.h"
#include "render/synthetic_run.h"
#include "render/text.h"
#include "render/ticks.h"

// libOSMesa (Mesa 22.3) leaks about 320 bytes for every context it creates, even one that
// is never destroyed (checked with a five-line program); not ours to fix, so sanitizer
// builds (SHOAL_SANITIZE) do not report it.
extern "C" const char* __lsan_default_suppressions() { return "leak:libOSMesa.so\n"; }

namespace shoal::render {
namespace {

// ---------------------------------------------------------------- ticks (pure functions)

TEST(Ticks, NiceStepKnownAnswers) {
  EXPECT_DOUBLE_EQ(NiceStep(10.0, 5), 2.0);
  EXPECT_DOUBLE_EQ(NiceStep(10.0, 10), 1.0);
  EXPECT_DOUBLE_EQ(NiceStep(10.0, 4), 5.0);       // 2.5 -> 5
  EXPECT_DOUBLE_EQ(NiceStep(3600.0, 7), 1000.0);  // 514 -> 1000
  EXPECT_DOUBLE_EQ(NiceStep(3600.0, 8), 500.0);   // 450 -> 500
  EXPECT_DOUBLE_EQ(NiceStep(0.4, 5), 0.1);        // 0.08 -> 0.1
  EXPECT_DOUBLE_EQ(NiceStep(1000.0, 1), 1000.0);  // exact powers stay
  EXPECT_EQ(NiceStep(0.0, 5), 0.0);
  EXPECT_EQ(NiceStep(1.0, 0), 0.0);
}

TEST(Ticks, NiceStepIsTheSmallest125StepThatFits) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> exp10(-8.0, 8.0);
  std::uniform_int_distribution<int> intervals(1, 12);
  for (int k = 0; k < 2000; ++k) {
    const double span = std::pow(10.0, exp10(rng));
    const int n = intervals(rng);
    const double step = NiceStep(span, n);
    ASSERT_GT(step, 0.0);
    // Of the form m * 10^e with m in {1, 2, 5}.
    const double e = std::floor(std::log10(step) + 1e-9);
    const double m = step / std::pow(10.0, e);
    EXPECT_TRUE(std::fabs(m - 1) < 1e-9 || std::fabs(m - 2) < 1e-9 || std::fabs(m - 5) < 1e-9)
        << "step " << step;
    EXPECT_LE(span / step, n * (1 + 1e-9));
    // The next smaller 1-2-5 step would need more than n intervals.
    const double smaller = std::fabs(m - 1) < 1e-9   ? 0.5 * step
                           : std::fabs(m - 2) < 1e-9 ? 0.5 * step
                                                     : 0.4 * step;
    EXPECT_GT(span / smaller, n * (1 - 1e-9));
  }
}

TEST(Ticks, LinearTicksKnownAnswers) {
  TickSet t = LinearTicks(0.0, 3600.0, 8);
  EXPECT_DOUBLE_EQ(t.step, 500.0);
  ASSERT_EQ(t.major.size(), 8u);
  EXPECT_DOUBLE_EQ(t.major.front(), 0.0);
  EXPECT_DOUBLE_EQ(t.major.back(), 3500.0);

  t = LinearTicks(-0.13, 0.27, 6);
  EXPECT_DOUBLE_EQ(t.step, 0.1);
  ASSERT_EQ(t.major.size(), 4u);
  EXPECT_NEAR(t.major[0], -0.1, 1e-15);
  EXPECT_EQ(t.major[1], 0.0);  // exactly zero, not 1e-17
  EXPECT_NEAR(t.major[3], 0.2, 1e-15);

  EXPECT_TRUE(LinearTicks(1.0, 1.0, 5).major.empty());
  EXPECT_TRUE(LinearTicks(0.0, 1.0, 1).major.empty());
}

TEST(Ticks, LinearTicksAreMultiplesOfTheStepInsideTheRange) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1e4, 1e4), w(-6, 6);
  for (int k = 0; k < 2000; ++k) {
    const double lo = u(rng), hi = lo + std::pow(10.0, w(rng));
    const int n = 3 + k % 8;
    const TickSet t = LinearTicks(lo, hi, n);
    ASSERT_FALSE(t.major.empty()) << lo << " " << hi;
    EXPECT_LE(static_cast<int>(t.major.size()), n);
    for (double v : t.major) {
      EXPECT_GE(v, lo - 1e-9 * t.step);
      EXPECT_LE(v, hi + 1e-9 * t.step);
      const double q = v / t.step;  // an integer, to double precision
      EXPECT_NEAR(q, std::round(q), 1e-9 * std::max(1.0, std::fabs(q)));
    }
    // The next smaller 1-2-5 step would put more than n ticks inside.
    const double m = t.step / std::pow(10.0, std::floor(std::log10(t.step) + 1e-9));
    const double smaller = m < 1.5 ? 0.5 * t.step : m < 3.0 ? 0.5 * t.step : 0.4 * t.step;
    const double more = std::floor(hi / smaller + 1e-9) - std::ceil(lo / smaller - 1e-9) + 1;
    EXPECT_GT(more, n);
  }
}

TEST(Ticks, LogTicksKnownAnswers) {
  // Six decades: majors at each power of ten, minors at 2..9 x 10^k.
  TickSet t = LogTicks(1e-3, 1e2, 10);
  EXPECT_TRUE(t.decades);
  ASSERT_EQ(t.major.size(), 6u);
  EXPECT_DOUBLE_EQ(t.major.front(), 1e-3);
  EXPECT_DOUBLE_EQ(t.major.back(), 1e2);
  EXPECT_EQ(t.minor.size(), 5u * 8u);
  EXPECT_NEAR(t.minor.front(), 2e-3, 1e-18);

  // Seventeen decades, at most six labels: every third decade (multiples of 3).
  t = LogTicks(1e-15, 10.0, 6);
  ASSERT_EQ(t.major.size(), 6u);
  EXPECT_NEAR(std::log10(t.major.front()), -15, 1e-9);
  EXPECT_NEAR(std::log10(t.major.back()), 0, 1e-9);

  // Less than two decades inside: 1-2-5 majors.
  t = LogTicks(0.02, 0.3, 8);
  EXPECT_FALSE(t.decades);
  ASSERT_EQ(t.major.size(), 4u);
  EXPECT_DOUBLE_EQ(t.major[0], 0.02);
  EXPECT_DOUBLE_EQ(t.major[1], 0.05);
  EXPECT_DOUBLE_EQ(t.major[2], 0.1);
  EXPECT_DOUBLE_EQ(t.major[3], 0.2);

  // Narrower than one 1-2-5 step: linear ticks.
  t = LogTicks(0.021, 0.029, 5);
  EXPECT_DOUBLE_EQ(t.step, 0.002);
  EXPECT_EQ(t.major.size(), 4u);  // 0.022 ... 0.028

  EXPECT_TRUE(LogTicks(-1.0, 10.0, 5).major.empty());
  EXPECT_TRUE(LogTicks(0.0, 10.0, 5).major.empty());
}

TEST(Ticks, LabelsKnownAnswers) {
  EXPECT_EQ(FormatLinearTick(0.05, 0.05), "0.05");
  EXPECT_EQ(FormatLinearTick(0.1, 0.1), "0.1");
  EXPECT_EQ(FormatLinearTick(500.0, 500.0), "500");
  EXPECT_EQ(FormatLinearTick(-2.0, 1.0),
            "\xE2\x88\x92"
            "2");  // U+2212 minus
  EXPECT_EQ(FormatLinearTick(1e-17, 0.1), "0");
  EXPECT_EQ(FormatLogTick(1e-3), "10\xE2\x81\xBB\xC2\xB3");  // 10⁻³
  EXPECT_EQ(FormatLogTick(1.0), "10\xE2\x81\xB0");           // 10⁰
  EXPECT_EQ(FormatLogTick(100.0), "10\xC2\xB2");             // 10²
  EXPECT_EQ(FormatLogTick(0.002), "0.002");
  EXPECT_EQ(FormatLogTick(500.0), "500");
  EXPECT_EQ(FormatLogTick(2e-6),
            "2\xC3\x97"
            "10\xE2\x81\xBB\xE2\x81\xB6");  // 2×10⁻⁶
  EXPECT_EQ(Superscript(-12), "\xE2\x81\xBB\xC2\xB9\xC2\xB2");
  TickSet big = LinearTicks(0.0, 3.0e6, 7);
  EXPECT_EQ(CommonExponent(big), 6);
  TickSet small = LinearTicks(0.0, 5e-5, 6);
  EXPECT_EQ(CommonExponent(small), -6);
  EXPECT_EQ(CommonExponent(LinearTicks(0.0, 3600.0, 8)), 0);
}

// ---------------------------------------------------------------- decimation (pure)

TEST(Decimate, MinMaxKeepsEveryColumnsExtremesAndSpikes) {
  // Given 100,000 noisy samples with one spike, decimated onto 500 columns.
  const std::size_t n = 100000;
  std::vector<double> x(n), y(n);
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, 1.0);
  for (std::size_t i = 0; i < n; ++i) {
    x[i] = static_cast<double>(i) * 0.01;
    y[i] = std::sin(x[i]) + 0.1 * noise(rng);
  }
  y[54321] = 50.0;
  const int columns = 500;
  const double x0 = 0.0, px_per_x = columns / (x.back() - x0);
  const IndexRuns r = DecimateMinMax(x.data(), y.data(), n, x0, px_per_x, columns);
  // Then: one run, at most 4 points per column, indices ascending, ends kept.
  ASSERT_EQ(r.runs(), 1u);
  EXPECT_LE(r.index.size(), 4u * (columns + 2));
  EXPECT_EQ(r.index.front(), 0u);
  EXPECT_EQ(r.index.back(), n - 1);
  for (std::size_t k = 1; k < r.index.size(); ++k) ASSERT_LT(r.index[k - 1], r.index[k]);
  // And every column's minimum and maximum are among the kept points.
  std::vector<double> lo(columns + 1, INFINITY), hi(columns + 1, -INFINITY);
  for (std::size_t i = 0; i < n; ++i) {
    const int c = std::min(columns, static_cast<int>(std::floor((x[i] - x0) * px_per_x)));
    lo[c] = std::min(lo[c], y[i]);
    hi[c] = std::max(hi[c], y[i]);
  }
  std::vector<double> klo(columns + 1, INFINITY), khi(columns + 1, -INFINITY);
  for (std::uint32_t i : r.index) {
    const int c = std::min(columns, static_cast<int>(std::floor((x[i] - x0) * px_per_x)));
    klo[c] = std::min(klo[c], y[i]);
    khi[c] = std::max(khi[c], y[i]);
  }
  for (int c = 0; c <= columns; ++c) {
    EXPECT_EQ(lo[c], klo[c]) << "column " << c;
    EXPECT_EQ(hi[c], khi[c]) << "column " << c;
  }
  EXPECT_NE(std::find(r.index.begin(), r.index.end(), 54321u), r.index.end());
}

TEST(Decimate, NonFiniteValuesBreakTheLine) {
  std::vector<double> x = {0, 1, 2, 3, 4, 5, 6};
  std::vector<double> y = {0, 1, NAN, 3, 4, INFINITY, 6};
  const IndexRuns r = DecimateMinMax(x.data(), y.data(), x.size(), 0.0, 100.0, 1000);
  ASSERT_EQ(r.runs(), 3u);
  EXPECT_EQ(r.run_size(0), 2u);
  EXPECT_EQ(r.run_size(1), 2u);
  EXPECT_EQ(r.run_size(2), 1u);
  EXPECT_TRUE(IsSortedX(x.data(), x.size()));
  std::vector<double> unsorted = {0, 2, 1};
  EXPECT_FALSE(IsSortedX(unsorted.data(), unsorted.size()));
}

TEST(Decimate, SimplifyKeepsTheLineWithinTolerance) {
  // A straight line collapses to its ends.
  std::vector<float> x, y;
  for (int i = 0; i < 1000; ++i) {
    x.push_back(static_cast<float>(i) * 0.7f);
    y.push_back(3.0f + static_cast<float>(i) * 0.3f);
  }
  SimplifyPolyline(&x, &y, 0.2f);
  EXPECT_EQ(x.size(), 2u);
  // A random walk: every dropped point within ~tolerance of the kept polyline.
  std::mt19937 rng(9);
  std::normal_distribution<float> step(0.0f, 0.3f);
  std::vector<float> ox, oy;
  float v = 0.0f;
  for (int i = 0; i < 5000; ++i) {
    v += step(rng);
    ox.push_back(static_cast<float>(i) * 0.25f);
    oy.push_back(v);
  }
  std::vector<float> sx = ox, sy = oy;
  SimplifyPolyline(&sx, &sy, 0.2f);
  EXPECT_LT(sx.size(), ox.size());
  EXPECT_EQ(sx.front(), ox.front());
  EXPECT_EQ(sx.back(), ox.back());
  std::size_t seg = 0;
  for (std::size_t i = 0; i < ox.size(); ++i) {
    while (seg + 1 < sx.size() - 1 && sx[seg + 1] < ox[i]) ++seg;
    const float ax = sx[seg], ay = sy[seg], bx = sx[seg + 1], by = sy[seg + 1];
    const float dx = bx - ax, dy = by - ay;
    const float d = std::fabs(dy * (ox[i] - ax) - dx * (oy[i] - ay)) / std::hypot(dx, dy);
    EXPECT_LE(d, 0.4f) << "point " << i;
  }
}

TEST(Decimate, ScatterKeepsOnePointPerCellAndCountsTheRest) {
  std::vector<double> px = {0.2, 0.7, 1.5, 1.6, 9.9, -1.0, 3.0};
  std::vector<double> py = {0.2, 0.9, 0.5, 0.5, 9.9, 1.0, 20.0};
  std::vector<std::uint32_t> counts;
  const auto kept = DecimateScatter(px.data(), py.data(), px.size(), 10.0, 10.0, 1.0, &counts);
  ASSERT_EQ(kept.size(), 3u);  // cells (0,0), (1,0), (9,9); two points outside
  EXPECT_EQ(kept[0], 0u);
  EXPECT_EQ(kept[1], 2u);
  EXPECT_EQ(kept[2], 4u);
  EXPECT_EQ(counts, (std::vector<std::uint32_t>{2, 2, 1}));
}

// ---------------------------------------------------------------- palette and text

// CIELAB (D65) of an sRGB colour: a perceptual-ish space where a Euclidean distance of
// about 20 (CIE76 Delta-E) separates colours that are easy to tell apart in a plot.
std::array<double, 3> Lab(const Color& c) {
  const auto lin = [](double v) { return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4); };
  const double r = lin(c.r), g = lin(c.g), b = lin(c.b);
  const double x = (0.4124 * r + 0.3576 * g + 0.1805 * b) / 0.95047;
  const double y = 0.2126 * r + 0.7152 * g + 0.0722 * b;
  const double z = (0.0193 * r + 0.1192 * g + 0.9505 * b) / 1.08883;
  const auto f = [](double t) { return t > 0.008856 ? std::cbrt(t) : 7.787 * t + 16.0 / 116.0; };
  return {116.0 * f(y) - 16.0, 500.0 * (f(x) - f(y)), 200.0 * (f(y) - f(z))};
}

double DeltaE(const Color& a, const Color& b) {
  const auto p = Lab(a), q = Lab(b);
  return std::sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                   (p[2] - q[2]) * (p[2] - q[2]));
}

TEST(Palette, LeaderIsDarkAndSixteenFollowersAreDistinct) {
  const Color leader = VehicleColor(0);
  EXPECT_LT(leader.r + leader.g + leader.b, 0.5f);
  const Color white{1, 1, 1, 1};
  for (int i = 1; i <= 16; ++i) {
    const Color c = VehicleColor(i);
    EXPECT_GE(DeltaE(c, white), 35.0) << "follower " << i << " is too light for white paper";
    EXPECT_GE(DeltaE(c, leader), 25.0) << "follower " << i << " looks like the leader";
    for (int j = 1; j < i; ++j) {
      EXPECT_GE(DeltaE(c, VehicleColor(j)), 20.0) << "followers " << j << " and " << i;
    }
  }
  EXPECT_EQ(VehicleName(0), "leader");
  EXPECT_EQ(VehicleName(3), "follower 3");
}

TEST(Text, DecodesUtf8) {
  const auto cps = DecodeUtf8("a\xCE\xB8\xE2\x88\x92\xF0\x9F\x98\x80\xFF");
  ASSERT_EQ(cps.size(), 5u);
  EXPECT_EQ(cps[0], 'a');
  EXPECT_EQ(cps[1], 0x3B8u);   // θ
  EXPECT_EQ(cps[2], 0x2212u);  // −
  EXPECT_EQ(cps[3], 0x1F600u);
  EXPECT_EQ(cps[4], 0xFFFDu);  // invalid byte
}

// ---------------------------------------------------------------- rendered figures

struct Stats {
  std::size_t non_white = 0;
  std::size_t distinct = 0;
};

Stats Measure(const Image& img, int x0, int y0, int x1, int y1) {
  Stats s;
  std::set<std::uint32_t> colours;
  for (int y = std::max(0, y0); y < std::min(img.height, y1); ++y) {
    for (int x = std::max(0, x0); x < std::min(img.width, x1); ++x) {
      const std::uint8_t* p = &img.rgba[(static_cast<std::size_t>(y) * img.width + x) * 4];
      if (p[0] < 250 || p[1] < 250 || p[2] < 250) ++s.non_white;
      colours.insert((p[0] << 16) | (p[1] << 8) | p[2]);
    }
  }
  s.distinct = colours.size();
  return s;
}

// Pixels within `tol` (per channel) of colour c.
std::size_t CountColour(const Image& img, const Color& c, int tol = 12) {
  const int r = static_cast<int>(std::lround(c.r * 255)),
            g = static_cast<int>(std::lround(c.g * 255)),
            b = static_cast<int>(std::lround(c.b * 255));
  std::size_t n = 0;
  for (std::size_t i = 0; i < img.rgba.size(); i += 4) {
    if (std::abs(img.rgba[i] - r) <= tol && std::abs(img.rgba[i + 1] - g) <= tol &&
        std::abs(img.rgba[i + 2] - b) <= tol) {
      ++n;
    }
  }
  return n;
}

// Dark pixels (luminance < 100) in a region.
std::size_t CountDark(const Image& img, int x0, int y0, int x1, int y1) {
  std::size_t n = 0;
  for (int y = y0; y < y1; ++y) {
    for (int x = x0; x < x1; ++x) {
      const std::uint8_t* p = &img.rgba[(static_cast<std::size_t>(y) * img.width + x) * 4];
      if (0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2] < 100) ++n;
    }
  }
  return n;
}

Figure2D TwoPanelFigure(int w, int h) {
  Figure2D f;
  f.width_px = w;
  f.height_px = h;
  f.title = "test figure";
  f.columns = 2;
  for (int p = 0; p < 2; ++p) {
    Panel panel;
    panel.title = p == 0 ? "sine" : "decay";
    panel.x.label = "time";
    panel.x.unit = "s";
    panel.y.label = p == 0 ? "x" : "error";
    panel.y.unit = "m";
    panel.y.log = p == 1;
    for (int k = 1; k <= 2; ++k) {
      Series s;
      s.label = VehicleName(k);
      s.color = VehicleColor(k);
      for (int i = 0; i <= 20000; ++i) {
        const double t = i * 0.01;
        s.x.push_back(t);
        s.y.push_back(p == 0 ? k * std::sin(t) : std::exp(-t / (10.0 * k)) + 1e-6);
      }
      panel.series.push_back(std::move(s));
    }
    f.panels.push_back(std::move(panel));
  }
  return f;
}

TEST(Render2D, FigureHasTheRequestedSizeAndIsNotBlank) {
  for (const auto& [w, h] : {std::pair{1600, 1000}, std::pair{800, 500}, std::pair{1234, 777}}) {
    Image img;
    std::string err;
    ASSERT_TRUE(RenderImage(TwoPanelFigure(w, h), &img, &err)) << err;
    EXPECT_EQ(img.width, w);
    EXPECT_EQ(img.height, h);
    ASSERT_EQ(img.rgba.size(), static_cast<std::size_t>(w) * h * 4);
    // Several colours overall, and drawn pixels in the middle of each panel's plot area.
    EXPECT_GT(Measure(img, 0, 0, w, h).distinct, 20u);
    EXPECT_GT(Measure(img, w / 8, h / 3, w * 3 / 8, h * 2 / 3).non_white, 100u);
    EXPECT_GT(Measure(img, w * 5 / 8, h / 3, w * 7 / 8, h * 2 / 3).non_white, 100u);
    // Both series colours appear.
    EXPECT_GT(CountColour(img, VehicleColor(1)), 200u);
    EXPECT_GT(CountColour(img, VehicleColor(2)), 200u);
  }
}

TEST(Render2D, TitleTextIsDrawn) {
  Figure2D with = TwoPanelFigure(800, 500);
  Figure2D without = with;
  without.title.clear();
  Image a, b;
  std::string err;
  ASSERT_TRUE(RenderImage(with, &a, &err)) << err;
  ASSERT_TRUE(RenderImage(without, &b, &err)) << err;
  // The title band (top 30 px, middle third) is dark only when there is a title.
  EXPECT_GT(CountDark(a, 800 / 3, 0, 800 * 2 / 3, 30), 100u);
  EXPECT_EQ(CountDark(b, 800 / 3, 0, 800 * 2 / 3, 8), 0u);
}

TEST(Render2D, AutoLegendDoesNotHideData) {
  // Given dense data in the upper-right quarter only.
  Figure2D f;
  f.width_px = 800;
  f.height_px = 600;
  Panel p;
  p.x.min = 0;
  p.x.max = 10;
  p.y.min = 0;
  p.y.max = 10;
  Series s;
  s.color = VehicleColor(1);
  s.line = LineStyle::kNone;
  s.marker = Marker::kSquare;
  s.marker_size_px = 6;
  for (double x = 5.5; x <= 9.9; x += 0.05) {
    for (double y = 5.5; y <= 9.9; y += 0.05) {
      s.x.push_back(x);
      s.y.push_back(y);
    }
  }
  p.series.push_back(s);
  f.panels.push_back(p);
  Image without, with;
  std::string err;
  ASSERT_TRUE(RenderImage(f, &without, &err)) << err;
  f.panels[0].series[0].label = "a rather long legend label";
  ASSERT_TRUE(RenderImage(f, &with, &err)) << err;
  // Then the legend goes elsewhere: no data pixel is lost (the legend adds a sample).
  EXPECT_GE(CountColour(with, VehicleColor(1)), CountColour(without, VehicleColor(1)));
}

TEST(Render2D, PngIsWrittenAtTheRequestedSize) {
  const std::string path =
      (std::filesystem::temp_directory_path() / "shoal_render_test_2d.png").string();
  std::string err;
  ASSERT_TRUE(RenderPng(TwoPanelFigure(640, 400), path, &err)) << err;
  int w = 0, h = 0, n = 0;
  unsigned char* data = stbi_load(path.c_str(), &w, &h, &n, 3);
  ASSERT_NE(data, nullptr);
  EXPECT_EQ(w, 640);
  EXPECT_EQ(h, 400);
  stbi_image_free(data);
  std::filesystem::remove(path);
}

Figure3D HelixFigure(int w, int h) {
  Figure3D f;
  f.width_px = w;
  f.height_px = h;
  f.title = "helix";
  for (int k = 0; k < 3; ++k) {
    Polyline3D l;
    l.label = VehicleName(k);
    l.color = VehicleColor(k);
    for (int i = 0; i <= 50000; ++i) {
      const double t = i * 0.01;
      l.points.push_back(
          {(50 + 5 * k) * std::cos(0.01 * t), (50 + 5 * k) * std::sin(0.01 * t), -0.1 * t});
    }
    f.lines.push_back(std::move(l));
  }
  Snapshot s;
  s.label = "t = 0 s";
  s.points = {f.lines[0].points[0], f.lines[1].points[0], f.lines[2].points[0]};
  s.colors = {VehicleColor(0), VehicleColor(1), VehicleColor(2)};
  s.edges = {{0, 1}, {0, 2}};
  f.snapshots.push_back(s);
  return f;
}

TEST(Render3D, FigureHasTheRequestedSizeAndIsNotBlank) {
  for (const auto& [w, h] : {std::pair{1400, 1000}, std::pair{700, 500}}) {
    Image img;
    std::string err;
    ASSERT_TRUE(RenderImage(HelixFigure(w, h), &img, &err)) << err;
    EXPECT_EQ(img.width, w);
    EXPECT_EQ(img.height, h);
    EXPECT_GT(Measure(img, 0, 0, w, h).distinct, 20u);
    // Drawn pixels in the central area where the box and data are.
    EXPECT_GT(Measure(img, w / 4, h / 4, w * 3 / 4, h * 3 / 4).non_white, 1000u);
    for (int k = 0; k < 3; ++k) EXPECT_GT(CountColour(img, VehicleColor(k)), 100u) << "line " << k;
    EXPECT_GT(CountDark(img, w / 3, 0, w * 2 / 3, h / 20), 50u);  // the title
  }
}

// Mean image row of the pixels of colour c.
double MeanRow(const Image& img, const Color& c) {
  double sum = 0, n = 0;
  for (int y = 0; y < img.height; ++y) {
    for (int x = 0; x < img.width; ++x) {
      const std::uint8_t* p = &img.rgba[(static_cast<std::size_t>(y) * img.width + x) * 4];
      if (std::abs(p[0] - c.r * 255) < 12 && std::abs(p[1] - c.g * 255) < 12 &&
          std::abs(p[2] - c.b * 255) < 12) {
        sum += y;
        n += 1;
      }
    }
  }
  return n > 0 ? sum / n : NAN;
}

TEST(Render3D, NedDepthGrowsDownTheScreen) {
  // Given a shallow ring (depth 0 m) and a deep ring (depth 80 m) in NED coordinates.
  Figure3D f;
  f.width_px = 600;
  f.height_px = 600;
  for (int k = 0; k < 2; ++k) {
    Polyline3D l;
    l.color = VehicleColor(k + 1);
    for (int i = 0; i <= 360; ++i) {
      const double a = i * M_PI / 180.0;
      l.points.push_back({50 * std::cos(a), 50 * std::sin(a), k == 0 ? 0.0 : 80.0});
    }
    f.lines.push_back(l);
  }
  for (const bool z_down : {true, false}) {
    f.z_down = z_down;
    Image img;
    std::string err;
    ASSERT_TRUE(RenderImage(f, &img, &err)) << err;
    const double shallow = MeanRow(img, VehicleColor(1)), deep = MeanRow(img, VehicleColor(2));
    // Then with z down the deep ring is lower on the screen; with z up it is higher.
    if (z_down) {
      EXPECT_GT(deep, shallow + 50);
    } else {
      EXPECT_LT(deep, shallow - 50);
    }
  }
}

TEST(RenderFigures, StandardFiguresFromSyntheticData) {
  const SyntheticRun run = MakeSyntheticRun(120.0, 10.0, 0.05, 2);
  const Figure2D states = StateFigure(run.vehicles, "synthetic", 1000, 700);
  ASSERT_EQ(states.panels.size(), 10u);
  for (const Panel& p : states.panels) EXPECT_EQ(p.series.size(), run.vehicles.size());
  // psi is broken where it wraps: NaNs inserted, all values in (-pi, pi].
  for (const Series& s : states.panels[8].series) {
    for (double v : s.y) {
      if (std::isfinite(v)) {
        EXPECT_GT(v, -M_PI - 1e-12);
        EXPECT_LE(v, M_PI + 1e-12);
      }
    }
  }
  ErrorOptions eo;
  eo.position_tol_m = 0.5;
  eo.converged_s = run.converged_s;
  const Figure2D errors = ErrorFigure(run.errors, eo);
  ASSERT_EQ(errors.panels.size(), 3u);
  EXPECT_TRUE(errors.panels[0].y.log);
  ChannelOptions co;
  co.tau_t_s = run.tau_t_s;
  co.tau_s = run.tau_s;
  const Figure2D channel = ChannelFigure(run.links, co);
  ASSERT_EQ(channel.panels.size(), 3u);
  EXPECT_EQ(channel.panels[2].y.ticks.size(), run.links.size());
  TrajectoryOptions to;
  to.snapshot_times_s = {0.0, 60.0, 120.0};
  const Figure3D traj = TrajectoryFigure(run.vehicles, to);
  EXPECT_EQ(traj.lines.size(), run.vehicles.size());
  ASSERT_EQ(traj.snapshots.size(), 3u);
  EXPECT_EQ(traj.snapshots[0].edges.size(), run.vehicles.size() - 1);  // leader to each
  std::string err;
  Image img;
  for (const Figure2D* f : {&states, &errors, &channel}) {
    ASSERT_TRUE(RenderImage(*f, &img, &err)) << err;
    EXPECT_EQ(img.width, f->width_px);
    EXPECT_GT(Measure(img, 0, 0, img.width, img.height).distinct, 20u);
  }
  ASSERT_TRUE(RenderImage(traj, &img, &err)) << err;
}

TEST(RenderFigures, ChannelGivesEachLinkARowAndSaysWhatTheDelayErrorMeans) {
  // Given three links whose delays exceed tau = 0.1 s by 0..10, 0..20 and 5..15 ms.
  std::vector<LinkSeries> links(3);
  const int from[3] = {0, 2, 0}, to[3] = {1, 1, 2};
  const double lo_ms[3] = {0, 0, 5}, hi_ms[3] = {10, 20, 15};
  for (int k = 0; k < 3; ++k) {
    links[k].from = from[k];
    links[k].to = to[k];
    for (int i = 0; i <= 1000; ++i) {
      links[k].sent_s.push_back(0.02 * i);
      links[k].delay_s.push_back(0.1 + 1e-3 * (lo_ms[k] + (hi_ms[k] - lo_ms[k]) * i / 1000.0));
    }
  }
  ChannelOptions o;
  o.tau_t_s = {0.0, 100.0};
  o.tau_s = {0.1, 0.1};
  o.mode = "sim";
  o.control_period_s = 0.02;
  // When the figure is made,
  const Figure2D f = ChannelFigure(links, o);
  ASSERT_EQ(f.panels.size(), 3u);
  const Panel& p = f.panels[1];
  // then the delay-error panel has one row per link (named like the drops panel's rows),
  ASSERT_EQ(p.y.ticks.size(), 3u);
  EXPECT_EQ(p.y.ticks[0].label, "0 \xE2\x86\x92 1");
  EXPECT_EQ(p.y.ticks[1].label, "2 \xE2\x86\x92 1");
  EXPECT_EQ(p.y.ticks[2].label, "0 \xE2\x86\x92 2");
  for (std::size_t k = 0; k < 3; ++k) EXPECT_EQ(f.panels[2].y.ticks[k].label, p.y.ticks[k].label);
  // with each link's median (ms) on its own row,
  const Series& medians = p.series.back();
  ASSERT_EQ(medians.x.size(), 3u);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(medians.x[k], 0.5 * (lo_ms[k] + hi_ms[k]), 0.05) << "link " << k;
    EXPECT_EQ(medians.y[k], p.y.ticks[k].value);
  }
  // and a note that in a sim run the difference lies within one control period.
  EXPECT_NE(p.note.find("[0, 20 ms), one control period"), std::string::npos) << p.note;
  // In real time the log stamps a delivery with its scheduled release: the difference is
  // its rounding, and the note gives the emulator's release error where it is known.
  o.mode = "realtime";
  const std::string rt = ChannelFigure(links, o).panels[1].note;
  EXPECT_NE(rt.find("scheduled release"), std::string::npos) << rt;
  EXPECT_EQ(rt.find("release error"), std::string::npos) << rt;
  o.release_error_p99_s = 2.346e-3;
  const std::string known = ChannelFigure(links, o).panels[1].note;
  EXPECT_NE(known.find("release error (how late it really released) p99 2.35 ms"), std::string::npos)
      << known;
  Image img;
  std::string err;
  EXPECT_TRUE(RenderImage(f, &img, &err)) << err;
}

// Given more links than the per-link panels can show (a dense swarm: once a figure of
// 10^7 px that could not be drawn), the rows are per receiver, and with more receivers than
// rows one row holds every link; every message is still drawn, in time order.
TEST(RenderFigures, ChannelFigureOfManyLinksGroupsThemIntoRowsItCanShow) {
  const auto make = [](int followers) {
    std::vector<LinkSeries> links;
    for (int to = 1; to <= followers; ++to) {
      for (int from = 0; from <= followers; ++from) {
        if (from == to) continue;
        LinkSeries l;
        l.from = from;
        l.to = to;
        for (int i = 0; i < 3; ++i) {
          l.sent_s.push_back(0.02 * (i + from));
          l.delay_s.push_back(0.1);
          l.model_delay_s.push_back(0.1);
        }
        l.dropped_s.push_back(0.01 * from);
        links.push_back(std::move(l));
      }
    }
    return links;
  };
  ChannelOptions o;
  o.mode = "sim";
  o.control_period_s = 0.02;
  const Figure2D by_receiver = ChannelFigure(make(20), o);  // 400 links, 20 receivers
  ASSERT_EQ(by_receiver.panels.size(), 3u);
  ASSERT_EQ(by_receiver.panels[2].y.ticks.size(), 20u);
  EXPECT_EQ(by_receiver.panels[2].y.ticks[0].label, "all \xE2\x86\x92 1");
  EXPECT_LE(by_receiver.height_px, 5000);
  EXPECT_NE(by_receiver.title.find("400 links, grouped by receiver"), std::string::npos)
      << by_receiver.title;
  std::size_t delivered = 0;
  for (const Series& s : by_receiver.panels[0].series) {
    if (s.marker == Marker::kCircle) delivered += s.x.size();
  }
  EXPECT_EQ(delivered, 400u * 3);
  const Figure2D one_row = ChannelFigure(make(60), o);  // 3600 links, 60 receivers
  ASSERT_EQ(one_row.panels[2].y.ticks.size(), 1u);
  EXPECT_EQ(one_row.panels[2].y.ticks[0].label, "all links");
  std::size_t drops = 0;
  for (const Series& s : one_row.panels[2].series) {
    drops += s.x.size();
    EXPECT_TRUE(std::is_sorted(s.x.begin(), s.x.end()));
  }
  EXPECT_EQ(drops, 3600u);
  Image img;
  std::string err;
  EXPECT_TRUE(RenderImage(one_row, &img, &err)) << err;
}

TEST(RenderFigures, StatesDrawDepthDownwardsLikeThe3DFigure) {
  VehicleSeries v;
  v.t_s = {0.0, 1.0};
  for (auto& c : v.eta) c = {0.0, 1.0};
  for (auto& c : v.nu) c = {0.0, 1.0};
  const Figure2D f = StateFigure({v}, "");
  const Panel& z = f.panels[4];  // row 2, left column
  EXPECT_TRUE(z.y.reversed);
  EXPECT_NE(z.y.label.find("down"), std::string::npos) << z.y.label;
  const Figure3D t = TrajectoryFigure({v}, TrajectoryOptions{});
  EXPECT_TRUE(t.z_down);
  EXPECT_NE(t.z_label.find("down"), std::string::npos) << t.z_label;
  for (std::size_t k = 0; k < f.panels.size(); ++k) {
    if (k != 4) {
      EXPECT_FALSE(f.panels[k].y.reversed) << "panel " << k;
    }
  }
}

TEST(Render3D, SeaSurfaceIsDrawnWhereTheBoxReachesIt) {
  // Given a dive from the surface (z = 0) to 40 m depth, and the
  // same dive 100 m deeper (the box does not reach z = 0).
  for (double offset : {0.0, 100.0}) {
    Figure3D f;
    f.width_px = 500;
    f.height_px = 400;
    Polyline3D l;
    l.color = VehicleColor(1);
    for (int i = 0; i <= 100; ++i) l.points.push_back({i * 1.0, i * 0.5, offset + 0.4 * i});
    f.lines.push_back(l);
    Image with, without;
    std::string err;
    ASSERT_TRUE(RenderImage(f, &with, &err)) << err;
    f.sea_surface = false;
    ASSERT_TRUE(RenderImage(f, &without, &err)) << err;
    std::size_t differ = 0;
    for (std::size_t i = 0; i < with.rgba.size(); i += 4) {
      differ += with.rgba[i] != without.rgba[i] || with.rgba[i + 2] != without.rgba[i + 2];
    }
    // Then the plane (and its legend entry) changes much of the picture only if it is there.
    if (offset == 0.0) {
      EXPECT_GT(differ, with.rgba.size() / 4 / 20) << "no sea surface drawn";
    } else {
      EXPECT_EQ(differ, 0u) << "a sea surface outside the box";
    }
  }
}

TEST(Render2D, RendersFromSeveralThreadsAtOnce) {
  // Given four threads drawing at the same time (each needs its own OpenGL context).
  std::vector<Image> images(4);
  std::vector<std::string> errors(4);
  std::vector<int> ok(4, 0);
  std::vector<std::thread> threads;
  for (int k = 0; k < 4; ++k) {
    threads.emplace_back([&, k] {
      for (int rep = 0; rep < 3; ++rep) {
        ok[k] = RenderImage(TwoPanelFigure(500 + 10 * k, 300), &images[k], &errors[k]);
        if (!ok[k]) return;
      }
    });
  }
  for (std::thread& t : threads) t.join();
  // Then every figure is complete.
  for (int k = 0; k < 4; ++k) {
    ASSERT_TRUE(ok[k]) << errors[k];
    EXPECT_EQ(images[k].width, 500 + 10 * k);
    EXPECT_GT(CountColour(images[k], VehicleColor(1)), 100u);
  }
}

// ---------------------------------------------------------------- bad input

TEST(RenderErrors, BadInputIsRefusedWithAMessage) {
  Image img;
  std::string err;
  Figure2D f = TwoPanelFigure(0, 0);
  EXPECT_FALSE(RenderImage(f, &img, &err));
  EXPECT_NE(err.find("too small"), std::string::npos) << err;

  f = TwoPanelFigure(800, 500);
  f.panels[1].series[0].x.clear();
  f.panels[1].series[0].y.clear();
  EXPECT_FALSE(RenderImage(f, &img, &err));
  EXPECT_NE(err.find("panel 2"), std::string::npos) << err;
  EXPECT_NE(err.find("empty"), std::string::npos) << err;

  f = TwoPanelFigure(800, 500);
  f.panels[0].series[1].y.pop_back();
  EXPECT_FALSE(RenderImage(f, &img, &err));
  EXPECT_NE(err.find("same length"), std::string::npos) << err;

  f = TwoPanelFigure(800, 500);
  for (Panel& p : f.panels) {
    for (Series& s : p.series) std::fill(s.y.begin(), s.y.end(), NAN);
  }
  EXPECT_FALSE(RenderImage(f, &img, &err));
  EXPECT_NE(err.find("nothing to draw"), std::string::npos) << err;

  f = TwoPanelFigure(800, 500);
  f.panels.clear();
  EXPECT_FALSE(RenderImage(f, &img, &err));
  EXPECT_NE(err.find("no panels"), std::string::npos) << err;

  f = TwoPanelFigure(800, 500);
  f.panels[1].y.min = -1.0;  // log axis
  EXPECT_FALSE(RenderImage(f, &img, &err));
  EXPECT_NE(err.find("log axis"), std::string::npos) << err;

  f = TwoPanelFigure(800, 500);
  f.font_path = "/nonexistent/font.ttf";
  EXPECT_FALSE(RenderImage(f, &img, &err));
  EXPECT_NE(err.find("/nonexistent/font.ttf"), std::string::npos) << err;

  Figure3D g = HelixFigure(700, 500);
  g.snapshots[0].edges.push_back({0, 7});
  EXPECT_FALSE(RenderImage(g, &img, &err));
  EXPECT_NE(err.find("does not exist"), std::string::npos) << err;
  g = HelixFigure(700, 500);
  g.lines[1].points.clear();
  EXPECT_FALSE(RenderImage(g, &img, &err));
  EXPECT_NE(err.find("line 2"), std::string::npos) << err;
  g = HelixFigure(100, 50);
  EXPECT_FALSE(RenderImage(g, &img, &err));
  EXPECT_NE(err.find("too small"), std::string::npos) << err;
}

TEST(RenderErrors, UnwritablePathIsReported) {
  std::string err;
  EXPECT_FALSE(RenderPng(TwoPanelFigure(400, 300), "/nonexistent_dir/figure.png", &err));
  EXPECT_NE(err.find("/nonexistent_dir/figure.png"), std::string::npos) << err;
  EXPECT_FALSE(RenderPng(HelixFigure(400, 300), "/nonexistent_dir/figure3d.png", &err));
  EXPECT_NE(err.find("figure3d.png"), std::string::npos) << err;
}

TEST(RenderErrors, ExtremeValuesRenderOrAreRefused) {
  const auto one_series = [](std::vector<double> x, std::vector<double> y, bool log) {
    Figure2D f;
    f.width_px = 500;
    f.height_px = 300;
    Panel p;
    p.y.log = log;
    Series s;
    s.x = std::move(x);
    s.y = std::move(y);
    s.marker = Marker::kCircle;
    p.series.push_back(std::move(s));
    f.panels.push_back(std::move(p));
    return f;
  };
  Image img;
  std::string err;
  // Beyond +-1e300 counts as missing.
  EXPECT_FALSE(RenderImage(one_series({0, 1}, {1e308, -1e308}, false), &img, &err));
  EXPECT_NE(err.find("usable"), std::string::npos) << err;
  // 600 decades on a log axis, epoch seconds with a 2 ms range, a vertical line, denormals.
  for (const Figure2D& f :
       {one_series({0, 1, 2}, {1e-300, 1, 1e300}, true),
        one_series({0, 1, 2}, {1.7e9, 1.7e9 + 1e-3, 1.7e9 + 2e-3}, false),
        one_series({5, 5, 5}, {1, 2, 3}, false), one_series({0, 1}, {4.9e-324, 1e-323}, false)}) {
    ASSERT_TRUE(RenderImage(f, &img, &err)) << err;
    EXPECT_EQ(img.width, 500);
    EXPECT_GT(CountColour(img, Color{0, 0, 0, 1}, 40), 20u);  // the black series is drawn
  }
}

// Where a colour's pixels are: their bounding box and count (within `tol` per channel).
struct ColourBox {
  int x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1;
  std::size_t n = 0;
};
ColourBox FindColour(const Image& img, const Color& c, int x_from = 0, int x_to = 1 << 30,
                     int tol = 40) {
  const int r = static_cast<int>(std::lround(c.r * 255)),
            g = static_cast<int>(std::lround(c.g * 255)),
            b = static_cast<int>(std::lround(c.b * 255));
  ColourBox box;
  for (int y = 0; y < img.height; ++y) {
    for (int x = std::max(0, x_from); x < std::min(img.width, x_to); ++x) {
      const std::uint8_t* p = &img.rgba[(static_cast<std::size_t>(y) * img.width + x) * 4];
      if (std::abs(p[0] - r) > tol || std::abs(p[1] - g) > tol || std::abs(p[2] - b) > tol)
        continue;
      ++box.n;
      box.x0 = std::min(box.x0, x);
      box.x1 = std::max(box.x1, x);
      box.y0 = std::min(box.y0, y);
      box.y1 = std::max(box.y1, y);
    }
  }
  return box;
}

TEST(RenderErrors, NonPositiveValuesOnALogAxisAreSkipped) {
  // Given a log-y scatter of 1..100 over x = 0..100, except that x in [40, 60] holds 0,
  // -5 and 1e-310 (positive, but its logarithm would stretch the axis over 300 decades).
  const Color red = Hex(0xD00000);
  Figure2D f;
  f.width_px = 600;
  f.height_px = 400;
  Panel p;
  p.y.log = true;
  p.legend = LegendPlacement::kNone;
  Series s;
  s.line = LineStyle::kNone;
  s.marker = Marker::kSquare;
  s.marker_size_px = 6.0f;
  s.color = red;
  const double bad[3] = {0.0, -5.0, 1e-310};
  for (int i = 0; i <= 100; ++i) {
    s.x.push_back(i);
    s.y.push_back(i >= 40 && i <= 60 ? bad[i % 3] : std::pow(10.0, i / 50.0));
  }
  p.series.push_back(std::move(s));
  f.panels.push_back(std::move(p));
  // When it is rendered,
  Image img;
  std::string err;
  ASSERT_TRUE(RenderImage(f, &img, &err)) << err;
  // then the good points span most of the plot's height (the axis is 1..100, not 1e-310..),
  const ColourBox all = FindColour(img, red);
  ASSERT_GT(all.n, 100u);
  EXPECT_GT(all.y1 - all.y0, img.height / 2);
  // and no marker is drawn where the skipped points are (x in [44, 56], clear of the
  // markers of x = 39 and 61).
  const double px_per_x = (all.x1 - all.x0) / 100.0;
  const ColourBox gap = FindColour(img, red, all.x0 + static_cast<int>(44 * px_per_x),
                                   all.x0 + static_cast<int>(56 * px_per_x));
  EXPECT_EQ(gap.n, 0u) << "markers at x " << gap.x0 << ".." << gap.x1 << ", y " << gap.y0
                       << ".." << gap.y1;
}

}  // namespace
}  // namespace shoal::render
