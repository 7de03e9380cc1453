// Scenario TOML loading and validation. Every key is documented in docs/scenario.md.
//
// The whole file is validated before anything runs; the first problem found is thrown as
// a ScenarioError that names the file, the line, the dotted key, what is wrong, the value
// that was given and how to fix it. Unknown keys are errors at every level.
#include "scenario/loader.h"

#include <iostream>

#include <toml++/toml.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include "core/timeline.h"
#include "core/topology.h"
#include "scenario/override_tree.h"
#include "scenario/regular_file.h"
#include "scenario/toml_depth.h"

namespace shoal {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// A dense n x n topology is built for validation; 1000 followers is far beyond any
// practical swarm and keeps a typo (followers = 1000000) from exhausting memory.
constexpr std::int64_t kMaxFollowers = 1000;
// Times are converted to int64 microseconds by the core; 1e9 s (~32 years) keeps every
// conversion far from overflow.
constexpr double kMaxSeconds = 1e9;
// A scenario is a few kilobytes; the limit keeps a wrong path (a disk image, a log) from
// being read whole.
constexpr std::size_t kMaxScenarioBytes = 16u << 20;
constexpr double kMaxControlRateHz = 10000.0;
constexpr double kMaxPitchRad = 0.5235987755982988;  // 30 deg, REMUS 100 limit
constexpr std::size_t kMaxShownChars = 80;           // of a value quoted in a message
constexpr int kMaxSuggestionDistance = 2;

constexpr std::size_t kMaxNameChars = 100;

/// A name that is safe as a file name in the working directory, on every file system.
bool IsPlainName(std::string_view name) {
  // Not '.' first (hidden, "..") nor '-' first (read as an option by the tools given it).
  if (name.empty() || name.size() > kMaxNameChars || name.front() == '.' || name.front() == '-') {
    return false;
  }
  return std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
           c == '_' || c == '-' || c == '.';
  });
}

// ---------------------------------------------------------------------------------------
// Schema: the keys each table accepts.

/// A non-owning view of a constexpr array of key names.
class KeySet {
 public:
  constexpr KeySet() = default;
  template <std::size_t N>
  constexpr KeySet(const std::array<std::string_view, N>& keys)  // NOLINT: implicit on purpose
      : data_(keys.data()), size_(N) {}

  const std::string_view* begin() const { return data_; }
  const std::string_view* end() const { return data_ + size_; }
  bool Contains(std::string_view key) const { return std::find(begin(), end(), key) != end(); }

 private:
  const std::string_view* data_ = nullptr;
  std::size_t size_ = 0;
};

constexpr std::array<std::string_view, 10> kTopKeys = {
    "run", "swarm", "control", "leader", "channel", "disturbance", "vehicle", "metrics",
    "follower", "event"};
constexpr std::array<std::string_view, 4> kRunKeys = {"name", "duration_s", "control_rate_hz",
                                                      "seed"};
constexpr std::array<std::string_view, 4> kSwarmKeys = {"followers", "edges", "leader_links",
                                                        "neighbour_timeout_s"};
constexpr std::array<std::string_view, 3> kControlKeys = {"k1", "k2", "offsets_m"};
constexpr std::array<std::string_view, 6> kLeaderKeys = {"path",        "start_m",   "velocity_mps",
                                                         "waypoints_m", "speed_mps", "loop"};
constexpr std::array<std::string_view, 5> kChannelKeys = {"delay", "loss", "link",
                                                          "modem_min_interval_s", "modem"};
constexpr std::array<std::string_view, 11> kDelayKeys = {
    "model",        "base_s",   "amplitude_s", "omega_rad_s",       "sound_speed_mps",
    "processing_s", "jitter_s", "max_range_m", "loss_at_max_range", "file",
    "interpolation"};
constexpr std::array<std::string_view, 6> kLossKeys = {
    "model", "probability", "p_good_to_bad", "p_bad_to_good", "loss_good", "loss_bad"};
constexpr std::array<std::string_view, 2> kModemKeys = {"id", "min_interval_s"};
constexpr std::array<std::string_view, 4> kLinkKeys = {"from", "to", "delay", "loss"};
constexpr std::array<std::string_view, 8> kDisturbanceKeys = {
    "model",    "speed_mps", "min_speed_mps", "max_speed_mps",
    "mu_per_s", "noise_mps", "direction_rad", "relative_to_leader"};
constexpr std::array<std::string_view, 2> kVehicleKeys = {"tau_max", "integrator_step_s"};
constexpr std::array<std::string_view, 2> kMetricsKeys = {"position_tol_m", "velocity_tol_mps"};
constexpr std::array<std::string_view, 5> kFollowerKeys = {"id", "position_m", "pitch_rad",
                                                           "heading_rad", "nu"};

/// Where each key lives, to point a key written in the wrong table to the right one.
struct TableSchema {
  std::string_view label;
  KeySet keys;
};
constexpr std::array<TableSchema, 12> kTables = {{
    {"[run]", kRunKeys},
    {"[swarm]", kSwarmKeys},
    {"[control]", kControlKeys},
    {"[leader]", kLeaderKeys},
    {"[channel.delay]", kDelayKeys},
    {"[channel.loss]", kLossKeys},
    {"[[channel.link]]", kLinkKeys},
    {"[[channel.modem]]", kModemKeys},
    {"[disturbance]", kDisturbanceKeys},
    {"[vehicle]", kVehicleKeys},
    {"[metrics]", kMetricsKeys},
    {"[[follower]]", kFollowerKeys},
}};

/// One choice of a selector key (path = "...", model = "..."): its name, its value and
/// the other keys of the table it uses. The first variant of a list is the default.
template <typename Kind>
struct Variant {
  std::string_view name;
  Kind kind;
  KeySet keys;
};

constexpr std::array<std::string_view, 2> kLinePathKeys = {"start_m", "velocity_mps"};
constexpr std::array<std::string_view, 3> kWaypointPathKeys = {"waypoints_m", "speed_mps", "loop"};
constexpr std::array<Variant<PathKind>, 3> kLeaderPaths = {{
    {"paper_helix", PathKind::kPaperHelix, {}},
    {"line", PathKind::kLine, kLinePathKeys},
    {"waypoints", PathKind::kWaypoints, kWaypointPathKeys},
}};

constexpr std::array<std::string_view, 1> kConstantDelayKeys = {"base_s"};
constexpr std::array<std::string_view, 3> kSinusoidDelayKeys = {"base_s", "amplitude_s",
                                                                "omega_rad_s"};
constexpr std::array<std::string_view, 2> kUniformDelayKeys = {"base_s", "amplitude_s"};
constexpr std::array<std::string_view, 5> kAcousticDelayKeys = {
    "sound_speed_mps", "processing_s", "jitter_s", "max_range_m", "loss_at_max_range"};
constexpr std::array<std::string_view, 2> kTraceDelayKeys = {"file", "interpolation"};
constexpr std::array<Variant<DelayKind>, 6> kDelayModels = {{
    {"none", DelayKind::kNone, {}},
    {"constant", DelayKind::kConstant, kConstantDelayKeys},
    {"sinusoid", DelayKind::kSinusoid, kSinusoidDelayKeys},
    {"uniform", DelayKind::kUniform, kUniformDelayKeys},
    {"acoustic", DelayKind::kAcoustic, kAcousticDelayKeys},
    {"trace", DelayKind::kTrace, kTraceDelayKeys},
}};

constexpr std::array<std::string_view, 1> kBernoulliLossKeys = {"probability"};
constexpr std::array<std::string_view, 4> kGilbertElliottLossKeys = {
    "p_good_to_bad", "p_bad_to_good", "loss_good", "loss_bad"};
constexpr std::array<Variant<LossKind>, 3> kLossModels = {{
    {"none", LossKind::kNone, {}},
    {"bernoulli", LossKind::kBernoulli, kBernoulliLossKeys},
    {"gilbert_elliott", LossKind::kGilbertElliott, kGilbertElliottLossKeys},
}};

constexpr std::array<std::string_view, 6> kOceanCurrentKeys = {
    "speed_mps", "min_speed_mps", "max_speed_mps", "mu_per_s", "noise_mps", "direction_rad"};
constexpr std::array<std::string_view, 1> kPaperDisturbanceKeys = {"relative_to_leader"};
constexpr std::array<Variant<DisturbanceKind>, 3> kDisturbanceModels = {{
    {"none", DisturbanceKind::kNone, {}},
    {"paper_example2", DisturbanceKind::kPaperExample2, kPaperDisturbanceKeys},
    {"ocean_current", DisturbanceKind::kOceanCurrent, kOceanCurrentKeys},
}};

// [[event]]: the keys every event takes, and those of each kind (docs/scenario.md,
// "Events"). A controller reset has no until_s: its window is [at_s, at_s + outage_s).
constexpr std::array<std::string_view, 10> kEventKeys = {
    "kind", "at_s",  "until_s",      "links",    "delay",
    "loss", "edges", "leader_links", "vehicles", "outage_s"};
constexpr std::array<std::string_view, 2> kLinkDownEventKeys = {"until_s", "links"};
constexpr std::array<std::string_view, 4> kChannelEventKeys = {"until_s", "links", "delay", "loss"};
constexpr std::array<std::string_view, 3> kTopologyEventKeys = {"until_s", "edges", "leader_links"};
constexpr std::array<std::string_view, 2> kVehicleEventKeys = {"until_s", "vehicles"};
constexpr std::array<std::string_view, 1> kLeaderEventKeys = {"until_s"};
constexpr std::array<std::string_view, 2> kResetEventKeys = {"vehicles", "outage_s"};
constexpr std::array<Variant<EventKind>, 7> kEventKinds = {{
    {"link_down", EventKind::kLinkDown, kLinkDownEventKeys},
    {"channel", EventKind::kChannel, kChannelEventKeys},
    {"topology", EventKind::kTopology, kTopologyEventKeys},
    {"vehicle_silent", EventKind::kVehicleSilent, kVehicleEventKeys},
    {"vehicle_deaf", EventKind::kVehicleDeaf, kVehicleEventKeys},
    {"leader_silent", EventKind::kLeaderSilent, kLeaderEventKeys},
    {"controller_reset", EventKind::kControllerReset, kResetEventKeys},
}};
// Hostile timelines: the core tabulates the state of every link in every segment between
// change times (cells), and building a segment costs checks of the events in force
// against the links (CheckTimelineSize). 1e9 checks take about half a second.
constexpr std::size_t kMaxEvents = 10000;
constexpr double kMaxTimelineCells = 5e7;
constexpr double kMaxTimelineChecks = 1e9;

// ---------------------------------------------------------------------------------------
// Number ranges.

/// An interval a number must lie in, and the rule in words for the message.
struct Bound {
  double lo;
  bool lo_open;
  double hi;
  bool hi_open;
  std::string_view what;
  // A magnitude beyond which a value is physically absurd, and the rule in words.
  double max_abs = kInf;
  std::string_view too_large = "";

  bool Contains(double v) const {
    return (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi);
  }
};

constexpr Bound kFinite{-kInf, true, kInf, true, "must be a finite number"};
constexpr Bound kPositive{0.0, true, kInf, true, "must be a positive number"};
constexpr Bound kNonNegative{0.0, false, kInf, true, "must be a number >= 0"};
constexpr Bound kPositiveSeconds{0.0, true, kMaxSeconds, false,
                                 "must be a positive number of seconds, at most 1e9"};
