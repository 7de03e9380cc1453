#include "scenario/toml_depth.h"

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

// The TOML parser builds one nested table per component of a dotted key or table header,
// and both builds and frees them recursively: a header of 100000 components ([a.a.a...])
// overflows the stack (a crash, no message). It bounds nested arrays and inline tables at
// 256 levels but not key components, so those are counted here first, along the whole
// path a key lies on: its table header, the inline tables around it and its own dots.
// Override values (scenario/overrides.cc) are counted the same way.

namespace shoal {
namespace {

/// The index just past the string starting at text[i] (basic or literal, single- or
/// multi-line), counting the newlines it holds into *line.
std::size_t SkipString(std::string_view text, std::size_t i, int* line) {
  const char quote = text[i];
  const bool multi = text.compare(i, 3, std::string(3, quote)) == 0;
  std::size_t k = i + (multi ? 3 : 1);
  for (; k < text.size(); ++k) {
    const char c = text[k];
    if (c == '\n') {
      if (!multi) return k;  // unterminated: the parser says so
      ++*line;
    } else if (c == '\\' && quote == '"') {
      ++k;  // the escaped character (a newline after it is a line, counted next round)
      if (k < text.size() && text[k] == '\n') ++*line;
    } else if (c == quote && (!multi || text.compare(k, 3, std::string(3, quote)) == 0)) {
      return k + (multi ? 3 : 1);
    }
  }
  return k;
}

}  // namespace

/// Just exact enough for this count: strings, comments and brackets are followed, nothing
/// else is checked (the parser does that).
int LineOfTooDeepKey(std::string_view text) {
  int line = 1;
  int header = 0;           // depth of the current table header
  int base = 0;             // depth at which the key being read starts
  int dots = 0;             // dots in the key being read
  bool in_key = true;       // reading a key (or a header), not a value
  bool is_header = false;   // the statement is a table header
  bool line_start = true;   // nothing but blanks yet in this statement
  int depth = 0;            // of the value being read
  std::vector<std::pair<char, int>> open;  // value brackets and the depth inside each
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '"' || c == '\'') {
      i = SkipString(text, i, &line) - 1;
      line_start = false;
      continue;
    }
    if (c == '#') {
      while (i + 1 < text.size() && text[i + 1] != '\n') ++i;
      continue;
    }
    if (c == '\n') {
      ++line;
      if (!open.empty()) continue;
      if (is_header) header = dots + 1;
      base = header, dots = 0, in_key = true, is_header = false, line_start = true;
      continue;
    }
    if (c == ' ' || c == '\t' || c == '\r') continue;
    if (line_start && c == '[' && open.empty()) base = 0, is_header = true;
    line_start = false;
    if (in_key) {
      if (c == '.' && base + ++dots + 1 > kMaxKeyDepth) return line;
      if (c == '=' && !is_header) in_key = false, depth = base + dots + 1;
      if (c == '}' && !open.empty()) open.pop_back(), in_key = false;
      continue;
    }
    // Nested arrays and inline tables are bounded by the parser, with its own message;
    // here they only add to the depth of the keys inside them.
    if (c == '[' || c == '{') {
      open.emplace_back(c, ++depth);
      if (c == '{') base = depth, dots = 0, in_key = true;
    } else if ((c == ']' || c == '}') && !open.empty()) {
      open.pop_back();
      depth = open.empty() ? 0 : open.back().second;
    } else if (c == ',' && !open.empty() && open.back().first == '{') {
      base = open.back().second, dots = 0, in_key = true;
    }
  }
  return 0;
}

}  // namespace shoal
