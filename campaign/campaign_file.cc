// Campaign file loading and validation (docs/campaigns.md). Unknown keys are errors at
// every level, with the closest valid key suggested.
#include "campaign/campaign_file.h"

#include <toml++/toml.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <string_view>
#include <system_error>

#include "scenario/regular_file.h"
#include "scenario/toml_depth.h"

namespace shoal {
namespace {

constexpr std::array<std::string_view, 5> kTopKeys = {"campaign", "axis", "pass", "map", "soak"};
constexpr std::array<std::string_view, 9> kCampaignKeys = {
    "scenario", "engine", "duration_s", "timeout_s", "workers", "sampling", "samples", "seed",
    "set"};
constexpr std::array<std::string_view, 7> kAxisKeys = {"key", "values", "from", "to",
                                                          "steps", "log", "range"};
constexpr std::array<std::string_view, 2> kBoundKeys = {"min", "max"};
constexpr std::array<std::string_view, 2> kMapKeys = {"x", "y"};
constexpr std::array<std::string_view, 6> kSoakKeys = {
    "phase_s",           "settle_s",          "lateness_p99_max_s", "delay_error_p99_max_s",
    "memory_growth_max", "overruns_max"};
constexpr std::size_t kMaxShownChars = 80;
constexpr double kMaxSeconds = 1e9;
// An axis value is a scenario value: a few numbers, a table of a model. A longer text is
// a mistake (a pasted file), and every point's command line carries it.
constexpr std::size_t kMaxValueChars = 4096;

int LineOf(const toml::node& node) {
  return std::max(1, static_cast<int>(node.source().begin.line));
}

int EditDistance(std::string_view a, std::string_view b) {
  std::vector<int> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = static_cast<int>(j);
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = static_cast<int>(i);
    for (std::size_t j = 1; j <= b.size(); ++j) {
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] != b[j - 1])});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

void AppendTomlString(std::string_view s, std::string* out) {
  *out += '"';
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      *out += '\\';
      *out += c;
    } else if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) {
      char escaped[8];
      std::snprintf(escaped, sizeof(escaped), "\\u%04x", static_cast<unsigned>(c));
      *out += escaped;
    } else {
      *out += c;
    }
  }
  *out += '"';
}

/// A key as TOML writes it: bare when it can be, quoted otherwise.
void AppendTomlKey(std::string_view key, std::string* out) {
  const bool bare = !key.empty() && std::all_of(key.begin(), key.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-';
  });
  if (bare) {
    *out += key;
  } else {
    AppendTomlString(key, out);
  }
}

/// The complete TOML text of a value (inline form); false for dates and times, which no
/// scenario key takes.
bool AppendTomlValue(const toml::node& node, std::string* out) {
  if (const auto* v = node.as_string()) {
    AppendTomlString(v->get(), out);
  } else if (const auto* v = node.as_integer()) {
    *out += std::to_string(v->get());
  } else if (const auto* v = node.as_floating_point()) {
    *out += TomlFloatText(v->get());
  } else if (const auto* v = node.as_boolean()) {
    *out += v->get() ? "true" : "false";
  } else if (const auto* array = node.as_array()) {
    *out += '[';
    for (std::size_t i = 0; i < array->size(); ++i) {
      if (i > 0) *out += ", ";
      if (!AppendTomlValue(*array->get(i), out)) return false;
    }
    *out += ']';
  } else if (const auto* table = node.as_table()) {
    *out += '{';
    bool first = true;
    for (auto&& [key, value] : *table) {
      *out += first ? " " : ", ";
      first = false;
      AppendTomlKey(key.str(), out);
      *out += " = ";
      if (!AppendTomlValue(value, out)) return false;
    }
    *out += first ? "}" : " }";
  } else {
    return false;
  }
  return true;
}

