// The scenario: one plain struct per concern, with defaults. Loading and validation of
// the TOML file live in scenario/loader; this header is pure data so that core/
// stays free of I/O. Every key is documented in docs/scenario.md.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/types.h"

namespace shoal {

enum class DelayKind { kNone, kConstant, kSinusoid, kUniform, kAcoustic, kTrace };

/// A measured delay series (from a sea trial or another tool): delay_s[k] applies to a
/// message sent at t_s[k]. t_s strictly increasing, every value finite and >= 0.
struct DelayTrace {
  std::string file;  // as written in the scenario (relative to the scenario file)
  std::vector<double> t_s;
  std::vector<double> delay_s;
  bool hold = false;  // true: zero-order hold; false: linear interpolation
};

/// tau(t) for one directed link.
///   none:      tau = 0
///   constant:  tau = base_s
///   sinusoid:  tau = base_s + amplitude_s * cos(omega_rad_s * t)   (paper Example 2)
///   uniform:   tau = base_s + U(-amplitude_s, amplitude_s), drawn per message (seeded)
///   acoustic:  tau = range / sound_speed_mps + processing_s + U(0, jitter_s) (seeded);
///              range beyond max_range_m: the message is lost; range in
///              (max_range_m / 2, max_range_m]: lost with a probability rising linearly
///              from 0 to loss_at_max_range
///   trace:     tau = the trace at t (held or interpolated; before its first row the
///              first delay, after its last row the last delay)
struct DelayConfig {
  DelayConfig() = default;
  /// The models of the paper (none, constant, sinusoid, uniform).
  DelayConfig(DelayKind k, double base, double amplitude, double omega)
      : kind(k), base_s(base), amplitude_s(amplitude), omega_rad_s(omega) {}

