#pragma once

#include <string>

namespace shoal {

struct RenderOptions {
  std::string log;
  std::string out_dir;
  std::string size;        // "WxH" for every figure; "" = each figure's default
  std::string scenario;    // overrides the log's scenario
  bool linear_errors = false;  // tracking errors on a linear instead of a log axis
  bool quiet = false;
  std::string key_file;    // the run's key (default: <log>.key if it exists)
};

/// `shoal render LOG --out DIR`: the run's figures as PNG, drawn off-screen with OSMesa:
/// trajectory.png (3-D), states.png, errors.png, channel.png. Exit 0 drawn, 2 bad input
/// or nothing to draw, 1 a figure could not be drawn or written.
int RunRender(const RenderOptions& opt);

}  // namespace shoal