nlohmann::json ToJson(const toml::node& node) {
  if (const auto* v = node.as_string()) return v->get();
  if (const auto* v = node.as_integer()) return v->get();
  if (const auto* v = node.as_floating_point()) return v->get();
  if (const auto* v = node.as_boolean()) return v->get();
  if (const auto* array = node.as_array()) {
    nlohmann::json out = nlohmann::json::array();
    for (std::size_t i = 0; i < array->size(); ++i) out.push_back(ToJson(*array->get(i)));
    return out;
  }
  nlohmann::json out = nlohmann::json::object();
  if (const auto* table = node.as_table()) {
    for (auto&& [key, value] : *table) out[std::string(key.str())] = ToJson(value);
  }
  return out;
}

std::string Show(const toml::node& node) {
  std::string out;
  if (!AppendTomlValue(node, &out)) {
    std::ostringstream text;
    if (const auto* v = node.as_date()) text << v->get();
    if (const auto* v = node.as_time()) text << v->get();
    if (const auto* v = node.as_date_time()) text << v->get();
    out = text.str();
  }
  if (out.size() > kMaxShownChars) out = out.substr(0, kMaxShownChars - 3) + "...";
  return out;
}

/// The entries of a table in the order they were written (toml++ keeps them sorted).
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

/// Reads checked values; every failure throws a located CampaignError.
class Reader {
 public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void Fail(int line, const std::string& key, const std::string& what,
                         const std::string& got, const std::string& fix) const {
    std::string message = file_ + ":" + std::to_string(line) + ": ";
    if (!key.empty()) message += key + ": ";
    message += what;
    if (!got.empty()) message += " (got " + got + ")";
    if (!fix.empty()) message += "; " + fix;
    throw CampaignError(message);
  }
  [[noreturn]] void FailAt(const toml::node& node, const std::string& key, const std::string& what,
                           const std::string& fix) const {
    Fail(LineOf(node), key, what, Show(node), fix);
  }

  template <std::size_t N>
  void CheckKeys(const toml::table& t, const std::string& prefix, const std::string& label,
                 const std::array<std::string_view, N>& allowed) const {
    for (const auto& [key, value] : InFileOrder(t)) {
      const std::string_view name = key->str();
      if (std::find(allowed.begin(), allowed.end(), name) != allowed.end()) continue;
      std::string fix;
      int best = 3;
      for (const std::string_view candidate : allowed) {
        const std::size_t diff = std::max(name.size(), candidate.size()) -
                                 std::min(name.size(), candidate.size());
        if (diff > 2) continue;
        const int d = EditDistance(name, candidate);
        if (d < best) best = d, fix = "did you mean '" + std::string(candidate) + "'?";
      }
      if (fix.empty()) {
        fix = "valid keys in " + label + ":";
        for (const std::string_view candidate : allowed) fix += " " + std::string(candidate);
      }
      const std::string shown = Show(toml::value<std::string>(std::string(name)));
      Fail(std::max(1, static_cast<int>(key->source().begin.line)),
           prefix.empty() ? std::string(name) : prefix + "." + std::string(name),
           "unknown key " + shown + " in " + label, "", fix);
    }
  }

  double Number(const toml::node& node, const std::string& key, double lo, double hi,
                const std::string& rule, const std::string& fix) const {
    double v = 0;
    if (const auto* i = node.as_integer()) {
      v = static_cast<double>(i->get());
    } else if (const auto* f = node.as_floating_point()) {
      v = f->get();
    } else {
      FailAt(node, key, "must be a number", fix);
    }
    if (!std::isfinite(v) || v < lo || v > hi) FailAt(node, key, rule, fix);
    return v;
  }
  std::int64_t Integer(const toml::node& node, const std::string& key, std::int64_t lo,
                       std::int64_t hi, const std::string& rule, const std::string& fix) const {
    const auto* i = node.as_integer();
    if (i == nullptr) FailAt(node, key, "must be an integer", fix);
    if (i->get() < lo || i->get() > hi) FailAt(node, key, rule, fix);
    return i->get();
  }
  std::string String(const toml::node& node, const std::string& key, const std::string& fix) const {
    const auto* s = node.as_string();
    if (s == nullptr) FailAt(node, key, "must be a string", fix);
    return s->get();
  }
  const std::string& file() const { return file_; }