constexpr Bound kSeconds{0.0, false, kMaxSeconds, false, "must be a number of seconds in [0, 1e9]"};
constexpr Bound kProbability{0.0, false, 1.0, true, "must be in [0, 1)"};
constexpr Bound kClosedProbability{0.0, false, 1.0, false, "must be in [0, 1]"};
constexpr Bound kTransitionProbability{0.0, true, 1.0, false, "must be in (0, 1]"};
constexpr Bound kControlRate{0.0, true, kMaxControlRateHz, false,
                             "must be a positive number <= 10000"};
// Physical magnitudes. A finite but absurd value (a position of 1e308 m, a gain of 1e300)
// once ran and overflowed to NaN or inf; these bounds are far beyond any REMUS 100 run
// (top speed about 2.5 m/s, range about 100 km) and far below any overflow.
constexpr double kMaxMetres = 1e6;
constexpr double kMaxSpeed = 100.0;  // m/s, and rad/s for body rates
constexpr double kMaxGain = 1e6;
constexpr double kMaxRatePerSecond = 1e6;
constexpr Bound kCoordinate{-kInf, true, kInf, true, "must be a finite number", kMaxMetres,
                            "must be a number of metres in [-1e6, 1e6]"};
constexpr Bound kVelocity{-kInf, true, kInf, true, "must be a finite number", kMaxSpeed,
                          "must be in [-100, 100]"};
constexpr Bound kPositiveSpeed{0.0, true, kInf, true, "must be a positive number", kMaxSpeed,
                               "must be at most 100"};
constexpr Bound kSpeed{0.0, false, kInf, true, "must be a number >= 0", kMaxSpeed,
                       "must be at most 100"};
constexpr Bound kGain{0.0, true, kInf, true, "must be a positive number", kMaxGain,
                      "must be at most 1e6"};
constexpr Bound kRatePerSecond{0.0, true, kInf, true, "must be a positive number",
                               kMaxRatePerSecond, "must be at most 1e6"};
constexpr Bound kPitch{-kMaxPitchRad, true, kMaxPitchRad, true,
                       "must satisfy |pitch_rad| < 0.5236 (30 deg)"};

/// An interval an integer must lie in, and the rule in words.
struct IntBound {
  std::int64_t lo;
  std::int64_t hi;
  std::string what;
};

// ---------------------------------------------------------------------------------------
// Text helpers.

/// Shortest decimal text that reads back as exactly `v`.
std::string FormatNumber(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  // Start with enough digits for the integer part, so that %g never switches to an
  // exponent for ordinary numbers (1000, not 1e+03).
  int first = 1;
  if (std::abs(v) >= 1.0 && std::abs(v) < 1e17) {
    first = static_cast<int>(std::floor(std::log10(std::abs(v)))) + 1;
  }
  char buffer[32];
  for (int precision = first; precision <= 17; ++precision) {
    std::snprintf(buffer, sizeof(buffer), "%.*g", precision, v);
    if (std::strtod(buffer, nullptr) == v) break;
  }
  return buffer;
}

std::string FixedPoint(double v, int decimals) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.*f", decimals, v);
  return buffer;
}

void AppendQuoted(std::string_view s, std::string* out) {
  *out += '"';
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      *out += '\\';
      *out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char escaped[8];
      std::snprintf(escaped, sizeof(escaped), "\\u%04x", static_cast<unsigned>(c));
      *out += escaped;
    } else {
      *out += c;
    }
  }
  *out += '"';
}

/// Appends `node` as TOML-like text; stops early once the text is too long to show.
void AppendValue(const toml::node& node, std::string* out) {
  if (out->size() > kMaxShownChars) return;
  if (const auto* v = node.as_string()) {
    AppendQuoted(v->get(), out);
  } else if (const auto* v = node.as_integer()) {
    *out += std::to_string(v->get());
  } else if (const auto* v = node.as_floating_point()) {
    std::string text = FormatNumber(v->get());
    // A TOML float stays visibly a float: "got 2.0", not "got 2".
    if (text.find_first_of(".eEni") == std::string::npos) text += ".0";
    *out += text;
  } else if (const auto* v = node.as_boolean()) {
    *out += v->get() ? "true" : "false";
  } else if (const auto* array = node.as_array()) {
    *out += '[';
    for (std::size_t i = 0; i < array->size() && out->size() <= kMaxShownChars; ++i) {
      if (i > 0) *out += ", ";
      AppendValue(*array->get(i), out);
    }
    *out += ']';
  } else if (const auto* table = node.as_table()) {
    *out += '{';
    bool first = true;
    for (auto&& [key, value] : *table) {
      *out += first ? " " : ", ";
      first = false;
      *out += key.str();
      *out += " = ";
      AppendValue(value, out);
    }
    *out += " }";
  } else {
    std::ostringstream text;
    if (const auto* v = node.as_date()) text << v->get();
    if (const auto* v = node.as_time()) text << v->get();
    if (const auto* v = node.as_date_time()) text << v->get();
    *out += text.str();
  }
}

/// The value as shown after "got" in a message.
std::string Show(const toml::node& node) {
  std::string out;
  AppendValue(node, &out);
  if (out.size() > kMaxShownChars) out = out.substr(0, kMaxShownChars - 3) + "...";
  return out;
}

std::string Quoted(std::string_view s) {
  std::string out;
  AppendQuoted(s, &out);
  return out;
}

/// A key name as a message shows it: bytes outside printable ASCII as \xNN (no valid key
/// has any, and a newline or an invisible character in a key must be seen), cut at
/// kMaxShownChars so that a key of megabytes does not flood the terminal.
std::string ShownKey(std::string_view name) {
  std::string out;
  for (const char c : name) {
    if (out.size() >= kMaxShownChars) return out + "...";
    const auto byte = static_cast<unsigned char>(c);
    if (byte >= 0x20 && byte < 0x7f) {
      out += c;
    } else {
      char escaped[8];
      std::snprintf(escaped, sizeof(escaped), "\\x%02x", static_cast<unsigned>(byte));
      out += escaped;
    }
  }
  return out;
}

std::string Index(const std::string& key, std::size_t i) {
  return key + "[" + std::to_string(i) + "]";
}

std::string JoinInts(const std::vector<int>& values) {
  std::string out;
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (i > 0) out += ", ";
    out += std::to_string(values[i]);
  }
  return out;
}

/// Optimal string alignment distance (Levenshtein plus adjacent transpositions).
int EditDistance(std::string_view a, std::string_view b) {
  const std::size_t n = a.size();
  const std::size_t m = b.size();
  std::vector<std::vector<int>> d(n + 1, std::vector<int>(m + 1, 0));
  for (std::size_t i = 0; i <= n; ++i) d[i][0] = static_cast<int>(i);
  for (std::size_t j = 0; j <= m; ++j) d[0][j] = static_cast<int>(j);
  for (std::size_t i = 1; i <= n; ++i) {
    for (std::size_t j = 1; j <= m; ++j) {
      const int cost = a[i - 1] == b[j - 1] ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) {
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
      }
    }
  }
  return d[n][m];
}

/// The candidate closest to `word` within kMaxSuggestionDistance, if any.
template <typename Names>
std::optional<std::string_view> Closest(std::string_view word, const Names& candidates) {
  std::optional<std::string_view> best;
  int best_distance = kMaxSuggestionDistance + 1;
  for (const std::string_view candidate : candidates) {
    // The distance is at least the difference in length: a long word (a key of megabytes)
    // is never compared character by character.
    const std::size_t longer = std::max(word.size(), candidate.size());
    if (longer - std::min(word.size(), candidate.size()) > kMaxSuggestionDistance) continue;
    const int distance = EditDistance(word, candidate);
    if (distance < best_distance) {
      best = candidate;
      best_distance = distance;
    }
  }
  return best;
}

int LineOf(const toml::source_region& source) {
  return std::max(1, static_cast<int>(source.begin.line));
}
int LineOf(const toml::node& node) { return LineOf(node.source()); }

/// Where a node is for a message: its source region (a --set value's names that --set), or
/// line `line` of the file for what has no node.
toml::source_region RegionAt(const toml::node* node, int line) {
  if (node != nullptr) return node->source();
  toml::source_region where;
  where.begin.line = static_cast<toml::source_index>(std::max(1, line));
  return where;
}

/// The entries of a table in the order they were written.
std::vector<std::pair<const toml::key*, const toml::node*>> InFileOrder(const toml::table& t) {
  std::vector<std::pair<const toml::key*, const toml::node*>> entries;
  for (auto&& [key, value] : t) entries.emplace_back(&key, &value);
  std::stable_sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) {
    const auto& sa = a.first->source().begin;
    const auto& sb = b.first->source().begin;
    return sa.line != sb.line ? sa.line < sb.line : sa.column < sb.column;
  });
  return entries;
}

// ---------------------------------------------------------------------------------------
// Reading typed values with located messages.

/// A table being read and what messages need to name it.
struct Table {
  const toml::table* node = nullptr;  // nullptr: the table is absent from the file
  std::string key;                    // dotted key, "" for the root
  std::string label;                  // "[run]", "[[follower]]", "channel.link[0].delay"
  int line = 1;                       // its header; 1 when absent

  const toml::node* Get(std::string_view k) const { return node ? node->get(k) : nullptr; }
  std::string KeyOf(std::string_view k) const {
    return key.empty() ? std::string(k) : key + "." + std::string(k);
  }
};

/// Converts TOML nodes to checked values; every failure throws a located ScenarioError.
class Reader {
 public:
  /// `base_dir`: where relative paths in the scenario (trace files) start.
  Reader(std::string file, std::string base_dir)
      : file_(std::move(file)), base_dir_(std::move(base_dir)) {}

  const std::string& file() const { return file_; }
  /// A path written in the scenario, as the process opens it.
  std::string Resolve(const std::string& path) const {
    const std::filesystem::path p(path);
    return p.is_absolute() || base_dir_.empty() ? path : (std::filesystem::path(base_dir_) / p).string();
  }

  /// "<file>:<line>: <key>: <what> (got <got>); <fix>"
  [[noreturn]] void Fail(int line, const std::string& key, std::string_view what,
                         const std::optional<std::string>& got, std::string_view fix) const {
    FailIn(file_ + ":" + std::to_string(line), key, what, got, fix);
  }

  /// Fail at `where`: "<file>:<line>", or the origin of an override (--set) when the node
  /// came from one (its source path is then the origin, not the file).
  [[noreturn]] void Fail(const toml::source_region& where, const std::string& key,
                         std::string_view what, const std::optional<std::string>& got,
                         std::string_view fix) const {
    if (where.path && !where.path->empty() && *where.path != file_) {
      FailIn(*where.path, key, what, got, fix);
    }
    Fail(LineOf(where), key, what, got, fix);
  }

  [[noreturn]] void FailIn(const std::string& location, const std::string& key,
                           std::string_view what, const std::optional<std::string>& got,
                           std::string_view fix) const {
    std::string message = location + ": ";
    if (!key.empty()) message += key + ": ";
    message += what;
    if (got) message += " (got " + *got + ")";
    if (!fix.empty()) message += "; " + std::string(fix);
    throw ScenarioError(message);
  }

  /// Fails on the line of `node`, quoting its value.
  [[noreturn]] void FailAt(const toml::node& node, const std::string& key, std::string_view what,
                           std::string_view fix) const {
    Fail(node.source(), key, what, Show(node), fix);
  }

  const toml::node& Require(const Table& t, std::string_view key, std::string_view hint) const {
    if (const toml::node* node = t.Get(key)) return *node;
    Fail(t.line, t.KeyOf(key), "missing required key", std::nullopt,
         "add " + std::string(key) + " to " + t.label + " (" + std::string(hint) + ")");
  }

