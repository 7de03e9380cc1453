// The standard figures of a Shoal run (`shoal render`), built from plain per-vehicle
// arrays. The caller (render/run_figures.h) reads the log; these functions only arrange
// numbers into Figure2D / Figure3D with one colour per vehicle (VehicleColor), so that
// they can be tested and benchmarked on synthetic data.
#pragma once

#include <array>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "render/figure.h"

namespace shoal::render {

/// One vehicle's states over time (leader: id 0). All arrays have t_s's length.
struct VehicleSeries {
  int id = 0;
  std::vector<double> t_s;
  std::array<std::vector<double>, 5> eta;  // x, y, z [m] (NED), theta, psi [rad]
  std::array<std::vector<double>, 5> nu;   // u, v, w [m/s], q, r [rad/s]
};

/// One follower's tracking errors over time (definitions: docs/sim.md).
struct ErrorSeries {
  int id = 1;
  std::vector<double> t_s;
  std::vector<double> position_m, velocity_mps, attitude_rad;
};

/// One directed link's channel ground truth: delivered messages (send time, realised
/// delay and, if known, the delay the link's model drew for the message) and dropped ones
/// (send time).
struct LinkSeries {
  int from = 0, to = 1;
  std::vector<double> sent_s, delay_s;
  /// Empty, or as long as delay_s: then the delay error is taken against it rather than
  /// against ChannelOptions' tau(t) (right for per-link and random delay models too).
  std::vector<double> model_delay_s;
  std::vector<double> dropped_s;
};

struct TrajectoryOptions {
  std::string scenario;  // in the title
  /// Formation snapshots at these times (the nearest sample of each vehicle); empty: six
  /// evenly spaced from the first to the last sample.
  std::vector<double> snapshot_times_s;
  /// Segments of each snapshot, as pairs of vehicle ids (e.g. the topology's links);
  /// empty: the leader to every follower.
  std::vector<std::pair<int, int>> snapshot_edges;
  int width_px = 1400, height_px = 1000;
};

/// Paper Figs. 12 and 23: 3-D trajectories of all vehicles with formation snapshots, each
/// line's start marked by a ring and its end by a filled square (both in the legend); z
/// down (NED), the sea surface z = 0 drawn when the box reaches it.
Figure3D TrajectoryFigure(const std::vector<VehicleSeries>& vehicles, const TrajectoryOptions& o);

/// Paper Figs. 2-11, 13-22: x, y, z, theta, psi (left column) and u, v, w, q, r (right)
/// against time for all vehicles, one legend for the figure. psi is drawn wrapped to
/// (-pi, pi] with the line broken at each wrap; z grows downwards, as in the 3-D figure.
Figure2D StateFigure(const std::vector<VehicleSeries>& vehicles, const std::string& scenario,
                     int width_px = 1600, int height_px = 1000);

/// A window of the scenario's timeline ([[event]]): shaded from t0_s to t1_s and labelled.
struct EventWindow {
  double t0_s = 0.0, t1_s = 0.0;
  std::string label;  // e.g. the event's kind, "link_down"
};

struct ErrorOptions {
  std::string scenario;
  bool log_y = true;
  double position_tol_m = -1.0;    // drawn as a dashed line if > 0
  double velocity_tol_mps = -1.0;  // ditto
  double converged_s = -1.0;       // a vertical line if >= 0
  /// Each drawn as a translucent band in every panel, labelled in the top panel.
  std::vector<EventWindow> events;
  int width_px = 1600, height_px = 1000;
};

/// Paper Figs. 24-27: position, velocity and attitude tracking errors of every follower.
Figure2D ErrorFigure(const std::vector<ErrorSeries>& followers, const ErrorOptions& o);

/// A time during which a link loses or never sends its messages (a link_down window, a
/// silent sender, a deaf receiver).
struct LinkOutage {
  int from = 0, to = 1;
  double t0_s = 0.0, t1_s = 0.0;
  std::string label;  // "link down", "silent", "deaf"
};

struct ChannelOptions {
  std::string scenario;
  /// The configured delay tau(t), sampled by the caller (e.g. every 10 ms).
  std::vector<double> tau_t_s, tau_s;
  double zoom_s = 20.0;  // the first panel shows the first zoom_s seconds
  /// "sim", "lockstep", "realtime" (analysis' RunAnalysis::mode) or "" (unknown), and the
  /// control period (0: unknown): they say in the figure what the delay error means.
  std::string mode;
  double control_period_s = 0.0;
  /// Real time: the emulator's release error p99 (how late it really released, from its
  /// health); NaN: unknown. The log stamps a delivery with its scheduled release, so the
  /// figure's delay minus tau cannot show it: the note gives it instead.
  double release_error_p99_s = std::numeric_limits<double>::quiet_NaN();
  /// Marked in the drops panel as a band on the link's row (on the receiver's row when
  /// the links are grouped by receiver; on the single row when they are all in one).
  std::vector<LinkOutage> outages;
  /// height_px 0: 1000 px, taller when there are so many links that their rows would
  /// crowd (text then kept at the scale of a 1000 px high figure).
  int width_px = 1600, height_px = 0;
};

/// The channel: realised delay of every link against tau(t) over the first zoom_s seconds
/// (drops marked); per link (one row each), the spread of realised minus configured delay
/// over the whole run (min-max, 5-95 %, median) with a note on what it means in the run's
/// mode; and drops over time per link. Row colours: the receiving vehicle's.
Figure2D ChannelFigure(const std::vector<LinkSeries>& links, const ChannelOptions& o);

/// One acoustic model's line in the delay-against-range figure.
struct AcousticModelLine {
  std::string label;         // e.g. "[channel.delay]" or "event 2 (channel)"
  double sound_speed_mps = 1500.0, processing_s = 0.0, jitter_s = 0.0;
  double max_range_m = 0.0;  // the line is drawn from 0 to here (0: to the largest range)
};

/// Delivered messages of acoustic links: range between sender and receiver at the send
/// time (from the logged states) and delay.
struct AcousticPoints {
  std::vector<double> send_s;
  std::vector<double> range_m;
  std::vector<double> drawn_delay_s;     // the model's draw
  std::vector<double> realised_delay_s;  // deliver - send
};

struct AcousticOptions {
  std::string scenario;
  int width_px = 1600, height_px = 1000;
};

/// Acoustic links: each delivered message's drawn and realised delay against the
/// sender-receiver range at its send time, with each model's line range / sound_speed +
/// processing and its jitter band (up to + jitter_s).
Figure2D AcousticDelayFigure(const AcousticPoints& points, const std::vector<AcousticModelLine>& models,
                             const AcousticOptions& o);

}  // namespace shoal::render