 private:
  std::string file_;
};

std::string ReadCampaignText(const std::string& path) {
  std::string error;
  const int fd = OpenRegularFile(path, "campaign file", kMaxCampaignBytes, &error);
  if (fd < 0) throw CampaignError(error);
  std::string text;
  char buffer[1 << 16];
  for (;;) {
    const ssize_t count = read(fd, buffer, sizeof(buffer));
    if (count < 0 && errno == EINTR) continue;
    if (count <= 0) {
      const int e = errno;
      close(fd);
      if (count < 0) {
        throw CampaignError(path + ": cannot read campaign file (" +
                            std::error_code(e, std::generic_category()).message() + ")");
      }
      return text;
    }
    text.append(buffer, static_cast<std::size_t>(count));
    if (text.size() > kMaxCampaignBytes) {
      close(fd);
      throw CampaignError(path + ": cannot read campaign file: it grew beyond " +
                          std::to_string(kMaxCampaignBytes) + " bytes while being read");
    }
  }
}

/// One of `names` for the string at `key`, with a suggestion when it is close to one.
template <std::size_t N>
int Choice(const Reader& r, const toml::node& node, const std::string& key,
           const std::array<std::string_view, N>& names) {
  std::string choices = "use one of";
  for (std::size_t i = 0; i < N; ++i) choices += std::string(i ? ", \"" : " \"") + std::string(names[i]) + "\"";
  const std::string value = r.String(node, key, choices);
  for (std::size_t i = 0; i < N; ++i) {
    if (names[i] == value) return static_cast<int>(i);
  }
  for (const std::string_view name : names) {
    if (EditDistance(value, name) <= 2) choices += "; did you mean \"" + std::string(name) + "\"?";
  }
  r.FailAt(node, key, "unknown value", choices);
}

void ReadSetList(const Reader& r, const toml::node& node, Campaign* c) {
  const std::string fix = "set lists overrides as --set takes them, e.g. set = [\"control.k1=0.3\"]";
  const toml::array* array = node.as_array();
  if (array == nullptr) r.FailAt(node, "campaign.set", "must be an array of strings", fix);
  for (std::size_t i = 0; i < array->size(); ++i) {
    const toml::node& item = *array->get(i);
    const std::string key = "campaign.set[" + std::to_string(i) + "]";
    const std::string text = r.String(item, key, fix);
    const std::size_t eq = text.find('=');
    if (eq == std::string::npos || eq == 0) r.FailAt(item, key, "must be KEY=VALUE", fix);
    c->set.push_back({text, LineOf(item)});
  }
}