  /// The sub-table `key` of `parent`; an absent table reads as empty.
  Table Child(const Table& parent, std::string_view key, std::string_view hint) const {
    Table child;
    child.key = parent.KeyOf(key);
    // Tables below an array element are named by their path ("channel.link[0].delay").
    child.label = child.key.find('[') == std::string::npos ? "[" + child.key + "]" : child.key;
    if (const toml::node* node = parent.Get(key)) {
      child.node = node->as_table();
      if (child.node == nullptr) FailAt(*node, child.key, "must be a table", hint);
      child.line = LineOf(*node);
    }
    return child;
  }

  /// The entries of the array of tables `key` of `parent` ([[key]] in the file).
  std::vector<Table> ArrayOfTables(const Table& parent, std::string_view key) const {
    std::vector<Table> tables;
    const toml::node* node = parent.Get(key);
    if (node == nullptr) return tables;
    const std::string dotted = parent.KeyOf(key);
    const toml::array* array = node->as_array();
    if (array == nullptr || (!array->empty() && !array->is_array_of_tables())) {
      FailAt(*node, dotted, "must be an array of tables",
             "write each entry as its own [[" + dotted + "]] table");
    }
    for (std::size_t i = 0; i < array->size(); ++i) {
      const toml::node& element = *array->get(i);
      tables.push_back(
          {element.as_table(), Index(dotted, i), "[[" + dotted + "]]", LineOf(element)});
    }
    return tables;
  }

  /// Rejects keys of `t` outside `allowed`, suggesting the closest valid key.
  void CheckKeys(const Table& t, KeySet allowed) const {
    if (t.node == nullptr) return;
    for (const auto& [key, value] : InFileOrder(*t.node)) {
      const std::string_view name = key->str();
      if (allowed.Contains(name)) continue;
      const bool is_table = value->is_table() && !value->as_table()->is_inline();
      const std::string dotted = t.KeyOf(ShownKey(name));
      const std::string where = t.key.empty() ? "at the top level" : "in " + t.label;
      const std::string what = is_table ? "unknown table [" + dotted + "]"
                                        : "unknown key '" + ShownKey(name) + "' " + where;
      Fail(key->source(), dotted, what, std::nullopt,
           UnknownKeyFix(t, name, is_table, allowed));
    }
  }

  /// Reads the selector `selector` (e.g. model = "sinusoid") and rejects keys of `t` that
  /// belong to another variant. `what` names the selector in messages ("delay model").
  template <typename Kind, std::size_t N>
  Kind ReadVariant(const Table& t, std::string_view selector,
                   const std::array<Variant<Kind>, N>& variants, std::string_view what) const {
    std::vector<std::string_view> names;
    std::string choices = "use one of";
    for (const auto& variant : variants) {
      names.push_back(variant.name);
      choices += (names.size() > 1 ? ", " : " ") + Quoted(variant.name);
    }
    const Variant<Kind>* chosen = &variants[0];
    if (const toml::node* node = t.Get(selector)) {
      const std::string key = t.KeyOf(selector);
      const std::string name = ToString(*node, key, choices);
      const auto it = std::find_if(variants.begin(), variants.end(),
                                   [&](const auto& variant) { return variant.name == name; });
      if (it == variants.end()) {
        std::string fix = choices;
        if (const auto close = Closest(name, names)) {
          fix += "; did you mean " + Quoted(*close) + "?";
        }
        FailAt(*node, key, "unknown " + std::string(what), fix);
      }
      chosen = &*it;
    }
    if (t.node == nullptr) return chosen->kind;
    for (const auto& [key, value] : InFileOrder(*t.node)) {
      const std::string_view name = key->str();
      if (name == selector || chosen->keys.Contains(name)) continue;
      const auto user = std::find_if(variants.begin(), variants.end(), [&](const auto& variant) {
        return variant.keys.Contains(name);
      });
      if (user == variants.end()) continue;  // not a variant key: CheckKeys' business
      FailAt(*value, t.KeyOf(name), "not used by " + std::string(what) + " " + Quoted(chosen->name),
             "remove it, or set " + std::string(selector) + " = " + Quoted(user->name));
    }
    return chosen->kind;
  }

  double ToNumber(const toml::node& node, const std::string& key, const Bound& bound,
                  std::string_view hint) const {
    double value = 0.0;
    if (const auto* integer = node.as_integer()) {
      value = static_cast<double>(integer->get());
    } else if (const auto* floating = node.as_floating_point()) {
      value = floating->get();
    } else {
      FailAt(node, key, "must be a number", hint);
    }
    if (!std::isfinite(value)) FailAt(node, key, "must be a finite number", hint);
    if (!bound.Contains(value)) FailAt(node, key, bound.what, hint);
    if (std::abs(value) > bound.max_abs) FailAt(node, key, bound.too_large, hint);
    return value;
  }

  std::int64_t ToInteger(const toml::node& node, const std::string& key, const IntBound& bound,
                         std::string_view hint) const {
    const auto* integer = node.as_integer();
    if (integer == nullptr) FailAt(node, key, "must be an integer", hint);
    const std::int64_t value = integer->get();
    if (value < bound.lo || value > bound.hi) FailAt(node, key, bound.what, hint);
    return value;
  }

  std::string ToString(const toml::node& node, const std::string& key,
                       std::string_view hint) const {
    const auto* string = node.as_string();
    if (string == nullptr) FailAt(node, key, "must be a string", hint);
    return string->get();
  }

  bool ToBool(const toml::node& node, const std::string& key, std::string_view hint) const {
    const auto* boolean = node.as_boolean();
    if (boolean == nullptr) FailAt(node, key, "must be true or false", hint);
    return boolean->get();
  }

  const toml::array& ToArray(const toml::node& node, const std::string& key, std::string_view what,
                             std::string_view hint) const {
    const toml::array* array = node.as_array();
    if (array == nullptr) FailAt(node, key, what, hint);
    return *array;
  }

  /// An array of exactly N numbers, each within `bound`.
  template <int N>
  Eigen::Matrix<double, N, 1> ToVector(const toml::node& node, const std::string& key,
                                       const Bound& bound, std::string_view hint) const {
    const toml::array* array = node.as_array();
    if (array == nullptr || array->size() != static_cast<std::size_t>(N)) {
      FailAt(node, key, "must be an array of " + std::to_string(N) + " numbers", hint);
    }
    Eigen::Matrix<double, N, 1> v;
    for (int k = 0; k < N; ++k) v(k) = ToNumber(*array->get(k), Index(key, k), bound, hint);
    return v;
  }

  // Optional keys: leave *out untouched when absent; return whether the key was given.
  bool ReadNumber(const Table& t, std::string_view key, const Bound& bound, std::string_view hint,
                  double* out) const {
    const toml::node* node = t.Get(key);
    if (node != nullptr) *out = ToNumber(*node, t.KeyOf(key), bound, hint);
    return node != nullptr;
  }

  template <int N>
  bool ReadVector(const Table& t, std::string_view key, const Bound& bound, std::string_view hint,
                  Eigen::Matrix<double, N, 1>* out) const {
    const toml::node* node = t.Get(key);
    if (node != nullptr) *out = ToVector<N>(*node, t.KeyOf(key), bound, hint);
    return node != nullptr;
  }

  bool ReadBool(const Table& t, std::string_view key, std::string_view hint, bool* out) const {
    const toml::node* node = t.Get(key);
    if (node != nullptr) *out = ToBool(*node, t.KeyOf(key), hint);
    return node != nullptr;
  }

  // Required keys.
  double RequireNumber(const Table& t, std::string_view key, const Bound& bound,
                       std::string_view hint) const {
    return ToNumber(Require(t, key, hint), t.KeyOf(key), bound, hint);
  }

  std::int64_t RequireInteger(const Table& t, std::string_view key, const IntBound& bound,
                              std::string_view hint) const {
    return ToInteger(Require(t, key, hint), t.KeyOf(key), bound, hint);
  }

 private:
  std::string UnknownKeyFix(const Table& t, std::string_view name, bool is_table,
                            KeySet allowed) const {
    // A valid key written in the wrong table: say where it belongs.
    std::string homes;
    for (const TableSchema& schema : kTables) {
      if (!is_table && schema.label != t.label && schema.keys.Contains(name)) {
        homes += (homes.empty() ? "" : ", ") + std::string(schema.label);
      }
    }
    if (!homes.empty()) return "'" + std::string(name) + "' belongs in " + homes;
    if (const auto close = Closest(name, allowed)) {
      return is_table ? "did you mean [" + t.KeyOf(*close) + "]?"
                      : "did you mean '" + std::string(*close) + "'?";
    }
    std::string valid;
    for (const std::string_view key : allowed) {
      valid += (valid.empty() ? "" : ", ") + std::string(key);
    }
    return t.key.empty() ? "valid tables: " + valid : "valid keys in " + t.label + ": " + valid;
  }

  std::string file_;
  std::string base_dir_;
};

// ---------------------------------------------------------------------------------------
// Sections.

void ReadRun(const Reader& r, const Table& t, Scenario* s) {
  r.CheckKeys(t, kRunKeys);
  if (const toml::node* node = t.Get("name")) {
    const std::string hint = "name is a label for logs and reports, e.g. name = \"helix_4\"";
    s->name = r.ToString(*node, t.KeyOf("name"), hint);
    if (s->name.empty()) r.FailAt(*node, t.KeyOf("name"), "must not be empty", hint);
    if (!IsPlainName(s->name)) {
      // shoal run names its log and its process output after it: never a path.
      r.FailAt(*node, t.KeyOf("name"),
               "must be a plain file name: letters, digits, '_', '-' and '.', not starting "
               "with '.' or '-', at most " + std::to_string(kMaxNameChars) + " characters",
               hint);
    }
  }
  r.ReadNumber(t, "duration_s", kPositiveSeconds,
               "the run lasts duration_s seconds, e.g. duration_s = 600", &s->duration_s);
  if (const toml::node* node = t.Get("control_rate_hz")) {
    const std::string key = t.KeyOf("control_rate_hz");
    const std::string_view hint = "the control loop runs at control_rate_hz, e.g. 50";
    s->control_rate_hz = r.ToNumber(*node, key, kControlRate, hint);
    // Time in the core counts whole microseconds, so the period must round to a whole
    // number of them within 1e-6 relative. The bound is inclusive, with a little slack so
    // that rates right on it (3 Hz -> 333333 us, 1e6 mod 3 = 1) do not depend on rounding.
    const double period_us = 1e6 / s->control_rate_hz;
    if (std::abs(period_us - std::round(period_us)) > 1e-6 * period_us * (1.0 + 1e-9)) {
      r.Fail(node->source(), key,
             "the control period 1e6/rate must be a whole number of microseconds",
             Show(*node) + ", a period of " + FixedPoint(period_us, 3) + " us",
             "choose a rate such as 10, 20, 25, 50, 64, 100, 125, 200 or 1000");
    }
  }
  if (!(s->duration_s * s->control_rate_hz >= 1.0)) {
    // A run of one tick, at t = 0, measures nothing and always reports "not converged".
    // Checked against the default duration too: a rate this slow is a mistake either way.
    if (const toml::node* node = t.Get("duration_s")) {
      r.FailAt(*node, t.KeyOf("duration_s"),
               "must be at least one control period (" + FormatNumber(1.0 / s->control_rate_hz) +
                   " s at " + FormatNumber(s->control_rate_hz) + " Hz)",
               "the run lasts duration_s seconds, e.g. duration_s = 600");
    } else if (const toml::node* rate = t.Get("control_rate_hz")) {
      r.FailAt(*rate, t.KeyOf("control_rate_hz"),
               "its control period (" + FormatNumber(1.0 / s->control_rate_hz) +
                   " s) is longer than the run (duration_s, default " +
                   FormatNumber(s->duration_s) + " s)",
               "the control loop runs at control_rate_hz, e.g. 50");
    }
  }
  if (const toml::node* node = t.Get("duration_s")) {
    const std::string refusal = s->TickLimitRefusal();
    if (!refusal.empty()) {
      r.FailAt(*node, t.KeyOf("duration_s"), "is too long: " + refusal,
               "the run lasts duration_s seconds, e.g. duration_s = 600");
    }
  }
  if (const toml::node* node = t.Get("seed")) {
    s->seed = static_cast<std::uint64_t>(
        r.ToInteger(*node, t.KeyOf("seed"),
                    {0, std::numeric_limits<std::int64_t>::max(), "must be an integer >= 0"},
                    "seed makes random delays, losses and currents reproducible"));
  }
}

