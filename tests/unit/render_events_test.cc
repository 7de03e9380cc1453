// shoal render on runs with a scenario timeline ([[event]]) and acoustic links: shaded
// bands, the event windows and outages taken from the scenario, and the delay against
// range of acoustic links. The runs are shoal sim's, logged and read back with the
// scenario given in code.
#include <gtest/gtest.h>
#include <stb_image.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include "analysis/analysis.h"
#include "analysis/run_data.h"
#include "analysis/sim_report.h"
#include "core/channel_model.h"
#include "render/figure.h"
#include "render/run_figures.h"
#include "render/shoal_figures.h"
#include "scenario/loader.h"

namespace shoal::render {
namespace {

std::string Tmp(const std::string& name) {
  const std::string dir = std::string(SHOAL_BINARY_DIR) + "/test_tmp";
  std::system(("mkdir -p " + dir).c_str());
  const ::testing::TestInfo* t = ::testing::UnitTest::GetInstance()->current_test_info();
  return dir + "/render_events_" + std::string(t->name()) + "_" + name;
}

Scenario Load(const std::string& file, double seconds) {
  Scenario s = LoadScenario(std::string(SHOAL_SOURCE_DIR) + "/scenarios/" + file);
  s.duration_s = seconds;
  return s;
}

ScenarioEvent Event(EventKind kind, double at_s, double until_s) {
  ScenarioEvent e;
  e.kind = kind;
  e.at_s = at_s;
  e.until_s = until_s;
  return e;
}

RunData SimulateAndLoad(const Scenario& s) {
  SimRunOptions opt;
  opt.out = Tmp("run.lcmlog");
  SimReport report;
  std::string error;
  EXPECT_TRUE(RunSimulation(s, opt, &report, &error)) << error;
  RunData run;
  LoadOptions lo;
  lo.scenario = &s;
  EXPECT_TRUE(LoadRunLog(opt.out, lo, &run, &error)) << error;
  return run;
}

const std::uint8_t* Pixel(const Image& im, int x, int y) {
  return &im.rgba[4 * (static_cast<std::size_t>(y) * im.width + x)];
}

TEST(RenderBands, ABandTintsItsIntervalOnlyAndLeavesTheRangeAlone) {
  Figure2D f;
  f.width_px = 800;
  f.height_px = 500;
  Panel p;
  p.x.min = 0.0;
  p.x.max = 10.0;
  p.y.min = 0.0;
  p.y.max = 1.0;
  Series s;
  s.x = {0.0, 10.0};
  s.y = {0.05, 0.05};
  p.series.push_back(s);
  p.bands.push_back({4.0, 6.0, kAutoRange, kAutoRange, Color{1.0f, 0.0f, 0.0f, 0.5f}, ""});
  p.bands.push_back({1e300, NAN, kAutoRange, kAutoRange, Color{0.0f, 0.0f, 1.0f, 0.5f}, "x"});
  f.panels.push_back(p);
  Image im;
  std::string err;
  ASSERT_TRUE(RenderImage(f, &im, &err)) << err;
  // Scan the middle row: reddish pixels form one run whose centre is the plot's centre.
  const int y = im.height / 2;
  int first = -1, last = -1, blue = 0;
  for (int x = 0; x < im.width; ++x) {
    const std::uint8_t* c = Pixel(im, x, y);
    const bool red = c[0] > 200 && c[1] < 160 && c[2] < 160;
    if (red && first < 0) first = x;
    if (red) last = x;
    blue += c[2] > 200 && c[0] < 160;
  }
  ASSERT_GT(first, 0);
  EXPECT_EQ(blue, 0);  // the non-finite band is not drawn
  // The band spans a fifth of the plot's width; the plot is most of the figure.
  EXPECT_GT(last - first, im.width / 5 - im.width / 10);
  EXPECT_LT(last - first, im.width / 5 + 5);
}

TEST(RenderEvents, WindowsAndOutagesComeFromTheScenario) {
  Scenario s = Load("paper_example2.toml", 10.0);
  ScenarioEvent down = Event(EventKind::kLinkDown, 2.0, 4.0);
  down.links = {{0, 1}};
  ScenarioEvent silent = Event(EventKind::kVehicleSilent, 3.0, 1e300);
  silent.vehicles = {2};
  ScenarioEvent deaf = Event(EventKind::kVehicleDeaf, 5.0, 6.0);
  deaf.vehicles = {4};
  ScenarioEvent reset = Event(EventKind::kControllerReset, 7.0, 1e300);
  reset.vehicles = {3};
  reset.outage_s = 0.5;
  s.events = {down, silent, deaf, reset};
  const RunData run = SimulateAndLoad(s);
  const std::vector<EventWindow> w = EventWindowsOf(run, 10.0);
  ASSERT_EQ(w.size(), 4u);
  EXPECT_EQ(w[0].label, "link_down");
  EXPECT_EQ(w[0].t0_s, 2.0);
  EXPECT_EQ(w[0].t1_s, 4.0);
  EXPECT_EQ(w[1].t1_s, 10.0);  // to the end of the run
  EXPECT_EQ(w[3].label, "controller_reset");
  EXPECT_EQ(w[3].t1_s, 7.5);
  const std::vector<LinkOutage> o = OutagesOf(run, 10.0);
  // 0->1 down; 2 sends to 5 only; 4 receives from 5 only; a reset is no outage.
  ASSERT_EQ(o.size(), 3u);
  EXPECT_EQ(o[0].from, 0);
  EXPECT_EQ(o[0].to, 1);
  EXPECT_EQ(o[0].label, "link down");
  EXPECT_EQ(o[1].from, 2);
  EXPECT_EQ(o[1].to, 5);
  EXPECT_EQ(o[1].label, "silent");
  EXPECT_EQ(o[1].t1_s, 10.0);
  EXPECT_EQ(o[2].from, 5);
  EXPECT_EQ(o[2].to, 4);
  EXPECT_EQ(o[2].label, "deaf");

  const std::string dir = Tmp("out");
  std::string err;
  ASSERT_TRUE(PrepareOutputDir(dir, &err)) << err;
  RunFigureReport report;
  RunFigureOptions opt;
  ASSERT_TRUE(WriteRunFigures(run, dir, opt, &report, &err)) << err;
  EXPECT_TRUE(report.failures.empty()) << report.failures.front();
  EXPECT_EQ(report.written.size(), 4u);  // no acoustic link: no acoustic_delay.png
  // The channel figure's drops panel carries the outages as bands on their rows.
  const RunAnalysis a = AnalyseRun(run);
  ChannelOptions c = ChannelOptionsOf(run, a);
  c.outages = o;
  const Figure2D cf = ChannelFigure(LinkSeriesOf(run), c);
  EXPECT_EQ(cf.panels.back().bands.size(), 3u);
}

// A log whose events are out of order (cut and joined the other way round): each link's
// series, and the configured tau(t), still run over the whole run in time order.
TEST(RenderEvents, ChannelEventsOutOfOrderAreDrawnInTimeOrder) {
  RunData run = SimulateAndLoad(Load("paper_example2.toml", 10.0));
  const std::vector<LinkSeries> in_order = LinkSeriesOf(run);
  const RunAnalysis a = AnalyseRun(run);
  const ChannelOptions c_in_order = ChannelOptionsOf(run, a);
  std::vector<ChannelEventRecord>& ev = run.channel_events;
  std::rotate(ev.begin(), ev.begin() + static_cast<std::ptrdiff_t>(ev.size() / 2), ev.end());
  const std::vector<LinkSeries> swapped = LinkSeriesOf(run);
  ASSERT_EQ(swapped.size(), in_order.size());
  for (std::size_t i = 0; i < swapped.size(); ++i) {
    EXPECT_EQ(swapped[i].sent_s, in_order[i].sent_s) << i;
    EXPECT_EQ(swapped[i].delay_s, in_order[i].delay_s) << i;
    EXPECT_EQ(swapped[i].dropped_s, in_order[i].dropped_s) << i;
  }
  const ChannelOptions c = ChannelOptionsOf(run, a);
  EXPECT_EQ(c.tau_t_s, c_in_order.tau_t_s);
  ASSERT_FALSE(c.tau_t_s.empty());
  EXPECT_NEAR(c.tau_t_s.back(), 10.0, 0.011);
}

TEST(RenderEvents, AcousticDelayAgainstRangeLiesOnTheModel) {
  Scenario s = Load("acoustic_survey.toml", 40.0);
  const RunData run = SimulateAndLoad(s);
  AcousticPoints p;
  std::vector<AcousticModelLine> models;
  ASSERT_TRUE(AcousticOf(run, &p, &models));
  ASSERT_EQ(models.size(), 1u);
  const AcousticModelLine& m = models[0];
  EXPECT_EQ(m.sound_speed_mps, s.delay.sound_speed_mps);
  ASSERT_GT(p.range_m.size(), 100u);
  std::size_t delivered = 0;
  for (const ChannelEventRecord& e : run.channel_events) delivered += e.status == 0;
  EXPECT_EQ(p.range_m.size(), delivered);
  // The drawn delay is range / c + processing + a jitter draw in [0, jitter], the range
  // that of the logged states at the send time to within a tick's travel (< 1 ms of
  // delay). At t = 0 a receiver that publishes after the sender has no position yet, and
  // the channel takes its range as 0: those lie below the line.
  std::size_t below_at_start = 0;
  for (std::size_t k = 0; k < p.range_m.size(); ++k) {
    const double line = p.range_m[k] / m.sound_speed_mps + m.processing_s;
    if (p.send_s[k] == 0.0 && p.drawn_delay_s[k] < line - 1e-3) {
      ++below_at_start;
      continue;
    }
    EXPECT_GE(p.drawn_delay_s[k], line - 1e-3) << k;
    EXPECT_LE(p.drawn_delay_s[k], line + m.jitter_s + 1e-3) << k;
    EXPECT_GE(p.realised_delay_s[k], p.drawn_delay_s[k] - 1e-6);
  }
  EXPECT_LE(below_at_start, 6u);  // at most one per link at t = 0
  // A state the busy modem never transmitted is neither delivered nor dropped in the
  // channel figure, as in shoal analyze's counts.
  std::size_t skipped = 0, transmitted = 0, drawn = 0;
  for (const ChannelEventRecord& e : run.channel_events) {
    skipped += shoal::NotTransmitted(e.status);
    transmitted += !shoal::NotTransmitted(e.status);
  }
  ASSERT_GT(skipped, 100u);
  for (const LinkSeries& l : LinkSeriesOf(run)) drawn += l.sent_s.size() + l.dropped_s.size();
  EXPECT_EQ(drawn, transmitted);
  const std::string dir = Tmp("out");
  std::string err;
  ASSERT_TRUE(PrepareOutputDir(dir, &err)) << err;
  RunFigureReport report;
  ASSERT_TRUE(WriteRunFigures(run, dir, RunFigureOptions(), &report, &err)) << err;
  EXPECT_TRUE(report.failures.empty());
  EXPECT_EQ(report.written.back(), dir + "/acoustic_delay.png");
  int w = 0, h = 0, n = 0;
  unsigned char* px = stbi_load((dir + "/acoustic_delay.png").c_str(), &w, &h, &n, 4);
  ASSERT_NE(px, nullptr);
  EXPECT_EQ(w, 1600);
  stbi_image_free(px);
}

}  // namespace
}  // namespace shoal::render
