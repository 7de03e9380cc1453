// Scenario overrides: "key=value" text to a change of the parsed TOML tree.
//
// A value is parsed by the TOML parser itself, as the document "v = <value>" named by the
// override's origin: its nodes then carry the origin as their source path, which the
// loader prints instead of "<file>:<line>" when one of them is wrong.
#include "scenario/overrides.h"

#include <algorithm>
#include <cctype>
#include <cstddef>
#include <cstdio>
#include <memory>
#include <string>
#include <utility>

#include "scenario/loader.h"
#include "scenario/override_tree.h"

namespace shoal {
namespace {

// A scenario is kilobytes; a value of a megabyte is a mistake (a file pasted whole),
// refused before the parser builds it.
constexpr std::size_t kMaxValueBytes = 1u << 20;
constexpr std::size_t kMaxKeyChars = 1000;
// Array indices of a scenario are follower and event numbers: far below this.
constexpr std::size_t kMaxIndex = 1000000;
// An origin quoting a long --set is shortened to this in messages.
constexpr std::size_t kMaxOriginChars = 120;

/// One component of a dotted key: a table key and the array indices after it
/// ("follower[2]" is {"follower", {2}}).
struct PathStep {
  std::string name;
  std::vector<std::size_t> indices;
};

[[noreturn]] void Fail(const std::string& origin, const std::string& what) {
  throw ScenarioError(origin + ": " + what);
}

bool IsBareKeyChar(char c) {
  return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_' || c == '-';
}

std::string Trim(const std::string& s) {
  const std::size_t begin = s.find_first_not_of(" \t");
  if (begin == std::string::npos) return "";
  return s.substr(begin, s.find_last_not_of(" \t") - begin + 1);
}

/// Reads a quoted component starting at key[*i] (a quote); no escapes ("a.b" keys only).
std::string ReadQuoted(const std::string& key, std::size_t* i, const std::string& origin) {
  const char quote = key[*i];
  const std::size_t end = key.find(quote, *i + 1);
  if (end == std::string::npos) Fail(origin, "key '" + key + "': unterminated quoted component");
  std::string name = key.substr(*i + 1, end - *i - 1);
  if (quote == '"' && name.find('\\') != std::string::npos) {
    Fail(origin, "key '" + key + "': escapes in quoted key components are not supported");
  }
  *i = end + 1;
  return name;
}

/// Reads the "[i][j]" after a component name starting at key[*i].
void ReadIndices(const std::string& key, std::size_t* i, const std::string& origin,
                 PathStep* step) {
  while (*i < key.size() && key[*i] == '[') {
    const std::size_t close = key.find(']', *i);
    const std::string digits =
        close == std::string::npos ? "" : key.substr(*i + 1, close - *i - 1);
    if (digits.empty() || digits.size() > 7 ||
        !std::all_of(digits.begin(), digits.end(),
                     [](char c) { return std::isdigit(static_cast<unsigned char>(c)) != 0; }) ||
        std::stoul(digits) > kMaxIndex) {
      Fail(origin, "key '" + key + "': an index is written [N] with N a whole number, as in " +
                       "follower[2].k1");
    }
    step->indices.push_back(std::stoul(digits));
    *i = close + 1;
  }
}

/// "channel.link[0].delay" to its steps; throws naming `origin` on a malformed key.
std::vector<PathStep> ParseKeyPath(const std::string& key, const std::string& origin) {
  if (key.empty()) Fail(origin, "empty key; write KEY=VALUE, as in channel.delay.base_s=0.3");
  if (key.size() > kMaxKeyChars) {
    Fail(origin, "key longer than " + std::to_string(kMaxKeyChars) + " characters");
  }
  std::vector<PathStep> steps;
  std::size_t i = 0;
  while (true) {
    PathStep step;
    if (i < key.size() && (key[i] == '"' || key[i] == '\'')) {
      step.name = ReadQuoted(key, &i, origin);
    } else {
      const std::size_t begin = i;
      while (i < key.size() && IsBareKeyChar(key[i])) ++i;
      step.name = key.substr(begin, i - begin);
      if (step.name.empty()) {
        Fail(origin, "key '" + key + "': expected a key name at character " +
                         std::to_string(i + 1) + " (names are letters, digits, _ and -)");
      }
    }
    ReadIndices(key, &i, origin, &step);
    steps.push_back(std::move(step));
    if (i == key.size()) break;
    if (key[i] != '.') {
      Fail(origin, "key '" + key + "': unexpected '" + std::string(1, key[i]) +
                       "' at character " + std::to_string(i + 1));
    }
    ++i;
  }
  std::size_t depth = 0;
  for (const PathStep& step : steps) depth += 1 + step.indices.size();
  if (depth > static_cast<std::size_t>(kMaxKeyDepth)) {
    Fail(origin, "key '" + key + "' nests more than " + std::to_string(kMaxKeyDepth) +
                     " tables deep");
  }
  return steps;
}

/// A word that is not a TOML value but reads as a string: constant, paper_helix, a-b.1.
bool IsBareWord(const std::string& value) {
  if (value.empty() || std::isalpha(static_cast<unsigned char>(value[0])) == 0) return false;
  if (value == "true" || value == "false" || value == "inf" || value == "nan") return false;
  return std::all_of(value.begin(), value.end(),
                     [](char c) { return IsBareKeyChar(c) || c == '.'; });
}

/// The document "v = <value>" named by the override's origin. `depth`: the tables the key
/// nests the value in, counted with the value's own for the depth limit.
toml::table ParseValue(const ScenarioOverride& o, std::size_t depth) {
  if (o.value.size() > kMaxValueBytes) {
    Fail(o.origin, "value longer than " + std::to_string(kMaxValueBytes) + " bytes");
  }
  const std::string text = "v = " + o.value + "\n";
  std::string probe;
  for (std::size_t k = 1; k < depth; ++k) probe += "a.";
  if (LineOfTooDeepKey(probe + text) != 0) {
    Fail(o.origin, "value nests tables more than " + std::to_string(kMaxKeyDepth) + " deep");
  }
  toml::table doc;
  try {
    doc = toml::parse(std::string_view(text), std::string_view(o.origin));
  } catch (const toml::parse_error& e) {
    if (!IsBareWord(o.value)) {
      Fail(o.origin, "not a TOML value: " + std::string(e.description()) +
                         "; write a number, true/false, a \"string\", an [array] or a { table }");
    }
    doc = toml::parse("v = \"\"", std::string_view(o.origin));
    *doc.get("v")->as_string() = o.value;
  }
  if (doc.size() != 1 || doc.get("v") == nullptr) {
    Fail(o.origin, "the value must be one TOML value, not several lines of keys");
  }
  return doc;
}

/// Where the walk down the key has got to, for messages: "channel.link[0]".
std::string Walked(const std::vector<PathStep>& steps, std::size_t step, std::size_t indices) {
  std::string text;
  for (std::size_t s = 0; s <= step; ++s) {
    text += (s > 0 ? "." : "") + steps[s].name;
    const std::size_t n = s < step ? steps[s].indices.size() : indices;
    for (std::size_t k = 0; k < n; ++k) text += "[" + std::to_string(steps[s].indices[k]) + "]";
  }
  return text;
}

/// The node of step `s` below `table` (through its indices), creating a missing table
/// when the step has no index; `key_source` locates the keys created.
toml::node* Descend(const ScenarioOverride& o, const std::vector<PathStep>& steps, std::size_t s,
                    const toml::source_region& key_source, toml::table* table) {
  const PathStep& step = steps[s];
  toml::node* node = table->get(step.name);
  if (node == nullptr) {
    if (!step.indices.empty()) {
      Fail(o.origin, Walked(steps, s, 0) + ": no such array in the scenario, so there is no " +
                         Walked(steps, s, 1) + " to change");
    }
    toml::table created = std::move(*toml::parse("t = {}", std::string_view(o.origin))
                                         .get_as<toml::table>("t"));
    created.is_inline(false);
    node = table->insert_or_assign(toml::key(step.name, key_source), std::move(created))
               .first->second.as_table();
  }
  for (std::size_t k = 0; k < step.indices.size(); ++k) {
    toml::array* array = node->as_array();
    if (array == nullptr) {
      Fail(o.origin, Walked(steps, s, k) + " is not an array, so there is no " +
                         Walked(steps, s, k + 1));
    }
    if (step.indices[k] >= array->size()) {
      Fail(o.origin, Walked(steps, s, k + 1) + ": index past the end (" + Walked(steps, s, k) +
                         " has " + std::to_string(array->size()) + " entries, numbered from 0)");
    }
    node = array->get(step.indices[k]);
  }
  return node;
}

void ApplyOne(const ScenarioOverride& o, toml::table* root) {
  const std::vector<PathStep> steps = ParseKeyPath(o.key, o.origin);
  std::size_t depth = 0;
  for (const PathStep& step : steps) depth += 1 + step.indices.size();
  toml::table doc = ParseValue(o, depth);
  const toml::source_region key_source = doc.begin()->first.source();
  toml::node& value = *doc.get("v");
  toml::table* table = root;
  for (std::size_t s = 0; s + 1 < steps.size(); ++s) {
    toml::node* node = Descend(o, steps, s, key_source, table);
    table = node->as_table();
    if (table == nullptr) {
      Fail(o.origin, Walked(steps, s, steps[s].indices.size()) + " is a " +
                         std::string(toml::impl::node_type_friendly_names[static_cast<int>(
                             node->type())]) +
                         ", not a table, so it has no key '" + steps[s + 1].name + "'");
    }
  }
  const PathStep& last = steps.back();
  if (last.indices.empty()) {
    table->insert_or_assign(toml::key(last.name, key_source), std::move(value));
    return;
  }
  // The element is replaced in the array that holds it: walk to it without its last index
  // (a missing array is refused first, not created as a table).
  if (table->get(last.name) == nullptr) Descend(o, steps, steps.size() - 1, key_source, table);
  std::vector<PathStep> to_array = steps;
  to_array.back().indices.pop_back();
  toml::node* holder = Descend(o, to_array, steps.size() - 1, key_source, table);
  toml::array* array = holder->as_array();
  const std::size_t index = last.indices.back();
  if (array == nullptr || index >= array->size()) {
    Descend(o, steps, steps.size() - 1, key_source, table);  // throws the located message
  }
  array->replace(array->cbegin() + static_cast<std::ptrdiff_t>(index), std::move(value));
}

}  // namespace

ScenarioOverride ParseSetFlag(const std::string& text) {
  std::string origin = "--set " + text;
  if (origin.size() > kMaxOriginChars) origin = origin.substr(0, kMaxOriginChars) + "...";
  const std::size_t equals = text.find('=');
  if (equals == std::string::npos) {
    Fail(origin, "expected KEY=VALUE, as in --set channel.delay.base_s=0.3");
  }
  ScenarioOverride o{Trim(text.substr(0, equals)), Trim(text.substr(equals + 1)), origin};
  if (o.key.empty()) Fail(origin, "empty key; write KEY=VALUE, as in --set run.seed=7");
  if (o.value.empty()) {
    Fail(origin, "empty value; write KEY=VALUE, as in --set run.seed=7 (a string: KEY='\"\"')");
  }
  ParseKeyPath(o.key, o.origin);  // a malformed key is refused before any file is read
  return o;
}

std::vector<ScenarioOverride> ParseSetFlags(const std::vector<std::string>& texts) {
  std::vector<ScenarioOverride> overrides;
  for (const std::string& text : texts) overrides.push_back(ParseSetFlag(text));
  return overrides;
}

void ApplyOverrides(const std::vector<ScenarioOverride>& overrides, toml::table* root) {
  for (const ScenarioOverride& o : overrides) ApplyOne(o, root);
}

std::string ExactNumber(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.17g", v);
  return text;
}

}  // namespace shoal