void ReadCampaignTable(const Reader& r, const toml::table& root, Campaign* c) {
  const toml::node* node = root.get("campaign");
  if (node == nullptr || !node->is_table()) {
    r.Fail(node ? LineOf(*node) : 1, "campaign", node ? "must be a table" : "missing [campaign]",
           "", "start the file with [campaign] and scenario = \"<scenario file>\"");
  }
  const toml::table& t = *node->as_table();
  r.CheckKeys(t, "campaign", "[campaign]", kCampaignKeys);
  const toml::node* scenario = t.get("scenario");
  if (scenario == nullptr) {
    r.Fail(LineOf(t), "campaign.scenario", "missing required key", "",
           "add scenario = \"<scenario file>\" (relative to the campaign file)");
  }
  c->scenario = r.String(*scenario, "campaign.scenario", "the base scenario's path");
  c->scenario_line = LineOf(*scenario);
  if (c->scenario.empty()) r.FailAt(*scenario, "campaign.scenario", "must not be empty", "");
  const std::filesystem::path dir = std::filesystem::path(c->path).parent_path();
  if (std::filesystem::path(c->scenario).is_relative() && !dir.empty()) {
    c->scenario = (dir / c->scenario).lexically_normal().string();
  }
  if (const toml::node* n = t.get("engine")) {
    constexpr std::array<std::string_view, 3> kEngines = {"sim", "lockstep", "realtime"};
    c->engine = static_cast<CampaignEngine>(Choice(r, *n, "campaign.engine", kEngines));
  }
  const std::string seconds = "must be a positive number of seconds, at most 1e9";
  if (const toml::node* n = t.get("duration_s")) {
    c->duration_s = r.Number(*n, "campaign.duration_s", 0, kMaxSeconds, seconds, "e.g. 600");
    if (c->duration_s <= 0) r.FailAt(*n, "campaign.duration_s", seconds, "e.g. 600");
  }
  if (const toml::node* n = t.get("timeout_s")) {
    c->timeout_s = r.Number(*n, "campaign.timeout_s", 0, kMaxSeconds, seconds, "e.g. 300");
    if (c->timeout_s <= 0) r.FailAt(*n, "campaign.timeout_s", seconds, "e.g. 300");
  }
  if (const toml::node* n = t.get("workers")) {
    c->workers = static_cast<int>(
        r.Integer(*n, "campaign.workers", 1, 1024, "must be an integer in 1..1024", "e.g. 2"));
  }
  if (const toml::node* n = t.get("sampling")) {
    constexpr std::array<std::string_view, 2> kSamplings = {"grid", "lhs"};
    c->sampling = static_cast<CampaignSampling>(Choice(r, *n, "campaign.sampling", kSamplings));
  }
  const toml::node* samples = t.get("samples");
  if (c->sampling == CampaignSampling::kLhs && samples == nullptr) {
    r.Fail(LineOf(t), "campaign.samples", "missing required key with sampling = \"lhs\"", "",
           "add samples = <number of points>");
  }
  if (samples != nullptr) {
    if (c->sampling != CampaignSampling::kLhs) {
      r.FailAt(*samples, "campaign.samples", "only used with sampling = \"lhs\"",
               "remove it, or set sampling = \"lhs\"");
    }
    c->samples = r.Integer(*samples, "campaign.samples", 1, kMaxPoints,
                           "must be an integer in 1..1000000", "e.g. samples = 100");
  }
  if (const toml::node* n = t.get("seed")) {
    // A grid draws nothing: a seed there would be taken for one that changes the runs (a
    // scenario's own seed is run.seed, set with set = [...] or an axis).
    if (c->sampling != CampaignSampling::kLhs) {
      r.FailAt(*n, "campaign.seed", "only used with sampling = \"lhs\"",
               "remove it (the runs' own seed is run.seed: set = [\"run.seed=7\"])");
    }
    c->seed = static_cast<std::uint64_t>(r.Integer(
        *n, "campaign.seed", 0, INT64_MAX, "must be an integer >= 0", "e.g. seed = 1"));
  }
  if (const toml::node* n = t.get("set")) ReadSetList(r, *n, c);
}

/// values = [...] of an axis.
void ReadAxisValues(const Reader& r, const toml::node& node, const std::string& key,
                    CampaignAxis* axis) {
  const std::string fix = "values lists the axis' values, e.g. values = [0.1, 0.2]";
  const toml::array* array = node.as_array();
  if (array == nullptr || array->empty()) r.FailAt(node, key, "must be a non-empty array", fix);
  if (array->size() > static_cast<std::size_t>(kMaxPoints)) {
    r.Fail(LineOf(node), key, "has more than 1000000 values", "", "sweep fewer values");
  }
  for (std::size_t i = 0; i < array->size(); ++i) {
    const toml::node& item = *array->get(i);
    std::string text;
    const std::string item_key = key + "[" + std::to_string(i) + "]";
    if (!AppendTomlValue(item, &text)) {
      r.FailAt(item, item_key, "must be a number, string, boolean, array or table", fix);
    }
    if (text.size() > kMaxValueChars) {
      r.Fail(LineOf(item), item_key, "is longer than 4096 characters", "", "use a shorter value");
    }
    axis->values.push_back(text);
    axis->json_values.push_back(ToJson(item));
  }
}