  DelayKind kind = DelayKind::kNone;
  double base_s = 0.0;
  double amplitude_s = 0.0;
  double omega_rad_s = 0.0;
  // acoustic
  double sound_speed_mps = 1500.0;
  double processing_s = 0.0;
  double jitter_s = 0.0;
  double max_range_m = 0.0;
  double loss_at_max_range = 0.0;
  // trace (shared: every link that uses one file holds the same table)
  std::shared_ptr<const DelayTrace> trace;
};

enum class LossKind { kNone, kBernoulli, kGilbertElliott };

/// Message loss for one directed link: none, independent drops with `probability`, or
/// the two-state Gilbert-Elliott chain: before each message the link's state moves
/// good -> bad with p_good_to_bad and bad -> good with p_bad_to_good, then the message is
/// lost with loss_good or loss_bad. Stationary loss rate
/// (p_gb * loss_bad + p_bg * loss_good) / (p_gb + p_bg); a bad burst lasts 1 / p_bg
/// messages on average.
struct LossConfig {
  LossKind kind = LossKind::kNone;
  double probability = 0.0;
  double p_good_to_bad = 0.0;
  double p_bad_to_good = 1.0;
  double loss_good = 0.0;
  double loss_bad = 1.0;
};

/// A sender's acoustic modem: it transmits a state only if at least min_interval_s has
/// passed since its last transmission (0: every state).
struct ModemConfig {
  int id = 0;
  double min_interval_s = 0.0;
};

/// A per-link override of the channel defaults; `from` 0 is the leader.
struct LinkOverride {
  int from = 0;
  int to = 0;
  std::optional<DelayConfig> delay;
  std::optional<LossConfig> loss;
};

enum class DisturbanceKind { kNone, kPaperExample2, kOceanCurrent };

/// Gauss-Markov ocean current (Fossen 2011, sec. 8.3): dV/dt + mu V = w, V clamped to
/// [min_speed_mps, max_speed_mps]; horizontal, from direction `direction_rad` (NED).
struct OceanCurrentConfig {
  double speed_mps = 0.5;        // initial (and mean) speed
  double min_speed_mps = 0.0;
  double max_speed_mps = 1.0;
  double mu_per_s = 0.01;        // Gauss-Markov time constant 1/mu
  double noise_mps = 0.1;        // standard deviation of w (per sqrt(s))
  double direction_rad = 0.5235987755982988;  // beta_c, 30 deg as Fossen's remus100
};

struct DisturbanceConfig {
  DisturbanceKind kind = DisturbanceKind::kNone;
  /// paper_example2 only. true: follower i feels F_i = f(x_i(t-tau), v_i(t-tau)) -
  /// f(x_0(t-tau), v_0(t-tau)), exactly the uncertain term of the paper's error system (13)
  /// (the leader, eq. (4), is subject to the same f and its given path already contains
  /// it). false: the absolute f(x_i(t-tau), v_i(t-tau)), which a PD consensus law without
  /// integral action can only hold to a bias of about H^{-1} f / k1.
  bool relative_to_leader = true;
  OceanCurrentConfig current;
};

enum class PathKind { kPaperHelix, kLine, kWaypoints };

struct LeaderConfig {
  PathKind path = PathKind::kPaperHelix;
  Vec3 start_m = Vec3::Zero();        // line: position at t = 0
  Vec3 velocity_mps = Vec3(1, 0, 0);  // line: constant velocity
  std::vector<Vec3> waypoints_m;      // waypoints: visited in order
  double speed_mps = 1.0;             // waypoints: along-path speed
  bool loop = false;                  // waypoints: return to the first and repeat
};

/// Initial state of one follower.
struct FollowerInit {
  Vec5 eta = Vec5::Zero();  // [x y z theta psi]
  Vec5 nu = Vec5::Zero();   // [u v w q r]
  bool given = false;       // false: starts at the leader's start + offset, at rest
};

/// At most this many RK4 steps per control period (the loader refuses a smaller step):
/// beyond it a tick is seconds of work, and the count must fit the integrator's int.
constexpr int kMaxRk4Substeps = 100000;

struct VehicleConfig {
  /// Per-channel limits of tau = [X Y Z M N] (N, N, N, N m, N m); docs/reference.md.
  Vec5 tau_max = (Vec5() << 100.0, 10.0, 10.0, 6.0, 6.0).finished();
  /// RK4 step inside each control period; the period is split into whole steps no longer
  /// than this (Follower::Rk4Substeps).
  double integrator_step_s = 0.01;
};

/// What an [[event]] of the scenario's timeline changes (docs/scenario.md, "Events").
enum class EventKind {
  kLinkDown,         // the listed links lose every message
  kChannel,          // the listed links take new delay and/or loss models
  kTopology,         // new follower edges and leader links (a switching topology)
  kVehicleSilent,    // the vehicles' modems stop sending
  kVehicleDeaf,      // the vehicles stop receiving
  kLeaderSilent,     // the leader's modem stops sending
  kControllerReset,  // the vehicles' controllers lose their memory, zero force for outage_s
};

/// One change of the timeline. It holds for every message sent (channel changes, silent),
/// every delivery due (deaf) and every tick stepped (topology, reset) at a mission time t
/// with at_s <= t < until_s; until_s = infinity: to the end of the run (a topology: until
/// the next topology event). A controller reset holds for [at_s, at_s + outage_s).
struct ScenarioEvent {
  EventKind kind = EventKind::kLinkDown;
  double at_s = 0.0;
  double until_s = std::numeric_limits<double>::infinity();
  int line = 0;  // line of its [[event]] header in the scenario file (0: built in code)
  // link_down, channel: the links (from, to) it applies to, from 0 = the leader; empty:
  // every link of the topology in force.
  std::vector<std::pair<int, int>> links;
  // channel: the new models (a missing one stays as it was).
  std::optional<DelayConfig> delay;
  std::optional<LossConfig> loss;
  // topology: replaces [swarm] edges and leader_links (same meaning).
  std::vector<std::pair<int, int>> edges;
  std::vector<int> leader_links;
  // vehicle_silent, vehicle_deaf, controller_reset: follower ids 1..n.
  std::vector<int> vehicles;
  // controller_reset: how long the controller commands zero force.
  double outage_s = 0.0;

