// The campaign file of `shoal sweep` and `shoal soak` (docs/campaigns.md): which scenario,
// how each point runs, the axes of the points and the pass criteria. Loaded and validated
// completely before anything runs; every problem is a CampaignError located as the
// scenario loader's are: "<file>:<line>: <key>: <what> (got <value>); <fix>".
#pragma once

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace shoal {

class CampaignError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Limits against hostile or mistaken files: a campaign is a few kilobytes, and a point is
// a process run, so a million of them is already months of machine time.
inline constexpr std::size_t kMaxCampaignBytes = 1u << 20;
inline constexpr std::size_t kMaxAxes = 16;
inline constexpr std::int64_t kMaxPoints = 1000000;

enum class CampaignEngine { kSim, kLockstep, kRealtime };
enum class CampaignSampling { kGrid, kLhs };

const char* EngineName(CampaignEngine engine);

/// One [[axis]]: exactly one of values, from/to/steps, range.
struct CampaignAxis {
  enum class Kind { kValues, kFromTo, kRange };
  std::string key;  // dotted scenario key, as --set takes it
  int line = 1;     // its [[axis]] header, for messages about its values
  Kind kind = Kind::kValues;
  std::vector<std::string> values;       // kValues: TOML value text of each value
  std::vector<nlohmann::json> json_values;  // kValues: the same values as JSON
  double from = 0, to = 0;               // kFromTo
  std::int64_t steps = 0;                // kFromTo (grid)
  bool log = false;                      // kFromTo: log spacing / log-uniform sampling
  std::int64_t range_lo = 0, range_hi = 0;  // kRange, inclusive

  /// Number of grid values along this axis.
  std::int64_t GridCount() const;
};

/// One [pass] criterion on a dotted key of the run's JSON.
struct CampaignCriterion {
  std::string key;
  int line = 1;
  std::optional<nlohmann::json> equals;  // bool, string or number
  std::optional<double> min, max;
};

/// One entry of `set`: "key=value" text and its line.
struct CampaignSet {
  std::string text;
  int line = 1;
};

/// [soak] (shoal soak only; kept here so that one loader reads the file).
struct CampaignSoak {
  bool present = false;
  double phase_s = 600, settle_s = 300;
  double lateness_p99_max_s = 0.002, delay_error_p99_max_s = 0.001;
  double memory_growth_max = 0.01;
  long long overruns_max = 0;  // realtime: control ticks a phase may overrun
};

struct Campaign {
  std::string path;      // the campaign file, as given
  std::string text;      // its content
  std::string scenario;  // the base scenario's path, resolved against the file's directory
  int scenario_line = 1;
  CampaignEngine engine = CampaignEngine::kSim;
  double duration_s = -1;  // < 0: the scenario's
  double timeout_s = -1;   // < 0: the default (DefaultTimeout)
  int workers = 0;         // 0: the default (one per core; realtime: 1)
  CampaignSampling sampling = CampaignSampling::kGrid;
  std::int64_t samples = 0;  // lhs
  std::uint64_t seed = 1;    // lhs
  std::vector<CampaignSet> set;
  std::vector<CampaignAxis> axes;
  std::vector<CampaignCriterion> pass;
  std::string map_x, map_y;  // "" : the first two axes
  CampaignSoak soak;
};

/// Reads and validates `path`; throws CampaignError.
Campaign LoadCampaign(const std::string& path);
/// Validates campaign text; `path` names it in messages and is where relative paths start.
Campaign ParseCampaign(const std::string& text, const std::string& path);

/// The number of points the campaign makes (grid: product of the axes' counts; lhs:
/// samples). At most kMaxPoints for a validated campaign.
std::int64_t PointCount(const Campaign& c);

/// Shortest decimal text that reads back as exactly `v`, as a TOML float ("2.0", "0.1").
std::string TomlFloatText(double v);

}  // namespace shoal