/// `edges` of [swarm] or of a topology event: pairs [i, j] of distinct follower ids, each
/// once. Absent: no follower edges.
void ReadEdges(const Reader& r, const Table& t, int n, std::vector<std::pair<int, int>>* out) {
  const toml::node* edges_node = t.Get("edges");
  if (edges_node == nullptr) return;
  const IntBound id{1, n, "follower ids must be in 1.." + std::to_string(n)};
  const std::string key = t.KeyOf("edges");
  const std::string_view hint =
      "an edge [i, j] means follower i receives from follower j, e.g. edges = [[2, 1]]";
  const toml::array& edges = r.ToArray(*edges_node, key, "must be an array of [i, j] pairs", hint);
  std::set<std::pair<int, int>> seen;
  for (std::size_t e = 0; e < edges.size(); ++e) {
    const toml::node& pair_node = *edges.get(e);
    const std::string pair_key = Index(key, e);
    const toml::array* pair = pair_node.as_array();
    if (pair == nullptr || pair->size() != 2) {
      r.FailAt(pair_node, pair_key, "must be a pair [i, j] of follower ids", hint);
    }
    const int i = static_cast<int>(r.ToInteger(*pair->get(0), Index(pair_key, 0), id, hint));
    const int j = static_cast<int>(r.ToInteger(*pair->get(1), Index(pair_key, 1), id, hint));
    if (i == j) r.FailAt(pair_node, pair_key, "a follower cannot receive from itself", hint);
    if (!seen.emplace(i, j).second) {
      r.FailAt(pair_node, pair_key, "duplicate edge", "list each edge once");
    }
    out->emplace_back(i, j);
  }
}

/// `leader_links` of [swarm] or of a topology event: required, non-empty, distinct ids.
void ReadLeaderLinks(const Reader& r, const Table& t, int n, std::vector<int>* out) {
  const IntBound id{1, n, "follower ids must be in 1.." + std::to_string(n)};
  const std::string key = t.KeyOf("leader_links");
  const std::string_view hint =
      "leader_links lists the followers that receive the leader, e.g. leader_links = [1]";
  const toml::node& node = r.Require(t, "leader_links", hint);
  const toml::array& links = r.ToArray(node, key, "must be an array of follower ids", hint);
  if (links.empty()) r.FailAt(node, key, "must list at least one follower", hint);
  for (std::size_t k = 0; k < links.size(); ++k) {
    const int i = static_cast<int>(r.ToInteger(*links.get(k), Index(key, k), id, hint));
    if (std::find(out->begin(), out->end(), i) != out->end()) {
      r.FailAt(*links.get(k), Index(key, k), "duplicate follower id", "list each follower once");
    }
    out->push_back(i);
  }
}

/// Assumption 1 for one topology: every follower has a directed path from the leader.
/// `when` qualifies the topology in the message ("" for [swarm]).
void CheckReachable(const Reader& r, int n, const std::vector<std::pair<int, int>>& edges,
                    const std::vector<int>& leader_links, const toml::source_region& where,
                    const std::string& key, const std::string& when) {
  const std::vector<int> unreachable =
      Topology::Build(n, edges, leader_links).UnreachableFollowers();
  if (unreachable.empty()) return;
  r.Fail(where, key,
         (unreachable.size() == 1 ? "follower " : "followers ") + JoinInts(unreachable) +
             " cannot be reached from the leader (Assumption 1)" + when,
         std::nullopt,
         "add leader_links or edges so every follower has a directed path from the leader");
}

void ReadSwarm(const Reader& r, const Table& t, Scenario* s) {
  r.CheckKeys(t, kSwarmKeys);
  const int n = static_cast<int>(
      r.RequireInteger(t, "followers", {1, kMaxFollowers, "must be an integer in 1..1000"},
                       "followers is the number of follower vehicles, a whole number >= 1"));
  s->followers = n;
  const toml::node* edges_node = t.Get("edges");
  ReadEdges(r, t, n, &s->edges);
  ReadLeaderLinks(r, t, n, &s->leader_links);

  r.ReadNumber(t, "neighbour_timeout_s", kPositiveSeconds,
               "a neighbour whose newest message is older than this drops out of the control law",
               &s->neighbour_timeout_s);

  CheckReachable(r, n, s->edges, s->leader_links, RegionAt(edges_node, t.line), t.KeyOf("edges"),
                 "");
}

void ReadControl(const Reader& r, const Table& t, Scenario* s) {
  r.CheckKeys(t, kControlKeys);
  const std::string_view gain_hint = "consensus gains k1, k2 must be > 0";
  s->k1 = r.RequireNumber(t, "k1", kGain, gain_hint);
  s->k2 = r.RequireNumber(t, "k2", kGain, gain_hint);

  const std::size_t n = static_cast<std::size_t>(s->followers);
  s->offsets_m.assign(n, Vec3::Zero());
  if (const toml::node* node = t.Get("offsets_m")) {
    const std::string key = t.KeyOf("offsets_m");
    const std::string hint =
        "give one offset [x, y, z] in metres (NED, relative to the leader) "
        "for each of the " +
        std::to_string(n) + " followers";
    const std::string what = "must have exactly " + std::to_string(n) +
                             (n == 1 ? " entry" : " entries") + ", one [x, y, z] per follower";
    const toml::array& offsets = r.ToArray(*node, key, what, hint);
    if (offsets.size() != n) r.FailAt(*node, key, what, hint);
    for (std::size_t i = 0; i < n; ++i) {
      s->offsets_m[i] = r.ToVector<3>(*offsets.get(i), Index(key, i), kCoordinate, hint);
    }
  }
}

/// The climb or dive angle of a leg d (NED: z down), in radians, magnitude only.
double PitchOf(const Vec3& d) { return std::abs(std::atan2(d.z(), std::hypot(d.x(), d.y()))); }

/// The leader's attitude follows its path, and the followers start at the leader's: a leg
/// steeper than a REMUS 100 can pitch would start them, or steer them, towards the
/// Euler angles' singularity at 90 deg.
void CheckPathPitch(const Reader& r, const toml::node& node, const std::string& key,
                    const Vec3& d, const std::string& which) {
  const double pitch = PitchOf(d);
  if (pitch <= kMaxPitchRad) return;
  char deg[32];
  std::snprintf(deg, sizeof(deg), "%.1f", pitch * 180.0 / M_PI);
  r.FailAt(node, key, which + " climbs or dives at " + deg + " deg",
           "a REMUS 100 pitches at most 30 deg (0.5236 rad): make it less steep");
}

void ReadWaypoints(const Reader& r, const Table& t, LeaderConfig* leader) {
  const std::string key = t.KeyOf("waypoints_m");
  const std::string_view hint =
      "waypoints_m is a list of points [x, y, z] in metres (NED), e.g. [[0, 0, 5], [50, 0, 5]]";
  const toml::node& node = r.Require(t, "waypoints_m", hint);
  const toml::array& points =
      r.ToArray(node, key, "must be an array of at least 2 points [x, y, z]", hint);
  if (points.size() < 2) r.FailAt(node, key, "must have at least 2 points", hint);
  for (std::size_t k = 0; k < points.size(); ++k) {
    const Vec3 p = r.ToVector<3>(*points.get(k), Index(key, k), kCoordinate, hint);
    if (!leader->waypoints_m.empty() && p == leader->waypoints_m.back()) {
      r.FailAt(*points.get(k), Index(key, k), "repeats the previous waypoint",
               "consecutive waypoints must differ");
    }
    if (!leader->waypoints_m.empty()) {
      CheckPathPitch(r, *points.get(k), Index(key, k), p - leader->waypoints_m.back(),
                     "the leg to this waypoint");
    }
    leader->waypoints_m.push_back(p);
  }
  r.ReadNumber(t, "speed_mps", kPositiveSpeed, "the leader's along-path speed in m/s",
               &leader->speed_mps);
  r.ReadBool(t, "loop", "loop = true returns to the first waypoint and repeats", &leader->loop);
  if (leader->loop && leader->waypoints_m.back() == leader->waypoints_m.front()) {
    r.FailAt(*points.get(points.size() - 1), Index(key, points.size() - 1),
             "repeats the first waypoint while loop = true",
             "a looped path closes by itself: remove the last waypoint");
  }
  if (leader->loop) {
    CheckPathPitch(r, node, key, leader->waypoints_m.front() - leader->waypoints_m.back(),
                   "the leg back to the first waypoint (loop = true)");
  }
}

void ReadLeader(const Reader& r, const Table& t, LeaderConfig* leader) {
  r.CheckKeys(t, kLeaderKeys);
  leader->path = r.ReadVariant(t, "path", kLeaderPaths, "leader path");
  switch (leader->path) {
    case PathKind::kPaperHelix:
      break;
    case PathKind::kLine:
      r.ReadVector<3>(t, "start_m", kCoordinate, "the leader's position [x, y, z] at t = 0, metres",
                      &leader->start_m);
      r.ReadVector<3>(t, "velocity_mps", kVelocity,
                      "the leader's constant velocity [vx, vy, vz] in m/s (NED)",
                      &leader->velocity_mps);
      if (const toml::node* v = t.Get("velocity_mps")) {
        CheckPathPitch(r, *v, t.KeyOf("velocity_mps"), leader->velocity_mps, "the path");
      }
      break;
    case PathKind::kWaypoints:
      ReadWaypoints(r, t, leader);
      break;
  }
}

/// The whole of a regular file of at most kMaxScenarioBytes; throws ScenarioError
/// ("<path>: cannot read <what> ...").
std::string ReadLimitedFile(const std::string& path, const std::string& what) {
  std::string error;
  const int fd = OpenRegularFile(path, what, kMaxScenarioBytes, &error);
  if (fd < 0) throw ScenarioError(error);
  std::string text;
  char buffer[1 << 16];
  for (;;) {
    const ssize_t count = read(fd, buffer, sizeof(buffer));
    if (count < 0 && errno == EINTR) continue;
    if (count <= 0) {
      const int e = errno;
      close(fd);
      if (count < 0) {
        throw ScenarioError(path + ": cannot read " + what + " (" +
                            std::error_code(e, std::generic_category()).message() + ")");
      }
      break;
    }
    text.append(buffer, static_cast<std::size_t>(count));
    if (text.size() > kMaxScenarioBytes) {  // grew since it was opened
      close(fd);
      throw ScenarioError(path + ": cannot read " + what +
                          ": it grew beyond the limit of " +
                          std::to_string(kMaxScenarioBytes) + " bytes while being read");
    }
  }
  return text;
}