  /// End of the event's window (until_s, or at_s + outage_s for a controller reset).
  double end_s() const { return kind == EventKind::kControllerReset ? at_s + outage_s : until_s; }
};

/// The TOML name of an event kind ("link_down", ...).
inline const char* EventKindName(EventKind k) {
  switch (k) {
    case EventKind::kLinkDown: return "link_down";
    case EventKind::kChannel: return "channel";
    case EventKind::kTopology: return "topology";
    case EventKind::kVehicleSilent: return "vehicle_silent";
    case EventKind::kVehicleDeaf: return "vehicle_deaf";
    case EventKind::kLeaderSilent: return "leader_silent";
    case EventKind::kControllerReset: return "controller_reset";
  }
  return "?";
}

struct MetricsConfig {
  double position_tol_m = 0.5;
  double velocity_tol_mps = 0.05;
};

struct Scenario {
  // Provenance.
  std::string name;         // [run] name, default: file stem
  std::string source_path;  // file it was loaded from ("" if built in code)
  std::string source_text;  // the file's text, logged so that a log reproduces its run

  // [run]
  double duration_s = 600.0;
  double control_rate_hz = 50.0;
  std::uint64_t seed = 1;

  // [swarm]  followers are 1..n, the leader is 0.
  int followers = 0;
  std::vector<std::pair<int, int>> edges;  // (i, j): follower i receives from follower j
  std::vector<int> leader_links;           // followers that receive the leader
  double neighbour_timeout_s = 1.0;

  // [control]
  double k1 = 0.0;
  double k2 = 0.0;
  std::vector<Vec3> offsets_m;  // d_i, size n (NED, relative to the leader)

  LeaderConfig leader;
  DelayConfig delay;            // [channel.delay], default for every link
  LossConfig loss;              // [channel.loss]
  std::vector<LinkOverride> links;  // [[channel.link]]
  double modem_min_interval_s = 0.0;  // [channel] default of every sender
  std::vector<ModemConfig> modems;    // [[channel.modem]] per-sender overrides
  DisturbanceConfig disturbance;
  VehicleConfig vehicle;
  MetricsConfig metrics;
  std::vector<FollowerInit> initial;  // size n, index i-1 for follower i
  std::vector<ScenarioEvent> events;  // [[event]], in the order of the file (sorted by at_s)

  /// Control period in whole microseconds.
  Micros period_us() const {
    return static_cast<Micros>(1e6 / control_rate_hz + 0.5);
  }

  /// The most ticks a run may have: a state's sequence number, an int32 on the wire,
  /// counts them from 0 (about 497 days at 50 Hz, 25 days at 1000 Hz).
  static constexpr std::int64_t kMaxFinalTick = 2147483646;
  /// "" if a run of `duration` seconds (< 0: the scenario's) fits kMaxFinalTick, else why not.
  std::string TickLimitRefusal(double duration = -1.0) const {
    if (final_tick(duration) <= kMaxFinalTick) return "";
    const double most_s = static_cast<double>(kMaxFinalTick) * static_cast<double>(period_us()) * 1e-6;
    char text[160];
    std::snprintf(text, sizeof text, "at most %.0f s at %g Hz (2^31 - 1 ticks)", std::floor(most_s),
                  control_rate_hz);
    return std::string("a run's ticks are counted by an int32 sequence number on the wire: ") +
           text;
  }

  /// Index of the last control tick of a run of `duration_s` seconds (< 0: duration_s of
  /// the scenario); ticks 0..final_tick(), the last one at or before the duration.
  std::int64_t final_tick(double duration = -1.0) const {
    const double d = duration >= 0 ? duration : duration_s;
    return static_cast<std::int64_t>(
        std::floor(d * 1e6 / static_cast<double>(period_us()) + 1e-9));
  }
};

}  // namespace shoal