void ReadAxisFromTo(const Reader& r, const toml::table& t, const std::string& key,
                    CampaignSampling sampling, CampaignAxis* axis) {
  const std::string fix = "from = a, to = b, steps = n: n values from a to b inclusive";
  for (const char* name : {"from", "to"}) {
    if (t.get(name) == nullptr) {
      r.Fail(LineOf(t), key + "." + name, "missing (from and to go together)", "", fix);
    }
  }
  constexpr double kMaxMagnitude = 1e300;
  const std::string rule = "must be a finite number";
  axis->from = r.Number(*t.get("from"), key + ".from", -kMaxMagnitude, kMaxMagnitude, rule, fix);
  axis->to = r.Number(*t.get("to"), key + ".to", -kMaxMagnitude, kMaxMagnitude, rule, fix);
  if (const toml::node* n = t.get("log")) {
    if (!n->is_boolean()) r.FailAt(*n, key + ".log", "must be true or false", fix);
    axis->log = n->as_boolean()->get();
    if (axis->log && (axis->from <= 0 || axis->to <= 0)) {
      r.FailAt(*n, key + ".log", "needs from and to both positive", "or set log = false");
    }
  }
  const toml::node* steps = t.get("steps");
  if (steps == nullptr && sampling == CampaignSampling::kGrid) {
    r.Fail(LineOf(t), key + ".steps", "missing (a grid needs the number of values)", "", fix);
  }
  if (steps != nullptr && sampling == CampaignSampling::kLhs) {
    r.FailAt(*steps, key + ".steps", "only used with sampling = \"grid\"",
             "remove it: lhs draws its samples from [from, to]");
  }
  if (steps != nullptr) {
    axis->steps = r.Integer(*steps, key + ".steps", 1, kMaxPoints,
                            "must be an integer in 1..1000000", fix);
    if (axis->steps == 1 && axis->from != axis->to) {
      r.FailAt(*steps, key + ".steps", "must be at least 2 when from != to", fix);
    }
  }
  axis->kind = CampaignAxis::Kind::kFromTo;
}

void ReadAxisRange(const Reader& r, const toml::node& node, const std::string& key,
                   CampaignAxis* axis) {
  const std::string fix = "range = [a, b] takes the integers a..b inclusive, e.g. range = [1, 50]";
  const toml::array* array = node.as_array();
  if (array == nullptr || array->size() != 2) r.FailAt(node, key, "must be [first, last]", fix);
  const std::int64_t limit = INT64_MAX / 4;
  axis->range_lo = r.Integer(*array->get(0), key + "[0]", -limit, limit, "is too large", fix);
  axis->range_hi = r.Integer(*array->get(1), key + "[1]", -limit, limit, "is too large", fix);
  if (axis->range_hi < axis->range_lo) r.FailAt(node, key, "must have first <= last", fix);
  if (axis->range_hi - axis->range_lo >= kMaxPoints) {
    r.FailAt(node, key, "spans more than 1000000 values", "sweep a shorter range");
  }
  axis->kind = CampaignAxis::Kind::kRange;
}

