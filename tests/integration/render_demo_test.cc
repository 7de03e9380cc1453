// render_demo as a user runs it: headless, five PNGs of the requested size, bad options
// refused with exit status 2 and a message.
#include <gtest/gtest.h>
#include <stb_image.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "tests/integration/test_util.h"

namespace shoal {
namespace {

struct Result {
  int status = -1;
  std::string err;
};

Result RunDemo(const std::string& args) {
  const std::string err_file = shoal::testing::TmpPath("render_demo.err");
  const std::string cmd = std::string(SHOAL_BINARY_DIR) + "/render/render_demo " + args +
                          " >/dev/null 2>" + err_file + " </dev/null";
  const int raw = std::system(cmd.c_str());
  Result r;
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : 128 + WTERMSIG(raw);
  r.err = shoal::testing::ReadFile(err_file);
  return r;
}

TEST(RenderDemo, WritesEveryFigureAtTheRequestedSize) {
  const std::string dir = shoal::testing::TmpPath("render_demo_out");
  std::filesystem::remove_all(dir);
  const Result r = RunDemo("--out " + dir + " --duration 30 --size 900x600");
  ASSERT_EQ(r.status, 0) << r.err;
  for (const char* name :
       {"trajectories.png", "states.png", "errors.png", "errors_linear.png", "channel.png"}) {
    const std::string path = dir + "/" + name;
    int w = 0, h = 0, n = 0;
    unsigned char* data = stbi_load(path.c_str(), &w, &h, &n, 3);
    ASSERT_NE(data, nullptr) << path;
    EXPECT_EQ(w, 900) << name;
    EXPECT_EQ(h, 600) << name;
    // Not blank: a good share of the pixels is not white.
    std::size_t drawn = 0;
    for (int i = 0; i < w * h; ++i) {
      drawn += data[3 * i] < 240 || data[3 * i + 1] < 240 || data[3 * i + 2] < 240;
    }
    EXPECT_GT(drawn, static_cast<std::size_t>(w * h / 50)) << name;
    stbi_image_free(data);
  }
}

TEST(RenderDemo, BadOptionsExitTwoWithAMessage) {
  const std::string dir = shoal::testing::TmpPath("render_demo_bad");
  Result r = RunDemo("--out " + dir + " --size 100x80");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("too small"), std::string::npos) << r.err;
  r = RunDemo("--out " + dir + " --size big");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("not WxH"), std::string::npos) << r.err;
  r = RunDemo("--out /proc/no_such_place/x");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("cannot create directory"), std::string::npos) << r.err;
  r = RunDemo("--duration -5");
  EXPECT_EQ(r.status, 2);
}

}  // namespace
}  // namespace shoal