/// One number of a trace row: the whole field must be a finite number in [0, 1e9].
bool ParseTraceNumber(std::string field, double* out) {
  const auto blank = [](char c) { return c == ' ' || c == '\t' || c == '\r'; };
  while (!field.empty() && blank(field.back())) field.pop_back();
  std::size_t first = 0;
  while (first < field.size() && blank(field[first])) ++first;
  field = field.substr(first);
  if (field.empty()) return false;
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(field.c_str(), &end);
  if (end != field.c_str() + field.size() || errno == ERANGE) return false;
  *out = v;
  return std::isfinite(v) && v >= 0.0 && v <= kMaxSeconds;
}

/// The rows of a delay trace CSV: "t_s, delay_s" per line, an optional header line
/// "t_s, delay_s", '#' comments and blank lines. Problems are reported at the CSV's line.
void ParseTraceText(const std::string& text, const std::string& csv, DelayTrace* trace) {
  std::istringstream in(text);
  std::string line;
  const std::string fix = "each line is \"t_s, delay_s\": seconds, t_s strictly increasing, "
                          "delays finite and in [0, 1e9]";
  for (int number = 1; std::getline(in, line); ++number) {
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.erase(hash);
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const auto fail = [&](const std::string& what) {
      throw ScenarioError(csv + ":" + std::to_string(number) + ": " + what + " (got " +
                          Quoted(line.substr(0, kMaxShownChars)) + "); " + fix);
    };
    const auto comma = line.find(',');
    if (comma == std::string::npos || line.find(',', comma + 1) != std::string::npos) {
      fail("a trace row needs exactly two fields, t_s and delay_s");
    }
    double t = 0.0, d = 0.0;
    const bool t_ok = ParseTraceNumber(line.substr(0, comma), &t);
    const bool d_ok = ParseTraceNumber(line.substr(comma + 1), &d);
    if (!t_ok || !d_ok) {
      std::string compact;
      for (char c : line) {
        if (c != ' ' && c != '\t' && c != '\r') compact += c;
      }
      if (trace->t_s.empty() && compact == "t_s,delay_s") continue;  // the header
      fail(t_ok ? "delay_s must be a number of seconds in [0, 1e9]"
                : "t_s must be a number of seconds in [0, 1e9]");
    }
    if (!trace->t_s.empty() && !(t > trace->t_s.back())) {
      fail("t_s must increase strictly from row to row");
    }
    trace->t_s.push_back(t);
    trace->delay_s.push_back(d);
  }
  if (trace->t_s.empty()) {
    throw ScenarioError(csv + ":1: the trace has no rows; " + fix);
  }
}

void ReadTraceDelay(const Reader& r, const Table& t, DelayConfig* delay) {
  auto trace = std::make_shared<DelayTrace>();
  const std::string hint = "file is a CSV of \"t_s, delay_s\" rows, relative to the scenario file";
  const toml::node& node = r.Require(t, "file", hint);
  trace->file = r.ToString(node, t.KeyOf("file"), hint);
  if (trace->file.empty()) r.FailAt(node, t.KeyOf("file"), "must not be empty", hint);
  if (const toml::node* how = t.Get("interpolation")) {
    const std::string key = t.KeyOf("interpolation");
    const std::string fix = "use \"linear\" (between rows) or \"hold\" (the row at or before t)";
    const std::string v = r.ToString(*how, key, fix);
    if (v != "linear" && v != "hold") r.FailAt(*how, key, "unknown interpolation", fix);
    trace->hold = v == "hold";
  }
  const std::string csv = r.Resolve(trace->file);
  try {
    ParseTraceText(ReadLimitedFile(csv, "delay trace"), csv, trace.get());
  } catch (const ScenarioError& e) {
    r.Fail(node.source(), t.KeyOf("file"), e.what(), std::nullopt,
           "fix the trace, or the path (relative to the scenario file)");
  }
  delay->trace = std::move(trace);
}

// At least 1 m/s: slower, a delay over the range of a run would not fit the microseconds
// of the run's clock (1 km at 1e-12 m/s is 1e15 s).
constexpr Bound kSoundSpeed{1.0, false, 1e5, false, "must be a speed in [1, 1e5] m/s"};
constexpr Bound kRange{0.0, true, 1e7, false, "must be a positive distance, at most 1e7 m"};

void ReadAcousticDelay(const Reader& r, const Table& t, DelayConfig* delay) {
  r.ReadNumber(t, "sound_speed_mps", kSoundSpeed, "the speed of sound in water is about 1500 m/s",
               &delay->sound_speed_mps);
  r.ReadNumber(t, "processing_s", kSeconds, "processing_s is the modem's latency in seconds",
               &delay->processing_s);
  r.ReadNumber(t, "jitter_s", kSeconds,
               "jitter_s adds a seeded U(0, jitter_s) to every message's delay",
               &delay->jitter_s);
  delay->max_range_m = r.RequireNumber(
      t, "max_range_m", kRange, "max_range_m is the modem's range: beyond it a message is lost");
  r.ReadNumber(t, "loss_at_max_range", kClosedProbability,
               "the loss probability rises from 0 at half the range to this at max_range_m",
               &delay->loss_at_max_range);
}

DelayConfig ReadDelay(const Reader& r, const Table& t) {
  r.CheckKeys(t, kDelayKeys);
  DelayConfig delay;
  delay.kind = r.ReadVariant(t, "model", kDelayModels, "delay model");
  if (delay.kind == DelayKind::kNone) return delay;
  if (delay.kind == DelayKind::kAcoustic) {
    ReadAcousticDelay(r, t, &delay);
    return delay;
  }
  if (delay.kind == DelayKind::kTrace) {
    ReadTraceDelay(r, t, &delay);
    return delay;
  }
  delay.base_s = r.RequireNumber(t, "base_s", kSeconds, "base_s is the mean delay in seconds");
  if (delay.kind == DelayKind::kConstant) return delay;

  delay.amplitude_s = r.RequireNumber(t, "amplitude_s", kSeconds,
                                      "amplitude_s is the delay's variation around base_s");
  if (delay.amplitude_s > delay.base_s) {
    r.FailAt(*t.Get("amplitude_s"), t.KeyOf("amplitude_s"),
             "must not exceed base_s = " + FormatNumber(delay.base_s),
             "the delay base_s +- amplitude_s must stay >= 0: lower amplitude_s or raise base_s");
  }
  if (delay.kind != DelayKind::kSinusoid) return delay;

  delay.omega_rad_s = r.RequireNumber(t, "omega_rad_s", kNonNegative,
                                      "omega_rad_s is the angular frequency of the delay");
  const double rate = delay.amplitude_s * delay.omega_rad_s;
  if (rate >= 1.0) {
    r.Fail(t.Get("omega_rad_s")->source(), t.KeyOf("omega_rad_s"),
           "amplitude_s * omega_rad_s must be < 1 (Assumption 3: d tau/dt < 1)",
           FormatNumber(delay.amplitude_s) + " * " + FormatNumber(delay.omega_rad_s) + " = " +
               FormatNumber(rate),
           "otherwise messages would overtake each other: lower amplitude_s or omega_rad_s");
  }
  return delay;
}

LossConfig ReadLoss(const Reader& r, const Table& t) {
  r.CheckKeys(t, kLossKeys);
  LossConfig loss;
  loss.kind = r.ReadVariant(t, "model", kLossModels, "loss model");
  if (loss.kind == LossKind::kBernoulli) {
    loss.probability = r.RequireNumber(
        t, "probability", kProbability,
        "probability is the chance that a message is dropped; 1 would drop every message");
  }
  if (loss.kind == LossKind::kGilbertElliott) {
    const std::string_view move = "the chance per message of moving between the good and bad state";
    loss.p_good_to_bad = r.RequireNumber(t, "p_good_to_bad", kTransitionProbability, move);
    loss.p_bad_to_good = r.RequireNumber(t, "p_bad_to_good", kTransitionProbability, move);
    loss.loss_good = r.RequireNumber(
        t, "loss_good", kProbability,
        "loss_good is the loss probability in the good state; 1 would drop every message");
    loss.loss_bad = r.RequireNumber(t, "loss_bad", kClosedProbability,
                                    "loss_bad is the loss probability in the bad state");
  }
  return loss;
}

void ReadLinks(const Reader& r, const Table& channel, Scenario* s) {
  const int n = s->followers;
  std::set<std::pair<int, int>> seen;
  for (const Table& t : r.ArrayOfTables(channel, "link")) {
    r.CheckKeys(t, kLinkKeys);
    LinkOverride link;
    link.from = static_cast<int>(r.RequireInteger(
        t, "from", {0, n, "must be 0 (the leader) or a follower id in 1.." + std::to_string(n)},
        "from is the sender: 0 for the leader or a follower id"));
    link.to = static_cast<int>(
        r.RequireInteger(t, "to", {1, n, "must be a follower id in 1.." + std::to_string(n)},
                         "to is the receiving follower's id"));
    const std::string from_text =
        link.from == 0 ? "the leader" : "follower " + std::to_string(link.from);
    const std::string link_text =
        "the link from " + from_text + " to follower " + std::to_string(link.to);
    const std::string got =
        "from = " + std::to_string(link.from) + ", to = " + std::to_string(link.to);
    const toml::source_region line = t.Get("from")->source();
    const bool exists =
        link.from == 0
            ? std::count(s->leader_links.begin(), s->leader_links.end(), link.to) > 0
            : std::count(s->edges.begin(), s->edges.end(), std::make_pair(link.to, link.from)) > 0;
    if (!exists) {
      const std::string fix = link.from == 0
                                  ? "add " + std::to_string(link.to) + " to swarm.leader_links"
                                  : "add [" + std::to_string(link.to) + ", " +
                                        std::to_string(link.from) + "] to swarm.edges";
      r.Fail(line, t.key, link_text + " is not a link of the topology", got,
             "overrides apply to existing links only: " + fix + ", or fix from/to");
    }
    if (!seen.emplace(link.from, link.to).second) {
      r.Fail(line, t.key, "duplicate override of " + link_text, got,
             "merge the two [[channel.link]] tables into one");
    }
    if (t.Get("delay") != nullptr) {
      link.delay =
          ReadDelay(r, r.Child(t, "delay", "write delay = { model = \"constant\", base_s = 0.1 }"));
    }
    if (t.Get("loss") != nullptr) {
      link.loss = ReadLoss(
          r, r.Child(t, "loss", "write loss = { model = \"bernoulli\", probability = 0.1 }"));
    }
    s->links.push_back(link);
  }
}

void ReadModems(const Reader& r, const Table& channel, Scenario* s) {
  const std::string_view hint = "the modem transmits at most one state per min_interval_s";
  r.ReadNumber(channel, "modem_min_interval_s", kSeconds, hint, &s->modem_min_interval_s);
  std::set<int> seen;
  for (const Table& t : r.ArrayOfTables(channel, "modem")) {
    r.CheckKeys(t, kModemKeys);
    ModemConfig m;
    m.id = static_cast<int>(r.RequireInteger(
        t, "id",
        {0, s->followers,
         "must be 0 (the leader) or a follower id in 1.." + std::to_string(s->followers)},
        "id is the sending vehicle: 0 for the leader or a follower id"));
    if (!seen.insert(m.id).second) {
      r.FailAt(*t.Get("id"), t.KeyOf("id"), "duplicate modem id",
               "give each vehicle at most one [[channel.modem]] table");
    }
    m.min_interval_s = r.RequireNumber(t, "min_interval_s", kSeconds, hint);
    s->modems.push_back(m);
  }
}