CampaignAxis ReadAxis(const Reader& r, const toml::table& t, std::size_t index,
                      CampaignSampling sampling) {
  const std::string label = "axis[" + std::to_string(index) + "]";
  r.CheckKeys(t, label, "[[axis]]", kAxisKeys);
  CampaignAxis axis;
  axis.line = LineOf(t);
  const toml::node* key = t.get("key");
  if (key == nullptr) {
    r.Fail(axis.line, label + ".key", "missing required key", "",
           "add key = \"<scenario key>\", e.g. key = \"channel.delay.base_s\"");
  }
  axis.key = r.String(*key, label + ".key", "the dotted scenario key the axis sets");
  if (axis.key.empty() || axis.key.size() > 200 || axis.key.find('=') != std::string::npos) {
    r.FailAt(*key, label + ".key", "must be a dotted scenario key",
             "e.g. key = \"channel.delay.base_s\"");
  }
  const int kinds = (t.get("values") != nullptr) + (t.get("from") || t.get("to")) +
                    (t.get("range") != nullptr);
  if (kinds != 1) {
    r.Fail(axis.line, label, kinds == 0 ? "has no values" : "has more than one kind of values",
           "", "give exactly one of values = [...], from/to/steps, range = [a, b]");
  }
  if (const toml::node* values = t.get("values")) {
    ReadAxisValues(r, *values, label + ".values", &axis);
  } else if (const toml::node* range = t.get("range")) {
    ReadAxisRange(r, *range, label + ".range", &axis);
  } else {
    ReadAxisFromTo(r, t, label, sampling, &axis);
  }
  if (axis.kind != CampaignAxis::Kind::kFromTo) {
    for (const char* name : {"steps", "log"}) {
      if (const toml::node* n = t.get(name)) {
        r.FailAt(*n, label + "." + name, "only used with from/to", "remove it");
      }
    }
  }
  return axis;
}

void ReadAxes(const Reader& r, const toml::table& root, Campaign* c) {
  const toml::node* node = root.get("axis");
  if (node == nullptr) return;
  const toml::array* array = node->as_array();
  if (array == nullptr || !array->is_array_of_tables()) {
    r.FailAt(*node, "axis", "must be an array of tables", "write each axis as its own [[axis]]");
  }
  if (array->size() > kMaxAxes) {
    r.Fail(LineOf(*array->get(kMaxAxes)), "axis", "more than 16 axes", "", "sweep fewer keys");
  }
  for (std::size_t i = 0; i < array->size(); ++i) {
    CampaignAxis axis = ReadAxis(r, *array->get(i)->as_table(), i, c->sampling);
    for (const CampaignAxis& other : c->axes) {
      if (other.key == axis.key) {
        r.Fail(axis.line, "axis[" + std::to_string(i) + "].key", "the key of another axis",
               axis.key, "merge the two axes' values into one");
      }
    }
    c->axes.push_back(std::move(axis));
  }
}

constexpr std::size_t kMaxCriteria = 1000;

void ReadCriterion(const Reader& r, const std::string& key, const toml::node& value,
                   Campaign* c) {
  const std::string fix = "a criterion is a value (converged = true) or bounds "
                          "({ min = a }, { max = b } or both)";
  CampaignCriterion criterion;
  criterion.key = key;
  criterion.line = LineOf(value);
  if (const toml::table* bounds = value.as_table()) {
    r.CheckKeys(*bounds, "pass." + key, "a bound", kBoundKeys);
    if (bounds->empty()) r.FailAt(value, "pass." + key, "has neither min nor max", fix);
    const double big = 1e300;
    if (const toml::node* n = bounds->get("min")) {
      criterion.min = r.Number(*n, "pass." + key + ".min", -big, big, "must be a finite number", fix);
    }
    if (const toml::node* n = bounds->get("max")) {
      criterion.max = r.Number(*n, "pass." + key + ".max", -big, big, "must be a finite number", fix);
    }
    if (criterion.min && criterion.max && *criterion.min > *criterion.max) {
      r.FailAt(value, "pass." + key, "min is above max", "swap them");
    }
  } else if (value.is_boolean() || value.is_string() || value.is_integer() ||
             value.is_floating_point()) {
    criterion.equals = ToJson(value);
    if (value.is_floating_point() && !std::isfinite(value.as_floating_point()->get())) {
      r.FailAt(value, "pass." + key, "must be a finite number", fix);
    }
  } else {
    r.FailAt(value, "pass." + key, "must be a boolean, string, number or bounds", fix);
  }
  if (c->pass.size() >= kMaxCriteria) {
    r.FailAt(value, "pass." + key, "more than 1000 criteria", "judge fewer metrics");
  }
  c->pass.push_back(std::move(criterion));
}

