#include "render/ticks.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace shoal::render {
namespace {

// floor(log10(v)) for v > 0, robust against log10(1000) = 2.9999999.
int FloorLog10(double v) {
  int k = static_cast<int>(std::floor(std::log10(v)));
  if (std::pow(10.0, k + 1) <= v * (1.0 + 1e-12)) ++k;
  if (std::pow(10.0, k) > v * (1.0 + 1e-12)) --k;
  return k;
}

std::string ReplaceMinus(std::string s) {
  if (!s.empty() && s[0] == '-') s.replace(0, 1, "\xE2\x88\x92");  // U+2212
  return s;
}

std::string Fixed(double value, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", std::clamp(decimals, 0, 20), value);
  return buf;
}

}  // namespace

double NiceStep(double span, int max_intervals) {
  if (!(span > 0.0) || !std::isfinite(span) || max_intervals < 1) return 0.0;
  const double raw = span / max_intervals;
  const int k = FloorLog10(raw);
  const double mag = std::pow(10.0, k);
  const double norm = raw / mag;  // in [1, 10)
  const double tol = 1e-9;
  double m = 10.0;
  if (norm <= 1.0 + tol) {
    m = 1.0;
  } else if (norm <= 2.0 + tol) {
    m = 2.0;
  } else if (norm <= 5.0 + tol) {
    m = 5.0;
  }
  return m * mag;
}

TickSet LinearTicks(double lo, double hi, int max_ticks) {
  TickSet t;
  if (!(lo < hi) || !std::isfinite(lo) || !std::isfinite(hi) || max_ticks < 2) return t;
  const auto count = [&](double s) {
    return std::floor(hi / s + 1e-9) - std::ceil(lo / s - 1e-9) + 1.0;
  };
  double step = NiceStep(hi - lo, max_ticks - 1);
  if (step <= 0.0) return t;
  // The span rule can be one step too coarse (0..3600 fits 8 ticks of 500, not only 4 of
  // 1000): take smaller 1-2-5 steps while the ticks inside still number at most max_ticks.
  for (;;) {
    const double m = step / std::pow(10.0, std::floor(std::log10(step) + 1e-9));
    const double smaller = m < 1.5 ? 0.5 * step : m < 3.0 ? 0.5 * step : 0.4 * step;
    if (count(smaller) > max_ticks) break;
    step = smaller;
  }
  t.step = step;
  const double first = std::ceil(lo / step - 1e-9);
  const double last = std::floor(hi / step + 1e-9);
  for (double k = first; k <= last; k += 1.0) {
    double v = k * step;
    if (std::fabs(v) < 1e-9 * step) v = 0.0;
    t.major.push_back(v);
  }
  return t;
}

TickSet LogTicks(double lo, double hi, int max_ticks) {
  TickSet t;
  if (!(lo > 0.0) || !(lo < hi) || !std::isfinite(hi) || max_ticks < 2) return t;
  const double lk = std::log10(lo), hk = std::log10(hi);
  const int kmin = static_cast<int>(std::ceil(lk - 1e-9));
  const int kmax = static_cast<int>(std::floor(hk + 1e-9));
  const int decades = kmax - kmin + 1;
  const auto inside = [&](double v) { return v >= lo * (1 - 1e-9) && v <= hi * (1 + 1e-9); };

  // Narrow ranges (at most two powers of ten inside): 1-2-5 majors if they fit.
  if (decades <= 2) {
    std::vector<double> majors, minors;
    for (int k = FloorLog10(lo); k <= FloorLog10(hi); ++k) {
      for (int j = 1; j <= 9; ++j) {
        const double v = j * std::pow(10.0, k);
        if (!inside(v)) continue;
        (j == 1 || j == 2 || j == 5 ? majors : minors).push_back(v);
      }
    }
    if (majors.size() >= 2 && static_cast<int>(majors.size()) <= max_ticks) {
      t.major = majors;
      t.minor = minors;
      return t;
    }
    if (decades < 2) return LinearTicks(lo, hi, max_ticks);
  }

  int m = 1;
  const auto count = [&](int step) {
    int n = 0;
    for (int k = kmin; k <= kmax; ++k) n += (((k % step) + step) % step == 0);
    return n;
  };
  // Every m-th decade, m from 1, 2, 3, 5, 10, 20, 30, 50, 100, ...
  for (int i = 0; count(m) > max_ticks; ++i) {
    static const int kSteps[4] = {1, 2, 3, 5};
    m = kSteps[(i + 1) % 4] * static_cast<int>(std::pow(10.0, (i + 1) / 4));
  }
  t.decades = true;
  for (int k = kmin; k <= kmax; ++k) {
    const double v = std::pow(10.0, k);
    if (((k % m) + m) % m == 0) {
      t.major.push_back(v);
    } else if (decades <= 60) {  // skipped decades as minor ticks, unless they would be a wash
      t.minor.push_back(v);
    }
  }
  if (m == 1) {
    for (int k = kmin - 1; k <= kmax; ++k) {
      for (int j = 2; j <= 9; ++j) {
        const double v = j * std::pow(10.0, k);
        if (inside(v)) t.minor.push_back(v);
      }
    }
  }
  std::sort(t.minor.begin(), t.minor.end());
  return t;
}