void ReadChannel(const Reader& r, const Table& t, Scenario* s) {
  r.CheckKeys(t, kChannelKeys);
  s->delay = ReadDelay(r, r.Child(t, "delay", "write [channel.delay] with model = ..."));
  s->loss = ReadLoss(r, r.Child(t, "loss", "write [channel.loss] with model = ..."));
  ReadLinks(r, t, s);
  ReadModems(r, t, s);
}

/// The line of the first of `keys` present in `t`, else the table's line.
toml::source_region LineOfAny(const Table& t, std::initializer_list<std::string_view> keys) {
  for (const std::string_view key : keys) {
    if (const toml::node* node = t.Get(key)) return node->source();
  }
  return RegionAt(t.node, t.line);
}

void ReadDisturbance(const Reader& r, const Table& t, DisturbanceConfig* disturbance) {
  r.CheckKeys(t, kDisturbanceKeys);
  disturbance->kind = r.ReadVariant(t, "model", kDisturbanceModels, "disturbance model");
  if (disturbance->kind == DisturbanceKind::kPaperExample2) {
    r.ReadBool(t, "relative_to_leader",
               "true: followers feel F(x_i) - F(x_0) as in the paper's error system (13); "
               "false: the absolute F(x_i)",
               &disturbance->relative_to_leader);
  }
  if (disturbance->kind != DisturbanceKind::kOceanCurrent) return;
  OceanCurrentConfig& c = disturbance->current;
  const std::string_view speed_hint =
      "current speeds are in m/s, min_speed_mps <= speed_mps <= max_speed_mps";
  r.ReadNumber(t, "speed_mps", kSpeed, speed_hint, &c.speed_mps);
  r.ReadNumber(t, "min_speed_mps", kSpeed, speed_hint, &c.min_speed_mps);
  r.ReadNumber(t, "max_speed_mps", kSpeed, speed_hint, &c.max_speed_mps);
  r.ReadNumber(t, "mu_per_s", kRatePerSecond, "1/mu_per_s is the Gauss-Markov time constant",
               &c.mu_per_s);
  r.ReadNumber(t, "noise_mps", kSpeed,
               "noise_mps is the standard deviation of the white noise", &c.noise_mps);
  r.ReadNumber(t, "direction_rad", kFinite, "direction_rad is the current's direction (NED)",
               &c.direction_rad);
  if (c.min_speed_mps > c.max_speed_mps) {
    r.Fail(LineOfAny(t, {"min_speed_mps", "max_speed_mps"}), t.KeyOf("min_speed_mps"),
           "must not exceed max_speed_mps",
           "min_speed_mps = " + FormatNumber(c.min_speed_mps) +
               ", max_speed_mps = " + FormatNumber(c.max_speed_mps),
           speed_hint);
  }
  if (c.speed_mps < c.min_speed_mps || c.speed_mps > c.max_speed_mps) {
    r.Fail(LineOfAny(t, {"speed_mps", "min_speed_mps", "max_speed_mps"}), t.KeyOf("speed_mps"),
           "must lie in [min_speed_mps, max_speed_mps]",
           FormatNumber(c.speed_mps) + " outside [" + FormatNumber(c.min_speed_mps) + ", " +
               FormatNumber(c.max_speed_mps) + "]",
           speed_hint);
  }
}

/// run_rate: [run] control_rate_hz's node (null: absent), where a default step too small
/// for the period is reported (the rate is what made it so, perhaps from a --set).
void ReadVehicle(const Reader& r, const Table& t, Scenario* s, const toml::node* run_rate) {
  r.CheckKeys(t, kVehicleKeys);
  r.ReadVector<5>(t, "tau_max", kPositive,
                  "give positive limits [X, Y, Z, M, N] in N, N, N, N m, N m", &s->vehicle.tau_max);
  const double period_s = ToSeconds(s->period_us());
  if (const toml::node* node = t.Get("integrator_step_s")) {
    const std::string key = t.KeyOf("integrator_step_s");
    const std::string hint = "the RK4 step must fit in one control period (" +
                             FormatNumber(period_s) + " s at " + FormatNumber(s->control_rate_hz) +
                             " Hz)";
    s->vehicle.integrator_step_s = r.ToNumber(*node, key, kPositive, hint);
    if (s->vehicle.integrator_step_s > period_s * (1.0 + 1e-9)) {
      r.FailAt(*node, key, "must not exceed the control period", hint);
    }
    if (period_s / s->vehicle.integrator_step_s > kMaxRk4Substeps * (1.0 + 1e-9)) {
      r.FailAt(*node, key,
               "must be at least 1/" + std::to_string(kMaxRk4Substeps) + " of the control period (" +
                   FormatNumber(period_s / kMaxRk4Substeps) + " s)",
               hint);
    }
  } else {
    // The default step never exceeds the control period at high rates.
    s->vehicle.integrator_step_s = std::min(s->vehicle.integrator_step_s, period_s);
    if (period_s / s->vehicle.integrator_step_s > kMaxRk4Substeps * (1.0 + 1e-9)) {
      r.Fail(RegionAt(run_rate, t.line), t.KeyOf("integrator_step_s"),
             "the default RK4 step (0.01 s) is less than 1/" + std::to_string(kMaxRk4Substeps) +
                 " of the control period (" + FormatNumber(period_s) + " s)",
             std::nullopt,
             "give [vehicle] integrator_step_s of at least " +
                 FormatNumber(period_s / kMaxRk4Substeps) + " s, or a faster control_rate_hz");
    }
  }
}

void ReadMetrics(const Reader& r, const Table& t, MetricsConfig* metrics) {
  r.CheckKeys(t, kMetricsKeys);
  r.ReadNumber(t, "position_tol_m", kPositive, "formation position tolerance in metres",
               &metrics->position_tol_m);
  r.ReadNumber(t, "velocity_tol_mps", kPositive, "formation velocity tolerance in m/s",
               &metrics->velocity_tol_mps);
}

void ReadFollowers(const Reader& r, const Table& root, Scenario* s) {
  const int n = s->followers;
  s->initial.assign(static_cast<std::size_t>(n), FollowerInit{});
  for (const Table& t : r.ArrayOfTables(root, "follower")) {
    r.CheckKeys(t, kFollowerKeys);
    const int id = static_cast<int>(
        r.RequireInteger(t, "id", {1, n, "must be a follower id in 1.." + std::to_string(n)},
                         "id says which follower this initial state is for"));
    FollowerInit& init = s->initial[static_cast<std::size_t>(id - 1)];
    if (init.given) {
      r.FailAt(*t.Get("id"), t.KeyOf("id"), "duplicate follower id",
               "give each follower at most one [[follower]] table");
    }
    init.given = true;
    Vec3 position = Vec3::Zero();
    r.ReadVector<3>(t, "position_m", kCoordinate, "initial position [x, y, z] in metres (NED)",
                    &position);
    init.eta.head<3>() = position;
    r.ReadNumber(t, "pitch_rad", kPitch, "the REMUS 100 pitch limit is 30 deg (0.5236 rad)",
                 &init.eta(3));
    r.ReadNumber(t, "heading_rad", kFinite, "initial heading in radians", &init.eta(4));
    r.ReadVector<5>(t, "nu", kVelocity, "initial body velocities [u, v, w, q, r] in m/s and rad/s",
                    &init.nu);
  }
}

// ---------------------------------------------------------------------------------------
// [[event]]: the timeline.

std::string LinkText(int from, int to) {
  return "the link from " +
         (from == 0 ? std::string("the leader") : "follower " + std::to_string(from)) +
         " to follower " + std::to_string(to);
}

/// `links` of a link_down or channel event: distinct pairs [from, to]; absent: every link.
void ReadEventLinks(const Reader& r, const Table& t, int n, std::vector<std::pair<int, int>>* out) {
  const toml::node* node = t.Get("links");
  if (node == nullptr) return;
  const std::string key = t.KeyOf("links");
  const std::string_view hint =
      "links lists [from, to] pairs, from 0 (the leader) or a follower id, e.g. "
      "links = [[0, 1], [1, 2]]; omit links for every link";
  const toml::array& links = r.ToArray(*node, key, "must be an array of [from, to] pairs", hint);
  if (links.empty()) r.FailAt(*node, key, "must list at least one link", hint);
  const IntBound from{0, n, "must be 0 (the leader) or a follower id in 1.." + std::to_string(n)};
  const IntBound to{1, n, "must be a follower id in 1.." + std::to_string(n)};
  std::set<std::pair<int, int>> seen;
  for (std::size_t k = 0; k < links.size(); ++k) {
    const toml::node& pair_node = *links.get(k);
    const std::string pair_key = Index(key, k);
    const toml::array* pair = pair_node.as_array();
    if (pair == nullptr || pair->size() != 2) {
      r.FailAt(pair_node, pair_key, "must be a pair [from, to]", hint);
    }
    const int f = static_cast<int>(r.ToInteger(*pair->get(0), Index(pair_key, 0), from, hint));
    const int g = static_cast<int>(r.ToInteger(*pair->get(1), Index(pair_key, 1), to, hint));
    if (!seen.emplace(f, g).second) {
      r.FailAt(pair_node, pair_key, "duplicate link", "list each link once");
    }
    out->emplace_back(f, g);
  }
}

/// `vehicles` of a vehicle_silent, vehicle_deaf or controller_reset event.
void ReadEventVehicles(const Reader& r, const Table& t, int n, std::vector<int>* out) {
  const std::string key = t.KeyOf("vehicles");
  const std::string_view hint = "vehicles lists follower ids, e.g. vehicles = [2, 3]";
  const toml::node& node = r.Require(t, "vehicles", hint);
  const toml::array& ids = r.ToArray(node, key, "must be an array of follower ids", hint);
  if (ids.empty()) r.FailAt(node, key, "must list at least one follower", hint);
  const IntBound id{1, n, "must be a follower id in 1.." + std::to_string(n)};
  for (std::size_t k = 0; k < ids.size(); ++k) {
    const int i = static_cast<int>(r.ToInteger(*ids.get(k), Index(key, k), id, hint));
    if (std::find(out->begin(), out->end(), i) != out->end()) {
      r.FailAt(*ids.get(k), Index(key, k), "duplicate follower id", "list each follower once");
    }
    out->push_back(i);
  }
}

void ReadChannelEvent(const Reader& r, const Table& t, ScenarioEvent* e) {
  if (t.Get("delay") == nullptr && t.Get("loss") == nullptr) {
    r.Fail(RegionAt(t.node, t.line), t.KeyOf("delay"), "a channel event needs a delay or a loss table", std::nullopt,
           "add delay = { model = \"constant\", base_s = 0.5 } and/or "
           "loss = { model = \"bernoulli\", probability = 0.2 }");
  }
  if (t.Get("delay") != nullptr) {
    e->delay =
        ReadDelay(r, r.Child(t, "delay", "write delay = { model = \"constant\", base_s = 0.1 }"));
  }
  if (t.Get("loss") != nullptr) {
    e->loss = ReadLoss(
        r, r.Child(t, "loss", "write loss = { model = \"bernoulli\", probability = 0.1 }"));
  }
}

