// Numbers in shoal design's messages and report: one format, so that the verdict, the
// advice and the report print a value the same way.
#pragma once

#include <cstdio>
#include <string>

namespace shoal {
namespace design {

/// printf-style formatting of one number (`f` holds one double conversion).
inline std::string Fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), f, v);
  return buf;
}

/// Four significant digits, as every figure of the report is quoted.
inline std::string G4(double v) { return Fmt("%.4g", v); }

}  // namespace design
}  // namespace shoal