/// [pass]: keys are dotted metric names, quoted ("channel.delay_error_p99_s") or written
/// as TOML dotted keys / sub-tables, which this walks down.
void ReadPassTable(const Reader& r, const toml::table& t, const std::string& prefix,
                   Campaign* c) {
  for (const auto& [key, value] : InFileOrder(t)) {
    const std::string dotted = prefix.empty() ? std::string(key->str())
                                              : prefix + "." + std::string(key->str());
    const toml::table* sub = value->as_table();
    if (sub != nullptr && !sub->is_inline()) {
      ReadPassTable(r, *sub, dotted, c);
    } else {
      ReadCriterion(r, dotted, *value, c);
    }
  }
}

std::string AxisKeyFix(const Campaign& c, const std::string& name) {
  std::string fix = "name one of the axes' keys:";
  for (const CampaignAxis& axis : c.axes) {
    if (EditDistance(axis.key, name) <= 2) return "did you mean \"" + axis.key + "\"?";
    fix += " " + axis.key;
  }
  return fix;
}

void ReadMapAndSoak(const Reader& r, const toml::table& root, Campaign* c) {
  if (const toml::node* node = root.get("map")) {
    if (!node->is_table()) r.FailAt(*node, "map", "must be a table", "[map] x = ..., y = ...");
    const toml::table& t = *node->as_table();
    r.CheckKeys(t, "map", "[map]", kMapKeys);
    for (const char* name : {"x", "y"}) {
      const toml::node* n = t.get(name);
      if (n == nullptr) continue;
      const std::string key = std::string("map.") + name;
      const std::string value = r.String(*n, key, AxisKeyFix(*c, ""));
      const bool found = std::any_of(c->axes.begin(), c->axes.end(),
                                     [&](const CampaignAxis& a) { return a.key == value; });
      if (!found) r.FailAt(*n, key, "not the key of an axis", AxisKeyFix(*c, value));
      (name[0] == 'x' ? c->map_x : c->map_y) = value;
    }
    if (!c->map_x.empty() && c->map_x == c->map_y) {
      r.FailAt(*node, "map", "x and y are the same axis", "choose two different axes");
    }
  }
  if (const toml::node* node = root.get("soak")) {
    if (!node->is_table()) r.FailAt(*node, "soak", "must be a table", "[soak] phase_s = ...");
    const toml::table& t = *node->as_table();
    r.CheckKeys(t, "soak", "[soak]", kSoakKeys);
    CampaignSoak& s = c->soak;
    s.present = true;
    const std::string positive = "must be a positive number, at most 1e9";
    const std::array<std::pair<const char*, double*>, 5> fields = {{
        {"phase_s", &s.phase_s},
        {"settle_s", &s.settle_s},
        {"lateness_p99_max_s", &s.lateness_p99_max_s},
        {"delay_error_p99_max_s", &s.delay_error_p99_max_s},
        {"memory_growth_max", &s.memory_growth_max},
    }};
    for (const auto& [name, out] : fields) {
      if (const toml::node* n = t.get(name)) {
        *out = r.Number(*n, std::string("soak.") + name, 0, kMaxSeconds, positive, "");
        if (*out <= 0 && std::string(name) != "settle_s") {
          r.FailAt(*n, std::string("soak.") + name, positive, "");
        }
      }
    }
    if (const toml::node* n = t.get("overruns_max")) {
      s.overruns_max = r.Integer(*n, "soak.overruns_max", 0, 1000000000,
                                 "must be an integer in 0..1e9 (control ticks per phase)",
                                 "e.g. 0");
    }
    if (s.settle_s >= s.phase_s) {
      r.Fail(LineOf(t), "soak.settle_s", "must be shorter than phase_s", "", "");
    }
    // Targets a lockstep run has no figure for: silently ignored, they would read as met.
    if (c->engine != CampaignEngine::kRealtime) {
      for (const char* name : {"lateness_p99_max_s", "delay_error_p99_max_s", "overruns_max"}) {
        if (const toml::node* n = t.get(name)) {
          r.FailAt(*n, std::string("soak.") + name, "a real-time target (engine = \"realtime\")",
                   "remove it, or set engine = \"realtime\"");
        }
      }
    }
  }
}

