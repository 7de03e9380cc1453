// Tick values and tick labels for linear and log axes (pure functions, no rendering).
#pragma once

#include <string>
#include <vector>

namespace shoal::render {

/// The smallest step s = m * 10^k with m in {1, 2, 5} such that `span` is covered by at
/// most `max_intervals` steps (span / s <= max_intervals). span > 0, max_intervals >= 1;
/// otherwise 0.
double NiceStep(double span, int max_intervals);

struct TickSet {
  std::vector<double> major;  // labelled ticks (data units), ascending
  std::vector<double> minor;  // unlabelled ticks (log axes only), ascending
  double step = 0.0;          // linear: spacing of the major ticks; log: 0
  bool decades = false;       // log: majors are powers of ten
};

/// Multiples of the smallest 1-2-5 step with at most max_ticks multiples inside [lo, hi]
/// (ends included within a relative 1e-9 of the step); at least one when max_ticks >= 3.
/// Values within 1e-9 step of zero are exactly 0. lo < hi and max_ticks >= 2, otherwise
/// empty.
TickSet LinearTicks(double lo, double hi, int max_ticks);

/// Ticks of a base-10 log axis on [lo, hi] (0 < lo < hi), at most max_ticks majors:
///  - at least two powers of ten inside: majors at 10^k, every m-th decade (k a multiple
///    of m, m in 1, 2, 3, 5, 10, 20, 30, 50, ...) when there are more than max_ticks;
///    minors at 2..9 x 10^k (m = 1) or at the skipped decades (m > 1, at most 60 decades);
///  - otherwise majors at 1, 2, 5 x 10^k inside the range (minors at the other n x 10^k),
///  - and if fewer than two of those fit, linear ticks on [lo, hi].
TickSet LogTicks(double lo, double hi, int max_ticks);

/// Linear tick label: as many decimals as `step` needs (0.05 -> 2), a typographic minus
/// (U+2212), "0" for zero.
std::string FormatLinearTick(double value, double step);

/// Log tick label: a power of ten as 10ⁿ with superscript digits ("10⁻³", "10⁰"), other
/// values as FormatLinearTick with the value's own precision when
/// 1e-4 <= value < 1e5 ("0.002", "500"), else m×10ⁿ ("2×10⁻⁵").
std::string FormatLogTick(double value);

/// A tick value in plain decimals with its own precision when 1e-4 <= |value| < 1e5
/// ("0.002", "20", "0.25"), else m×10ⁿ; used for log axes with 1-2-5 ticks, so that all
/// labels of an axis look alike.
std::string FormatPlainTick(double value);

/// For linear ticks with very large or very small values: the power of ten n to factor
/// out (labels show value / 10^n, the axis shows "×10ⁿ"), or 0 when plain labels are
/// short enough (largest |tick| < 1e5 and step >= 1e-4).
int CommonExponent(const TickSet& ticks);

/// "×10ⁿ" with superscript digits.
std::string ExponentLabel(int n);

/// n with Unicode superscript digits and minus ("⁻¹²").
std::string Superscript(int n);

}  // namespace shoal::render
