// The figures of a campaign (`shoal sweep`, `shoal soak`), built from plain arrays and
// written as PNGs through Figure2D. The caller reads the campaign's results; these
// functions only arrange the numbers, so that they can be tested on synthetic data.
#pragma once

#include <string>
#include <vector>

#include "render/figure.h"

namespace shoal::render {

/// One axis of the stability map: a scenario key and its unit.
struct MapAxis {
  std::string label;  ///< e.g. "channel.delay.base_s" or "delay base"
  std::string unit;   ///< e.g. "s"; empty: none
  bool log = false;
};

/// The points of a sweep and the theory on the same axes.
///
/// Points: x[i] (and y[i] with two axes) and outcome[i], one of "pass", "fail", or
/// anything else ("crashed", "timeout", "no_result"), drawn as one third class.
///
/// Theory: the delay bounds as functions of the other axis. `delay_on_y` says which axis
/// is the delay (two axes; with one axis the delay is x). curve_at holds values of the
/// non-delay axis; exact_margin and theorem3 the bound on the delay axis at each (as long
/// as curve_at; NaN where undefined, e.g. Theorem 3 infeasible; only the defined stretches
/// are drawn, and the legend counts the rest). With one axis, curve_at is ignored and the
/// first value of each bound is drawn as a vertical line. Empty vectors: no curve.
struct StabilityMapData {
  std::string title;     ///< e.g. the campaign's name
  std::string subtitle;  ///< one line under the title (e.g. the pass criteria); may be empty
  MapAxis x, y;
  bool has_y = false;  ///< false: one axis (pass/fail along x)
  std::vector<double> x_values, y_values;
  std::vector<std::string> outcome;

  bool delay_on_y = true;
  std::vector<double> curve_at;
  std::vector<double> exact_margin;
  std::vector<double> theorem3;
  /// Shown on the line under the title after the subtitle, e.g. how a bound was put on
  /// the axis or why it is undefined somewhere.
  std::string exact_note, theorem3_note;

  int width_px = 1400, height_px = 1000;
};

/// Points coloured pass (green disc, 0x009E73), fail (vermillion cross, 0xD55E00), crashed
/// or timed out (purple triangle, 0x5B2A86); the exact delay margin (blue 0x0072B2, solid)
/// and Theorem 3's certified delay (near black, dashed) over them; the legend, with the
/// count of each class, under the title. False with *err on bad input (mismatched
/// lengths, no points) or when the PNG cannot be drawn or written.
bool RenderStabilityMap(const StabilityMapData& data, const std::string& png_path,
                        std::string* err);

/// The figure itself, for callers that render it elsewhere; false with *err on bad input.
bool StabilityMapFigure(const StabilityMapData& data, Figure2D* out, std::string* err);

/// One phase of a soak: [t0_s, t1_s) of mission time, the value the phase sets (as text,
/// e.g. "0.3"), and whether it passed (failed phases are drawn in red with their reason).
struct SoakPhase {
  double t0_s = 0.0, t1_s = 0.0;
  std::string value;
  bool passed = true;
  std::string why;  ///< the failed criteria (shown in the figure, shortened to fit)
};

/// The soak's time series, sampled by the caller (e.g. once a minute). Each series has its
/// own time vector; an empty series leaves its panel out. Times are mission seconds.
struct SoakFigureData {
  std::string title;     ///< e.g. "soak: channel.delay.base_s, realtime"
  std::string verdict;   ///< e.g. "PASS" or "FAIL: phase 3 memory growth"; may be empty
  std::string phase_key; ///< the key the phases step, for the phase labels' legend
  std::vector<SoakPhase> phases;

  std::vector<double> error_t_s, worst_position_error_m;
  double position_tol_m = -1.0;  ///< drawn if > 0

  std::vector<double> lateness_t_s, lateness_p99_s;
  double lateness_p99_max_s = -1.0;  ///< target, drawn if > 0
  std::vector<double> delay_error_t_s, delay_error_p99_s;
  double delay_error_p99_max_s = -1.0;

  struct Process {
    std::string name;  ///< e.g. "vehicle 1", "channel emulator"
    std::vector<double> t_s, rss_mib;
  };
  std::vector<Process> rss;

  std::vector<double> logged_t_s, logged_per_min, expected_per_min;

  int width_px = 1600, height_px = 1400;
};

/// Stacked panels against mission time (minutes, or hours beyond three hours): worst
/// position error, loop lateness p99 and delay error p99 with their targets, RSS per
/// process, states logged against expected per minute; phases shaded alternately and
/// labelled with their value, failed phases shaded red. False with *err on bad input or
/// when the PNG cannot be drawn or written.
bool RenderSoakFigure(const SoakFigureData& data, const std::string& png_path, std::string* err);

bool SoakFigure(const SoakFigureData& data, Figure2D* out, std::string* err);

}  // namespace shoal::render