void CheckPointCount(const Reader& r, const Campaign& c) {
  if (c.sampling != CampaignSampling::kGrid) return;
  std::int64_t count = 1;
  for (const CampaignAxis& axis : c.axes) {
    count *= axis.GridCount();
    if (count > kMaxPoints) {
      r.Fail(axis.line, "axis " + axis.key, "the grid has more than 1000000 points", "",
             "sweep fewer values, or sample with sampling = \"lhs\"");
    }
  }
}

}  // namespace

const char* EngineName(CampaignEngine engine) {
  switch (engine) {
    case CampaignEngine::kSim: return "sim";
    case CampaignEngine::kLockstep: return "lockstep";
    case CampaignEngine::kRealtime: return "realtime";
  }
  return "sim";
}

std::int64_t CampaignAxis::GridCount() const {
  switch (kind) {
    case Kind::kValues: return static_cast<std::int64_t>(values.size());
    case Kind::kFromTo: return steps;
    case Kind::kRange: return range_hi - range_lo + 1;
  }
  return 0;
}

std::string TomlFloatText(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buffer[40];
  // Start with the integer part's digits, so that %g writes 1000.0, not 1e+03.
  int first = 1;
  if (std::abs(v) >= 1.0 && std::abs(v) < 1e17) {
    first = static_cast<int>(std::floor(std::log10(std::abs(v)))) + 1;
  }
  for (int precision = first; precision <= 17; ++precision) {
    std::snprintf(buffer, sizeof(buffer), "%.*g", precision, v);
    if (std::strtod(buffer, nullptr) == v) break;
  }
  std::string text = buffer;
  // %g may drop the point ("2", "1e+20"): TOML needs a fraction or an exponent for a float.
  if (text.find_first_of(".e") == std::string::npos) text += ".0";
  return text;
}

std::int64_t PointCount(const Campaign& c) {
  if (c.sampling == CampaignSampling::kLhs) return c.samples;
  std::int64_t count = 1;
  for (const CampaignAxis& axis : c.axes) count *= axis.GridCount();
  return count;
}

Campaign ParseCampaign(const std::string& text, const std::string& path) {
  const std::string file = path.empty() ? "<campaign>" : path;
  if (text.size() > kMaxCampaignBytes) {
    throw CampaignError(file + ": campaign file larger than " +
                        std::to_string(kMaxCampaignBytes) + " bytes");
  }
  // toml++ would recurse once per component of a deeper key and overflow the stack.
  if (const int line = LineOfTooDeepKey(text)) {
    throw CampaignError(file + ":" + std::to_string(line) +
                        ": TOML syntax error: a key or table nests more than " +
                        std::to_string(kMaxKeyDepth) + " tables deep");
  }
  toml::table root;
  try {
    root = toml::parse(std::string_view(text), std::string_view(file));
  } catch (const toml::parse_error& e) {
    const toml::source_position& where = e.source().begin;
    throw CampaignError(file + ":" + std::to_string(std::max(1, static_cast<int>(where.line))) +
                        ": TOML syntax error: " + std::string(e.description()) + " (column " +
                        std::to_string(where.column) + ")");
  }
  const Reader r(file);
  r.CheckKeys(root, "", "a campaign file", kTopKeys);
  Campaign c;
  c.path = path;
  c.text = text;
  ReadCampaignTable(r, root, &c);
  ReadAxes(r, root, &c);
  CheckPointCount(r, c);
  if (const toml::node* node = root.get("pass")) {
    if (!node->is_table()) r.FailAt(*node, "pass", "must be a table", "[pass] converged = true");
    ReadPassTable(r, *node->as_table(), "", &c);
  }
  ReadMapAndSoak(r, root, &c);
  return c;
}

Campaign LoadCampaign(const std::string& path) {
  return ParseCampaign(ReadCampaignText(path), path);
}

}  // namespace shoal