/// kind, at_s and until_s of an event.
void ReadEventTimes(const Reader& r, const Table& t, ScenarioEvent* e) {
  const std::string_view kind_hint =
      "kind is one of \"link_down\", \"channel\", \"topology\", \"vehicle_silent\", "
      "\"vehicle_deaf\", \"leader_silent\", \"controller_reset\"";
  const toml::node& kind = r.Require(t, "kind", kind_hint);
  const toml::node* until = t.Get("until_s");
  if (until != nullptr && kind.as_string() != nullptr &&
      kind.as_string()->get() == "controller_reset") {
    r.FailAt(*until, t.KeyOf("until_s"), "not used by event kind \"controller_reset\"",
             "a reset lasts outage_s from at_s: remove until_s");
  }
  e->kind = r.ReadVariant(t, "kind", kEventKinds, "event kind");
  e->at_s = r.RequireNumber(t, "at_s", kSeconds,
                            "at_s is the mission time in seconds at which the change starts");
  if (until != nullptr) {
    const std::string key = t.KeyOf("until_s");
    const std::string_view hint = "the change is undone at until_s (seconds of mission time)";
    e->until_s = r.ToNumber(*until, key, kSeconds, hint);
    // The timeline counts whole microseconds: an empty window there is a mistake here.
    if (TimelineMicros(e->until_s) <= TimelineMicros(e->at_s)) {
      r.FailAt(
          *until, key,
          "must be later than at_s = " + FormatNumber(e->at_s) + " (by at least a microsecond)",
          hint);
    }
  }
}

ScenarioEvent ReadEvent(const Reader& r, const Table& t, int n) {
  r.CheckKeys(t, kEventKeys);
  ScenarioEvent e;
  e.line = t.line;
  ReadEventTimes(r, t, &e);
  switch (e.kind) {
    case EventKind::kLinkDown:
      ReadEventLinks(r, t, n, &e.links);
      break;
    case EventKind::kChannel:
      ReadEventLinks(r, t, n, &e.links);
      ReadChannelEvent(r, t, &e);
      break;
    case EventKind::kTopology:
      ReadEdges(r, t, n, &e.edges);
      ReadLeaderLinks(r, t, n, &e.leader_links);
      break;
    case EventKind::kVehicleSilent:
    case EventKind::kVehicleDeaf:
      ReadEventVehicles(r, t, n, &e.vehicles);
      break;
    case EventKind::kLeaderSilent:
      break;
    case EventKind::kControllerReset: {
      ReadEventVehicles(r, t, n, &e.vehicles);
      const std::string_view hint =
          "the controller commands zero force for outage_s seconds from at_s";
      e.outage_s = r.RequireNumber(t, "outage_s", kPositiveSeconds, hint);
      if (TimelineMicros(e.end_s()) <= TimelineMicros(e.at_s)) {
        r.FailAt(*t.Get("outage_s"), t.KeyOf("outage_s"), "must be at least a microsecond", hint);
      }
      break;
    }
  }
  return e;
}

/// Every link an event lists belongs to some topology of the timeline.
void CheckEventLinks(const Reader& r, const std::vector<Table>& tables, const Scenario& s) {
  const std::vector<std::pair<int, int>> all = UnionTopology(s).Links();
  const std::set<std::pair<int, int>> known(all.begin(), all.end());
  for (std::size_t k = 0; k < s.events.size(); ++k) {
    const ScenarioEvent& e = s.events[k];
    for (std::size_t j = 0; j < e.links.size(); ++j) {
      const auto [from, to] = e.links[j];
      if (known.count(e.links[j]) > 0) continue;
      const std::string edge =
          from == 0 ? std::to_string(to) + " in leader_links"
                    : "[" + std::to_string(to) + ", " + std::to_string(from) + "] in edges";
      r.Fail(tables[k].Get("links")->as_array()->get(j)->source(),
             Index(tables[k].KeyOf("links"), j),
             LinkText(from, to) + " is not a link of any topology of the scenario",
             "[" + std::to_string(from) + ", " + std::to_string(to) + "]",
             "a link exists if [swarm] or a topology event has " + edge +
                 ": add it there, or "
                 "fix the pair [from, to]");
    }
  }
}

/// "[a, b)" in seconds, "[a, end of run)" for an open window.
std::string WindowText(const ScenarioEvent& e) {
  const double end = e.end_s();
  return "[" + FormatNumber(e.at_s) + ", " + (std::isinf(end) ? "end of run" : FormatNumber(end)) +
         ")";
}

/// The latest end among earlier events (they all start at or before the current one, so
/// the current one overlaps one of them exactly if it starts before this end).
struct LatestEnd {
  Micros end = std::numeric_limits<Micros>::min();
  int event = -1;
  void Take(Micros e, int k) {
    if (e > end) end = e, event = k;
  }
};

[[noreturn]] void FailOverlap(const Reader& r, const std::vector<Table>& tables, const Scenario& s,
                              std::size_t later, int earlier, const std::string& what,
                              std::string_view fix) {
  const ScenarioEvent& a = s.events[static_cast<std::size_t>(earlier)];
  const ScenarioEvent& b = s.events[later];
  r.Fail(RegionAt(tables[later].node, b.line), tables[later].key,
         std::string(EventKindName(b.kind)) + " window " + WindowText(b) + " overlaps the window " +
             WindowText(a) + " of " + tables[static_cast<std::size_t>(earlier)].key + " (line " +
             std::to_string(a.line) + ")" + what,
         std::nullopt, fix);
}

/// Two channel changes of one link at once would contradict each other.
void CheckChannelOverlaps(const Reader& r, const std::vector<Table>& tables, const Scenario& s) {
  const std::string_view fix =
      "two channel events must not change one link at the same time: end the first (until_s) "
      "at or before the second's at_s, or list disjoint links";
  LatestEnd any, every;  // of every channel event; of those on every link
  std::map<std::pair<int, int>, LatestEnd> by_link;
  for (std::size_t k = 0; k < s.events.size(); ++k) {
    const ScenarioEvent& e = s.events[k];
    if (e.kind != EventKind::kChannel) continue;
    const Micros at = TimelineMicros(e.at_s);
    const Micros end = TimelineMicros(e.end_s());
    // The link named is one both change: an event without links changes every link.
    const auto shared = [&](const ScenarioEvent& other) {
      const ScenarioEvent& listing = e.links.empty() ? other : e;
      return listing.links.empty()
                 ? std::string(" on every link")
                 : " on " + LinkText(listing.links[0].first, listing.links[0].second);
    };
    if (e.links.empty() && any.end > at) {
      FailOverlap(r, tables, s, k, any.event, shared(s.events[static_cast<std::size_t>(any.event)]),
                  fix);
    }
    if (every.end > at) {
      FailOverlap(r, tables, s, k, every.event,
                  shared(s.events[static_cast<std::size_t>(every.event)]), fix);
    }
    for (const auto& [from, to] : e.links) {
      const LatestEnd& l = by_link[{from, to}];
      if (l.end > at) FailOverlap(r, tables, s, k, l.event, " on " + LinkText(from, to), fix);
    }
    const int index = static_cast<int>(k);
    any.Take(end, index);
    if (e.links.empty()) every.Take(end, index);
    for (const auto& link : e.links) by_link[link].Take(end, index);
  }
}

/// Topology events follow each other: one with an explicit until_s must end before the
/// next starts. Two resets of one vehicle must not overlap.
void CheckTopologyAndResetOverlaps(const Reader& r, const std::vector<Table>& tables,
                                   const Scenario& s) {
  LatestEnd until;  // explicit until_s of earlier topology events
  int previous = -1;
  std::map<int, LatestEnd> reset_of;
  for (std::size_t k = 0; k < s.events.size(); ++k) {
    const ScenarioEvent& e = s.events[k];
    const Micros at = TimelineMicros(e.at_s);
    if (e.kind == EventKind::kTopology) {
      const std::string_view fix =
          "a topology event holds until the next one: remove until_s, or end it at or before "
          "the next topology event's at_s";
      if (previous >= 0 &&
          TimelineMicros(s.events[static_cast<std::size_t>(previous)].at_s) == at) {
        FailOverlap(r, tables, s, k, previous, " (two topologies from the same at_s)",
                    "give the topology events different at_s");
      }
      if (until.end > at) FailOverlap(r, tables, s, k, until.event, "", fix);
      if (!std::isinf(e.until_s)) until.Take(TimelineMicros(e.until_s), static_cast<int>(k));
      previous = static_cast<int>(k);
    }
    if (e.kind != EventKind::kControllerReset) continue;
    for (const int id : e.vehicles) {
      LatestEnd& l = reset_of[id];
      if (l.end > at) {
        FailOverlap(r, tables, s, k, l.event, " for follower " + std::to_string(id),
                    "two resets of one follower must not overlap: start the second at or after "
                    "the first's at_s + outage_s");
      }
      l.Take(TimelineMicros(e.end_s()), static_cast<int>(k));
    }
  }
}

/// A reset acts at the control ticks of its window: one whose window holds none would do
/// nothing in shoal sim, and shoal run would restart the vehicle's process for it all the
/// same.
void CheckResetsHoldATick(const Reader& r, const std::vector<Table>& tables, const Scenario& s) {
  const Micros period = s.period_us();
  for (std::size_t k = 0; k < s.events.size(); ++k) {
    const ScenarioEvent& e = s.events[k];
    if (e.kind != EventKind::kControllerReset) continue;
    const Micros end = TimelineMicros(e.end_s());
    const Micros last = (end - 1) / period * period;  // the last tick before the window ends
    if (last >= TimelineMicros(e.at_s)) continue;
    const Table& t = tables[k];
    r.FailAt(*t.Get("outage_s"), t.KeyOf("outage_s"),
             "the window [" + FormatNumber(e.at_s) + ", " + FormatNumber(e.end_s()) +
                 ") s holds no control tick (ticks every " + FormatNumber(period / 1e6) +
                 " s; the next at " + FormatNumber((static_cast<double>(last) + period) / 1e6) +
                 " s), so the reset would do nothing",
             "make outage_s reach the next tick, or start the reset at a tick");
  }
}

/// Assumption 1 for every topology the timeline switches to.
void CheckEventTopologies(const Reader& r, const std::vector<Table>& tables, const Scenario& s) {
  for (std::size_t k = 0; k < s.events.size(); ++k) {
    const ScenarioEvent& e = s.events[k];
    if (e.kind != EventKind::kTopology) continue;
    CheckReachable(r, s.followers, e.edges, e.leader_links, RegionAt(tables[k].node, e.line),
                   tables[k].key,
                   " in the topology from t = " + FormatNumber(e.at_s) + " s");
  }
}

/// Where the timeline's segments start (besides the one before every event): each event's
/// start and end, a topology event ending at the next one's start at the latest (as in
/// core/timeline.cc). Sorted, distinct.
std::vector<Micros> ChangeTimes(const Scenario& s) {
  std::vector<Micros> times;
  for (std::size_t k = 0; k < s.events.size(); ++k) {
    const ScenarioEvent& e = s.events[k];
    times.push_back(TimelineMicros(e.at_s));
    Micros end = TimelineMicros(e.end_s());
    for (std::size_t j = k + 1; e.kind == EventKind::kTopology && j < s.events.size(); ++j) {
      if (s.events[j].kind != EventKind::kTopology) continue;
      end = std::min(end, TimelineMicros(s.events[j].at_s));
      break;
    }
    if (end != std::numeric_limits<Micros>::max()) times.push_back(end);
  }
  std::sort(times.begin(), times.end());
  times.erase(std::unique(times.begin(), times.end()), times.end());
  return times;
}