std::string FormatLinearTick(double value, double step) {
  if (!(step > 0.0)) step = std::fabs(value) > 0 ? std::fabs(value) : 1.0;
  if (std::fabs(value) < 1e-6 * step) return "0";
  const int decimals = std::max(0, -FloorLog10(step));
  std::string s = Fixed(value, decimals);
  return ReplaceMinus(s);
}

std::string Superscript(int n) {
  static const char* const kDigits[10] = {
      "\xE2\x81\xB0", "\xC2\xB9",     "\xC2\xB2",     "\xC2\xB3",     "\xE2\x81\xB4",
      "\xE2\x81\xB5", "\xE2\x81\xB6", "\xE2\x81\xB7", "\xE2\x81\xB8", "\xE2\x81\xB9"};
  std::string s;
  if (n < 0) s += "\xE2\x81\xBB";  // superscript minus U+207B
  const std::string digits = std::to_string(n < 0 ? -static_cast<long>(n) : n);
  for (char c : digits) s += kDigits[c - '0'];
  return s;
}

std::string ExponentLabel(int n) {
  return "\xC3\x97"
         "10" +
         Superscript(n);
}  // ×10ⁿ

std::string FormatLogTick(double value) {
  if (!(value > 0.0) || !std::isfinite(value)) return "";
  const int k = FloorLog10(value);
  const double mantissa = value / std::pow(10.0, k);
  if (std::fabs(mantissa - 1.0) < 1e-9) return "10" + Superscript(k);
  return FormatPlainTick(value);
}

std::string FormatPlainTick(double value) {
  if (!std::isfinite(value)) return "";
  if (value == 0.0) return "0";
  if (value < 0.0) return ReplaceMinus("-" + FormatPlainTick(-value));
  const int k = FloorLog10(value);
  const double mantissa = value / std::pow(10.0, k);
  // Significant digits of the mantissa (1 for 2, 5; up to 3).
  int sig = 1;
  while (sig < 3 && std::fabs(mantissa * std::pow(10.0, sig - 1) -
                              std::round(mantissa * std::pow(10.0, sig - 1))) > 1e-6) {
    ++sig;
  }
  if (value >= 1e-4 && value < 1e5) return Fixed(value, std::max(0, sig - 1 - k));
  return Fixed(mantissa, sig - 1) +
         "\xC3\x97"
         "10" +
         Superscript(k);
}

int CommonExponent(const TickSet& ticks) {
  double biggest = 0.0;
  for (double v : ticks.major) biggest = std::max(biggest, std::fabs(v));
  if (!(biggest > 0.0) || !(ticks.step > 0.0)) return 0;
  if (biggest < 1e5 && ticks.step >= 1e-4) return 0;
  const int k = FloorLog10(biggest);
  return 3 * static_cast<int>(std::floor(k / 3.0));
}

}  // namespace shoal::render
