// `shoal render` as a user runs it: every figure of a shoal sim log at the requested size,
// not blank, in the vehicles' colours; bad input exits 2 with a message.
#include <sys/wait.h>

#include <gtest/gtest.h>
#include <stb_image.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <set>
#include <string>

#include "render/figure.h"
#include "runtime/channels.h"
#include "runtime/log_writer.h"
#include "runtime/messages.h"
#include "tests/integration/test_util.h"

namespace shoal {
namespace {

using shoal::testing::RunShoal;
using shoal::testing::SourcePath;
using shoal::testing::TmpPath;

struct Stats {
  int w = 0, h = 0;
  std::size_t colours = 0;
  double drawn = 0.0;  // fraction of pixels that are not (near) white
  bool has_colour(const render::Color& c) const { return found.count(Key(c)) > 0; }
  std::set<int> found;  // colours quantised to 4 bits per channel
  static int Key(int r, int g, int b) { return (r >> 4) << 8 | (g >> 4) << 4 | (b >> 4); }
  static int Key(const render::Color& c) {
    return Key(static_cast<int>(std::lround(c.r * 255)), static_cast<int>(std::lround(c.g * 255)),
               static_cast<int>(std::lround(c.b * 255)));
  }
};

Stats Load(const std::string& path) {
  Stats s;
  int n = 0;
  unsigned char* d = stbi_load(path.c_str(), &s.w, &s.h, &n, 3);
  if (!d) return s;
  std::set<int> exact;
  std::size_t drawn = 0;
  for (int i = 0; i < s.w * s.h; ++i) {
    const int r = d[3 * i], g = d[3 * i + 1], b = d[3 * i + 2];
    exact.insert(r << 16 | g << 8 | b);
    s.found.insert(Stats::Key(r, g, b));
    drawn += (r < 235 || g < 235 || b < 235);
  }
  stbi_image_free(d);
  s.colours = exact.size();
  s.drawn = static_cast<double>(drawn) / (s.w * s.h);
  return s;
}

TEST(RenderCli, EveryFigureOfASimLogAtTheRequestedSizeAndNotBlank) {
  const std::string log = TmpPath("render_cli.lcmlog");
  const std::string dir = TmpPath("render_cli_figures");
  std::filesystem::remove_all(dir);
  ASSERT_EQ(RunShoal("sim " + SourcePath("scenarios/paper_example2.toml") +
                         " --duration 60 --quiet --out " + log, "rc_sim").status, 0);
  const auto r = RunShoal("render " + log + " --out " + dir + " --size 900x600", "rc_render");
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  for (const char* name : {"trajectory", "states", "errors", "channel"}) {
    const std::string path = dir + "/" + name + ".png";
    EXPECT_NE(r.out.find(path), std::string::npos) << r.out;
    const Stats s = Load(path);
    EXPECT_EQ(s.w, 900) << path;
    EXPECT_EQ(s.h, 600) << path;
    EXPECT_GT(s.colours, 50u) << path;  // anti-aliased lines and text in several colours
    EXPECT_GT(s.drawn, 0.02) << path;
    EXPECT_LT(s.drawn, 0.9) << path;    // not a filled canvas either
    if (std::string(name) != "channel") {  // the channel figure is coloured by receiver
      for (int id = 1; id <= 5; ++id) {
        EXPECT_TRUE(s.has_colour(render::VehicleColor(id))) << path << " follower " << id;
      }
    }
  }
  EXPECT_TRUE(Load(dir + "/trajectory.png").has_colour(render::VehicleColor(0)));
}

// Loading libOSMesa (and llvmpipe's LLVM) costs about 20 ms at every start of a program that
// links it, paid by every point of a campaign. shoal loads it when it first draws: the
// dynamic loader's trace of `shoal sim` must not name it, that of `shoal render` must.
TEST(RenderCli, OnlyCommandsThatDrawLoadOsMesa) {
  const std::string log = TmpPath("render_load.lcmlog");
  const std::string dir = TmpPath("render_load_figures");
  const std::string sim_trace = TmpPath("render_load_sim.ld");
  const std::string render_trace = TmpPath("render_load_render.ld");
  std::filesystem::remove_all(dir);
  // The loader writes its trace to stderr; the commands print nothing there when they work.
  const auto traced = [](const std::string& args, const std::string& trace) {
    const std::string cmd = "LD_DEBUG=files " + shoal::testing::ShoalBinary() + " " + args +
                            " >/dev/null 2>" + trace + " </dev/null";
    return std::system(cmd.c_str());
  };
  ASSERT_EQ(traced("sim " + SourcePath("scenarios/paper_example2.toml") +
                       " --duration 60 --quiet --out " + log, sim_trace), 0);
  ASSERT_EQ(traced("render " + log + " --out " + dir + " --size 400x300", render_trace), 0);
  const std::string sim = shoal::testing::ReadFile(sim_trace);
  const std::string render = shoal::testing::ReadFile(render_trace);
  EXPECT_NE(sim.find("libstdc++"), std::string::npos) << "no loader trace: " << sim;
  EXPECT_EQ(sim.find("libOSMesa"), std::string::npos) << sim;
  EXPECT_NE(render.find("libOSMesa"), std::string::npos) << render;
  EXPECT_TRUE(std::filesystem::exists(dir + "/trajectory.png"));
}

// A machine without libOSMesa, or SHOAL_OSMESA_LIBRARY naming something else: every figure
// fails with what to install, exit 1, and nothing else is lost (the log is only read).
TEST(RenderCli, AMissingOrWrongOsMesaIsAClearError) {
  const std::string log = TmpPath("render_noosmesa.lcmlog");
  ASSERT_EQ(RunShoal("sim " + SourcePath("scenarios/paper_example2.toml") +
                         " --duration 60 --quiet --out " + log, "rn_sim").status, 0);
  const std::string before = shoal::testing::ReadFile(log);
  struct Case {
    std::string library, expected;
  };
  const Case cases[] = {
      {"/nonexistent/libOSMesa.so.8",
       "cannot load /nonexistent/libOSMesa.so.8 for off-screen figures (install libosmesa6"},
      {"libz.so.1", "libz.so.1 has no OSMesaCreateContextAttribs"},
  };
  for (const Case& c : cases) {
    const std::string dir = TmpPath("render_noosmesa_figures");
    const std::string err = TmpPath("render_noosmesa.err");
    std::filesystem::remove_all(dir);
    const std::string cmd = "SHOAL_OSMESA_LIBRARY=" + c.library + " " +
                            shoal::testing::ShoalBinary() + " render " + log + " --out " + dir +
                            " >/dev/null 2>" + err + " </dev/null";
    const int raw = std::system(cmd.c_str());
    ASSERT_TRUE(WIFEXITED(raw)) << c.library;
    EXPECT_EQ(WEXITSTATUS(raw), 1) << c.library;
    const std::string text = shoal::testing::ReadFile(err);
    EXPECT_NE(text.find(c.expected), std::string::npos) << text;
    EXPECT_FALSE(std::filesystem::exists(dir + "/trajectory.png")) << c.library;
  }
  EXPECT_EQ(shoal::testing::ReadFile(log), before);
}

std::string Bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// States at impossible times (utime = INT64_MAX, negative, 1e9 s) appended to a 20 s log
// would stretch every time axis to 9e12 s, a channel event sent at 1e9 s the delay curve,
// one delivered 1e9 s after sending the delay panel: they are left out (the rule of shoal
// analyze, ChannelEventTimeOf), with a warning, and every figure is the clean log's, byte
// for byte.
TEST(RenderCli, StatesAtImpossibleTimesDoNotStretchTheAxes) {
  const std::string clean = TmpPath("render_impossible_clean.lcmlog");
  const std::string forged = TmpPath("render_impossible_forged.lcmlog");
  const std::string damaged = TmpPath("render_impossible.lcmlog");
  ASSERT_EQ(RunShoal("sim " + SourcePath("scenarios/paper_example2.toml") +
                         " --duration 20 --quiet --out " + clean, "ri_sim").status, 1);
  {
    LogWriter log(forged);
    const std::pair<int, std::int64_t> bad[] = {
        {3, std::numeric_limits<std::int64_t>::max()}, {0, -1000000}, {2, 1000000000000000}};
    for (const auto& [id, utime] : bad) {
      StateMsg m;
      m.vehicle_id = id;
      m.utime = utime;
      m.eta = Vec5::Constant(1e6);
      m.eta_dot = m.nu = Vec5::Constant(1e3);
      log.Write(channels::State(id), 20000000, ToLcm(m));
    }
    // Channel events sent at 1e9 s (a delay curve drawn up to it took 8e11 bytes), at
    // -1 s, delivered before they were sent, and delivered 1e9 s after sending (a delay
    // panel scaled to it shows the run's delays as one flat line).
    ChannelDecision late, early, negative, far;
    late.sender = early.sender = negative.sender = far.sender = 1;
    late.receiver = early.receiver = negative.receiver = far.receiver = 2;
    late.send_utime = 1000000000000000;
    late.deliver_utime = late.send_utime + 100000;
    early.send_utime = 10000000;
    early.deliver_utime = 5000000;
    negative.send_utime = -1000000;
    negative.deliver_utime = -900000;
    far.send_utime = 3000000;
    far.deliver_utime = far.send_utime + 1000000000000000;
    std::int32_t seq = 0;
    for (const ChannelDecision* d : {&late, &early, &negative, &far}) {
      log.Write(channels::ChannelEvents(), 20000000, ToLcm(*d, seq++));
    }
  }
  ASSERT_EQ(std::system(("cat '" + clean + "' '" + forged + "' > '" + damaged + "'").c_str()), 0);
  const std::string dir_c = TmpPath("render_impossible_clean"), dir_d = TmpPath("render_impossible");
  std::filesystem::remove_all(dir_c);
  std::filesystem::remove_all(dir_d);
  ASSERT_EQ(RunShoal("render " + clean + " --out " + dir_c, "ri_clean").status, 0);
  const auto r = RunShoal("render " + damaged + " --out " + dir_d, "ri_damaged");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("3 vehicle states and 4 channel events at impossible times"),
            std::string::npos) << r.err;
  for (const char* name : {"trajectory", "states", "errors", "channel"}) {
    const std::string a = Bytes(dir_c + "/" + name + ".png"), b = Bytes(dir_d + "/" + name + ".png");
    EXPECT_FALSE(a.empty()) << name;
    EXPECT_TRUE(a == b) << name;
  }
}

TEST(RenderCli, BadInputExitsTwoWithAMessage) {
  const std::string dir = TmpPath("render_cli_bad");
  const std::string empty = TmpPath("render_cli_empty.lcmlog");
  const std::string text = TmpPath("render_cli_text.lcmlog");
  std::fclose(std::fopen(empty.c_str(), "w"));
  FILE* f = std::fopen(text.c_str(), "w");
  std::fputs("this is not an LCM log\n", f);
  std::fclose(f);
  struct Case {
    std::string args, says;
  } cases[] = {
      {"render /nonexistent.lcmlog --out " + dir, "nonexistent"},
      {"render " + empty + " --out " + dir, "empty"},
      {"render " + text + " --out " + dir, "LCM"},
      {"render " + empty + " --out " + dir + " --size 10x10", "--size"},
      {"render " + empty + " --out " + dir + " --size big", "--size"},
      // Past an int's range: refused, not wrapped into it (4294968896 is 2^32 + 1600).
      {"render " + empty + " --out " + dir + " --size 4294968896x1000", "--size"},
      {"render " + empty + " --out " + dir + " --size 1600x1000px", "--size"},
      {"render " + empty + " --out " + text, "not a directory"},
      {"render " + empty, "--out"},
  };
  for (const Case& c : cases) {
    const auto r = RunShoal(c.args, "rc_bad");
    EXPECT_EQ(r.status, 2) << c.args << "\n" << r.out << r.err;
    EXPECT_NE(r.err.find(c.says), std::string::npos) << c.args << "\n" << r.err;
  }
}

}  // namespace
}  // namespace shoal