/// The core tabulates every link of the union topology for every segment between change
/// times (core/timeline.h): refuse a table too large to hold, or too long to build. Building
/// a segment checks every link against the list of each link event in force
/// (links x listed links), each vehicle of the vehicle events in force, and every event.
void CheckTimelineSize(const Reader& r, const std::vector<Table>& tables, const Scenario& s) {
  if (s.events.empty()) return;
  const std::vector<Micros> times = ChangeTimes(s);
  const double links = static_cast<double>(UnionTopology(s).Links().size());
  const double segments = static_cast<double>(times.size()) + 1.0;
  const double cells = segments * links;
  if (cells > kMaxTimelineCells) {
    r.Fail(tables[0].line, "event",
           "the timeline is too large: " + std::to_string(times.size()) +
               " distinct change times and " + FormatNumber(links) + " links make (" +
               std::to_string(times.size()) + " + 1) x " + FormatNumber(links) + " = " +
               FormatNumber(cells) + " link states, more than 5e7",
           std::nullopt, "use fewer events (or events at shared times), or fewer links");
  }
  // Each topology is held as dense n x n matrices (core/topology.h).
  double topologies = 1.0;
  for (const ScenarioEvent& e : s.events) topologies += e.kind == EventKind::kTopology;
  const double n = static_cast<double>(s.followers);
  if (topologies * n * n > kMaxTimelineCells) {
    r.Fail(tables[0].line, "event",
           "the timeline holds too many topologies for its size: " +
               FormatNumber(topologies) + " topologies of " + FormatNumber(n) +
               " followers make " + FormatNumber(topologies * n * n) +
               " matrix entries, more than 5e7",
           std::nullopt, "use fewer topology events, or fewer followers");
  }
  double checks = segments * static_cast<double>(s.events.size());
  for (const ScenarioEvent& e : s.events) {
    // The segments of its window: those starting in [at_s, end).
    const auto first = std::lower_bound(times.begin(), times.end(), TimelineMicros(e.at_s));
    const auto last = std::lower_bound(first, times.end(), TimelineMicros(e.end_s()));
    double cost = static_cast<double>(e.vehicles.size());
    if (e.kind == EventKind::kLinkDown || e.kind == EventKind::kChannel) {
      cost = e.links.empty() ? links : static_cast<double>(e.links.size());
    }
    checks += static_cast<double>(last - first) * cost;
  }
  if (checks > kMaxTimelineChecks) {
    r.Fail(tables[0].line, "event",
           "the timeline is too costly to build: the links and vehicles its events mark in "
           "every segment of their windows (" +
               FormatNumber(links) + " links for an event without a list) make " +
               FormatNumber(checks) + " checks, more than 1e9",
           std::nullopt,
           "use fewer or shorter events, or list fewer links in them");
  }
}

void ReadEvents(const Reader& r, const Table& root, Scenario* s) {
  const std::vector<Table> tables = r.ArrayOfTables(root, "event");
  if (tables.size() > kMaxEvents) {
    r.Fail(tables[kMaxEvents].line, tables[kMaxEvents].key,
           "more than " + std::to_string(kMaxEvents) + " events", std::nullopt,
           "a timeline holds at most " + std::to_string(kMaxEvents) + " [[event]] tables");
  }
  for (const Table& t : tables) {
    ScenarioEvent e = ReadEvent(r, t, s->followers);
    if (!s->events.empty() && e.at_s < s->events.back().at_s) {
      r.FailAt(
          *t.Get("at_s"), t.KeyOf("at_s"),
          "is earlier than the previous event's at_s = " + FormatNumber(s->events.back().at_s) +
              " (line " + std::to_string(s->events.back().line) + ")",
          "list the [[event]] tables in the order of their at_s");
    }
    s->events.push_back(std::move(e));
  }
  CheckEventLinks(r, tables, *s);
  CheckEventTopologies(r, tables, *s);
  CheckChannelOverlaps(r, tables, *s);
  CheckTopologyAndResetOverlaps(r, tables, *s);
  CheckResetsHoldATick(r, tables, *s);
  CheckTimelineSize(r, tables, *s);
}

void ReadScenario(const Reader& r, const toml::table& root, Scenario* s) {
  const Table top{&root, "", "the top level", 1};
  r.CheckKeys(top, kTopKeys);
  const auto child = [&](std::string_view key) {
    return r.Child(top, key, "write [" + std::string(key) + "] as a table header");
  };
  const Table run = child("run");
  ReadRun(r, run, s);
  ReadSwarm(r, child("swarm"), s);
  ReadControl(r, child("control"), s);
  ReadLeader(r, child("leader"), &s->leader);
  ReadChannel(r, child("channel"), s);
  ReadDisturbance(r, child("disturbance"), &s->disturbance);
  ReadVehicle(r, child("vehicle"), s, run.Get("control_rate_hz"));
  ReadMetrics(r, child("metrics"), &s->metrics);
  ReadFollowers(r, top, s);
  ReadEvents(r, top, s);
}

std::string FileLabel(const std::string& path) { return path.empty() ? "<scenario>" : path; }

/// The TOML tree of scenario text, within the key depth limit; throws a located
/// ScenarioError on a syntax error.
toml::table ParseToml(const std::string& text, const std::string& file) {
  if (const int line = LineOfTooDeepKey(text)) {
    throw ScenarioError(file + ":" + std::to_string(line) +
                        ": TOML syntax error: a key or table nests more than " +
                        std::to_string(kMaxKeyDepth) + " tables deep");
  }
  try {
    return toml::parse(std::string_view(text), std::string_view(file));
  } catch (const toml::parse_error& e) {
    const toml::source_position& where = e.source().begin;
    throw ScenarioError(file + ":" + std::to_string(std::max(1, static_cast<int>(where.line))) +
                        ": TOML syntax error: " + std::string(e.description()) + " (column " +
                        std::to_string(where.column) + ")");
  }
}

/// Validates the tree of `path`; `text` is kept as the scenario's source text.
Scenario ReadTree(const toml::table& root, const std::string& text, const std::string& path) {
  Scenario s;
  s.source_path = path;
  s.source_text = text;
  s.name = std::filesystem::path(path).stem().string();
  if (s.name.empty()) s.name = "scenario";  // a file name holds no '/': never a path
  // Trace files are relative to the scenario file's directory; text that does not come
  // from a file (a log's copy, named by a label) resolves them in the working directory.
  std::error_code error;
  const bool is_file = !path.empty() && std::filesystem::is_regular_file(path, error);
  const std::string base = is_file ? std::filesystem::path(path).parent_path().string() : "";
  ReadScenario(Reader(FileLabel(path), base), root, &s);
  return s;
}

/// A comment line's text: newlines in a value would end the comment.
std::string OneLine(const std::string& text) {
  std::string line;
  for (const char c : text) line += c == '\n' ? std::string("\\n") : std::string(1, c);
  return line;
}

/// The merged tree as a TOML document, headed by comments naming the base file and each
/// override, so that a log of the run shows (and reproduces) what ran.
std::string EffectiveText(const toml::table& root, const std::string& path,
                          const std::vector<ScenarioOverride>& overrides) {
  std::ostringstream text;
  text << "# Effective scenario: " << OneLine(FileLabel(path))
       << " with these changes, in order:\n";
  for (const ScenarioOverride& o : overrides) {
    const std::string set = "--set " + o.key + "=" + o.value;
    text << "#   " << OneLine(set);
    if (o.origin != set) text << "   (" << OneLine(o.origin) << ")";
    text << "\n";
  }
  text << "\n" << toml::toml_formatter(root) << "\n";
  return text.str();
}

/// Whether `message` is located at an override ("<origin>: ...").
bool NamesAnOverride(const std::string& message, const std::vector<ScenarioOverride>& overrides) {
  return std::any_of(overrides.begin(), overrides.end(), [&](const ScenarioOverride& o) {
    return message.compare(0, o.origin.size() + 1, o.origin + ":") == 0;
  });
}

/// The error of the overridden scenario, saying that the overrides changed it unless the
/// message names one of them or the file alone fails the same way.
ScenarioError ChangedScenarioError(const ScenarioError& e, const std::string& text,
                                   const std::string& path,
                                   const std::vector<ScenarioOverride>& overrides) {
  const std::string message = e.what();
  if (NamesAnOverride(message, overrides)) return e;
  try {
    ParseScenario(text, path);
  } catch (const ScenarioError& base) {
    if (message == base.what()) return e;
  }
  std::string origins;
  for (const ScenarioOverride& o : overrides) origins += (origins.empty() ? "" : ", ") + o.origin;
  return ScenarioError(message + " (scenario changed by " + origins + ")");
}

}  // namespace

Scenario LoadScenario(const std::string& path) {
  return ParseScenario(ReadLimitedFile(path, "scenario file"), path);
}

Scenario LoadScenario(const std::string& path, const std::vector<ScenarioOverride>& overrides) {
  return ParseScenario(ReadLimitedFile(path, "scenario file"), path, overrides);
}

Scenario ParseScenario(const std::string& text, const std::string& path) {
  return ReadTree(ParseToml(text, FileLabel(path)), text, path);
}

std::string ApplyOverridesToText(const std::string& text, const std::string& path,
                                 const std::vector<ScenarioOverride>& overrides) {
  if (overrides.empty()) return text;
  toml::table root = ParseToml(text, FileLabel(path));
  ApplyOverrides(overrides, &root);
  return EffectiveText(root, path, overrides);
}

Scenario ParseScenario(const std::string& text, const std::string& path,
                       const std::vector<ScenarioOverride>& overrides) {
  if (overrides.empty()) return ParseScenario(text, path);
  toml::table root = ParseToml(text, FileLabel(path));
  ApplyOverrides(overrides, &root);
  const std::string effective = EffectiveText(root, path, overrides);
  try {
    // The merged tree is validated first, so that messages locate each value in the file
    // or at its override; the scenario is then read from the effective text itself, so
    // that it equals what a log of the run (which keeps that text) reads back, lines of
    // events included.
    ReadTree(root, effective, path);
    return ParseScenario(effective, path);
  } catch (const ScenarioError& e) {
    throw ChangedScenarioError(e, text, path, overrides);
  }
}

struct ScenarioTemplate::Tree {
  toml::table root;
};

ScenarioTemplate::ScenarioTemplate(std::string text, std::string path)
    : tree_(std::make_unique<Tree>()), text_(std::move(text)), path_(std::move(path)) {
  tree_->root = ParseToml(text_, FileLabel(path_));
}

ScenarioTemplate::~ScenarioTemplate() = default;

Scenario ScenarioTemplate::Read(const std::vector<ScenarioOverride>& overrides) const {
  try {
    toml::table root = tree_->root;
    ApplyOverrides(overrides, &root);
    return ReadTree(root, std::string(), path_);
  } catch (const ScenarioError&) {
    // A refused set of overrides pays for the whole parse, whose message names the file's
    // line or the override exactly as ParseScenario's does.
    Scenario s = ParseScenario(text_, path_, overrides);
    s.source_text.clear();
    return s;
  }
}

bool LoadScenarioOrReport(const std::string& who, const std::string& path, Scenario* out) {
  return LoadScenarioOrReport(who, path, std::vector<ScenarioOverride>(), out);
}

bool LoadScenarioOrReport(const std::string& who, const std::string& path,
                          const std::vector<ScenarioOverride>& overrides, Scenario* out) {
  try {
    *out = LoadScenario(path, overrides);
    return true;
  } catch (const ScenarioError& e) {
    std::cerr << who << ": " << e.what() << "\n";
    return false;
  }
}

bool LoadScenarioWithSetsOrReport(const std::string& who, const std::string& path,
                                  const std::vector<std::string>& set_flags, Scenario* out) {
  std::vector<ScenarioOverride> overrides;
  try {
    overrides = ParseSetFlags(set_flags);
  } catch (const ScenarioError& e) {
    std::cerr << who << ": " << e.what() << "\n";
    return false;
  }
  return LoadScenarioOrReport(who, path, overrides, out);
}

}  // namespace shoal
