// render/campaign_figures: the stability map and the soak figure from synthetic data,
// written as PNGs and checked by size and pixel colours (never against stored images);
// bad input refused with a message. With SHOAL_CAMPAIGN_FIGURES_DIR set, the PNGs are
// written there and kept (to look at them).
#include <gtest/gtest.h>
#include <stb_image.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "render/campaign_figures.h"

// libOSMesa (Mesa 22.3) leaks about 320 bytes per context; not ours (see render_test.cc).
extern "C" const char* __lsan_default_suppressions() { return "leak:libOSMesa.so\n"; }

namespace shoal::render {
namespace {

// The colours render/campaign_figures.h names: pass bluish green, fail vermillion,
// crashed purple, the exact margin blue.
const Color kPass = Hex(0x009E73), kFail = Hex(0xD55E00), kCrash = Hex(0x5B2A86),
            kExact = Hex(0x0072B2);

struct Png {
  int w = 0, h = 0;
  std::vector<unsigned char> rgb;
  std::size_t Count(const Color& c, int tol = 14) const {
    const int r = static_cast<int>(std::lround(c.r * 255)),
              g = static_cast<int>(std::lround(c.g * 255)),
              b = static_cast<int>(std::lround(c.b * 255));
    std::size_t n = 0;
    for (std::size_t i = 0; i + 2 < rgb.size(); i += 3) {
      if (std::abs(rgb[i] - r) <= tol && std::abs(rgb[i + 1] - g) <= tol &&
          std::abs(rgb[i + 2] - b) <= tol) {
        ++n;
      }
    }
    return n;
  }
};

bool Keep() { return std::getenv("SHOAL_CAMPAIGN_FIGURES_DIR") != nullptr; }

std::string OutPath(const std::string& name) {
  const char* dir = std::getenv("SHOAL_CAMPAIGN_FIGURES_DIR");
  return ((dir ? std::filesystem::path(dir) : std::filesystem::temp_directory_path()) /
          ("shoal_campaign_figures_test_" + name + ".png"))
      .string();
}

Png Read(const std::string& path) {
  Png p;
  int n = 0;
  unsigned char* data = stbi_load(path.c_str(), &p.w, &p.h, &n, 3);
  if (data) {
    p.rgb.assign(data, data + static_cast<std::size_t>(p.w) * p.h * 3);
    stbi_image_free(data);
  }
  if (!Keep()) std::filesystem::remove(path);
  return p;
}

// A k1 x delay-base sweep shaped like a real one: passes under a margin that falls with
// k1, Theorem 3 certifying less and infeasible at the two largest k1, two crashed points.
StabilityMapData SyntheticMap() {
  StabilityMapData d;
  d.title = "k1_delay_sweep";
  d.subtitle = "pass: converged = true, final_position_error_m <= 0.5";
  d.has_y = true;
  d.x = {"control.k1", "1/s\xC2\xB2", false};
  d.y = {"channel.delay.base_s", "s", false};
  for (int i = 0; i < 10; ++i) {
    const double k1 = 0.05 + 0.05 * i;
    const double margin = 0.12 / std::sqrt(k1);
    d.curve_at.push_back(k1);
    d.exact_margin.push_back(margin);
    d.theorem3.push_back(i >= 8 ? NAN : 0.55 * margin);
    for (int j = 0; j < 12; ++j) {
      const double base = 0.05 + 0.05 * j;
      d.x_values.push_back(k1);
      d.y_values.push_back(base);
      d.outcome.push_back(base < 0.95 * margin ? "pass" : "fail");
    }
  }
  d.outcome[17] = "crashed";
  d.outcome[60] = "timeout";
  d.exact_note = "channel.delay.base_s = bound - 0.05 s";
  return d;
}

TEST(StabilityMap, TwoAxesShowPassFailCrashedAndTheTheory) {
  const std::string path = OutPath("map");
  std::string err;
  ASSERT_TRUE(RenderStabilityMap(SyntheticMap(), path, &err)) << err;
  const Png png = Read(path);
  ASSERT_FALSE(png.rgb.empty()) << path;
  EXPECT_EQ(png.w, 1400);
  EXPECT_EQ(png.h, 1000);
  EXPECT_GT(png.Count(kPass), 1000u);  // 50-odd discs of 11 px
  EXPECT_GT(png.Count(kFail), 300u);
  EXPECT_GT(png.Count(kCrash), 30u);   // two triangles and the legend's
  EXPECT_GT(png.Count(kExact), 300u);  // the margin's polyline
}

TEST(StabilityMap, OneAxisShowsTheBoundsAsVerticalLines) {
  StabilityMapData d;
  d.title = "delay_sweep";
  d.x = {"channel.delay.base_s", "s", false};
  for (int i = 0; i < 20; ++i) {
    d.x_values.push_back(0.025 * (i + 1));
    d.outcome.push_back(d.x_values.back() < 0.29 ? "pass" : "fail");
  }
  d.exact_margin = {0.2935};
  d.theorem3 = {0.12};
  d.width_px = 1000;
  d.height_px = 600;
  const std::string path = OutPath("map_one_axis");
  std::string err;
  ASSERT_TRUE(RenderStabilityMap(d, path, &err)) << err;
  const Png png = Read(path);
  ASSERT_FALSE(png.rgb.empty());
  EXPECT_EQ(png.w, 1000);
  EXPECT_EQ(png.h, 600);
  EXPECT_GT(png.Count(kPass), 300u);
  EXPECT_GT(png.Count(kFail), 200u);
  EXPECT_GT(png.Count(kExact), 300u);  // a vertical line across the plot
  EXPECT_EQ(png.Count(kCrash, 6), 0u);  // no crashed point: no class, no legend entry
}

TEST(StabilityMap, UndefinedBoundsAreSaidInTheLegendAndNotDrawn) {
  StabilityMapData d = SyntheticMap();
  Figure2D f;
  std::string err;
  ASSERT_TRUE(StabilityMapFigure(d, &f, &err)) << err;
  bool said = false;
  for (const Series& s : f.panels[0].series) {
    if (s.label.find("Theorem 3") != std::string::npos) {
      said = s.label.find("undefined at 2 of 10 values") != std::string::npos;
    }
  }
  EXPECT_TRUE(said);
  // A bound far above the points is clipped, not allowed to squash them.
  d.exact_margin.assign(d.exact_margin.size(), 50.0);
  ASSERT_TRUE(StabilityMapFigure(d, &f, &err)) << err;
  EXPECT_LT(f.panels[0].y.max, 2.0);
}

TEST(StabilityMap, BadInputIsRefusedWithAMessage) {
  StabilityMapData d = SyntheticMap();
  d.outcome.pop_back();
  std::string err;
  EXPECT_FALSE(RenderStabilityMap(d, OutPath("bad"), &err));
  EXPECT_NE(err.find("one per point"), std::string::npos) << err;
  d = SyntheticMap();
  d.theorem3.pop_back();
  EXPECT_FALSE(RenderStabilityMap(d, OutPath("bad"), &err));
  EXPECT_NE(err.find("curve_at"), std::string::npos) << err;
  d = StabilityMapData{};
  EXPECT_FALSE(RenderStabilityMap(d, OutPath("bad"), &err));
  EXPECT_NE(err.find("no points"), std::string::npos) << err;
}

// Four 10-minute phases of a delay soak, sampled every 10 s; phase 3 fails on lateness.
SoakFigureData SyntheticSoak() {
  SoakFigureData d;
  d.title = "soak: channel.delay.base_s, realtime";
  d.verdict = "FAIL (phase 3: lateness p99)";
  d.phase_key = "channel.delay.base_s";
  const char* values[4] = {"0.1", "0.2", "0.3", "0.4"};
  for (int k = 0; k < 4; ++k) {
    d.phases.push_back({600.0 * k, 600.0 * (k + 1), values[k], k != 2,
                        k == 2 ? "lateness p99 3.1 ms > 2 ms" : ""});
  }
  d.position_tol_m = 0.5;
  d.lateness_p99_max_s = 0.002;
  d.delay_error_p99_max_s = 0.001;
  d.rss = {{"vehicle 1", {}, {}}, {"channel emulator", {}, {}}};
  for (int i = 0; i <= 240; ++i) {
    const double t = 10.0 * i;
    const double phase = std::floor(t / 600.0);
    d.error_t_s.push_back(t);
    d.worst_position_error_m.push_back(5.0 * std::exp(-t / 200.0) + 0.01 * (1 + phase));
    d.lateness_t_s.push_back(t);
    d.lateness_p99_s.push_back(phase == 2 ? 0.0031 : 0.0008 + 0.0001 * std::sin(t));
    d.delay_error_t_s.push_back(t);
    d.delay_error_p99_s.push_back(0.0004 + 0.0001 * std::cos(t / 50.0));
    d.rss[0].t_s.push_back(t);
    d.rss[0].rss_mib.push_back(42.0 + 0.001 * t);
    d.rss[1].t_s.push_back(t);
    d.rss[1].rss_mib.push_back(18.0);
    if (i % 6 == 0 && i > 0) {
      d.logged_t_s.push_back(t);
      d.logged_per_min.push_back(phase == 2 ? 17700.0 : 18000.0);
      d.expected_per_min.push_back(18000.0);
    }
  }
  return d;
}

TEST(SoakFigure, PanelsPhasesAndTheFailedPhase) {
  const std::string path = OutPath("soak");
  std::string err;
  const SoakFigureData d = SyntheticSoak();
  Figure2D f;
  ASSERT_TRUE(SoakFigure(d, &f, &err)) << err;
  EXPECT_EQ(f.panels.size(), 5u);
  EXPECT_EQ(f.panels[0].x.unit, "min");
  EXPECT_NE(f.panels[0].note.find("lateness p99 3.1 ms"), std::string::npos);
  ASSERT_TRUE(RenderSoakFigure(d, path, &err)) << err;
  const Png png = Read(path);
  ASSERT_FALSE(png.rgb.empty());
  EXPECT_EQ(png.w, 1600);
  EXPECT_EQ(png.h, 1400);
  // The failed phase's red band over white (alpha 0.22 of 0xE0102A).
  EXPECT_GT(png.Count(Hex(0xF8CAD0), 6), 5000u);
  EXPECT_GT(png.Count(VehicleColor(1)), 300u);  // lateness and the first process' RSS
}

TEST(SoakFigure, LongSoaksAreInHoursAndEmptySeriesAreLeftOut) {
  SoakFigureData d;
  d.phases = {{0.0, 4.0 * 3600.0, "1", true, ""}};
  d.lateness_t_s = {0.0, 3600.0, 14400.0};
  d.lateness_p99_s = {0.001, 0.001, 0.0012};
  Figure2D f;
  std::string err;
  ASSERT_TRUE(SoakFigure(d, &f, &err)) << err;
  ASSERT_EQ(f.panels.size(), 1u);
  EXPECT_EQ(f.panels[0].x.unit, "h");
  d.lateness_p99_s.pop_back();
  EXPECT_FALSE(SoakFigure(d, &f, &err));
  EXPECT_NE(err.find("lateness_p99_s"), std::string::npos) << err;
  EXPECT_FALSE(SoakFigure(SoakFigureData{}, &f, &err));
  EXPECT_NE(err.find("no series"), std::string::npos) << err;
}

}  // namespace
}  // namespace shoal::render
