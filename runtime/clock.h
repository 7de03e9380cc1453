// Clocks and fixed-rate loops for the real-time mode. Nothing in core/ reads a clock.
#pragma once

#include <time.h>

#include <algorithm>
#include <cstdint>
#include <vector>

namespace shoal {

/// CLOCK_MONOTONIC now, in nanoseconds.
inline std::int64_t MonotonicNs() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
}

/// Sleeps until an absolute CLOCK_MONOTONIC time (never drifts: deadlines are absolute).
/// Returns early only if interrupted by a signal.
inline void SleepUntilNs(std::int64_t deadline_ns) {
  timespec ts;
  ts.tv_sec = deadline_ns / 1000000000LL;
  ts.tv_nsec = deadline_ns % 1000000000LL;
  clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
}

/// Lateness statistics over a run, in a fixed histogram: Add() is O(1) and never
/// allocates, and a quantile costs O(bins) whatever the run length, so reporting from
/// inside a real-time loop stays cheap. Resolution 2 us up to 200 ms; later samples fall
/// in an overflow bin (reported as the exact maximum).
class LatenessStats {
 public:
  LatenessStats() : bins_(kBins + 1, 0) {}

  void Add(double late_s) {
    const double b = late_s / kBinS;
    const std::size_t i =
        b <= 0.0 ? 0 : (b >= kBins ? kBins : static_cast<std::size_t>(b));
    ++bins_[i];
    ++count_;
    max_ = std::max(max_, late_s);
  }
  /// Quantile q in [0, 1] (upper edge of its bin, at most the maximum); 0 if no samples.
  double Quantile(double q) const {
    if (count_ == 0) return 0.0;
    const auto rank = static_cast<std::int64_t>(q * static_cast<double>(count_ - 1) + 0.5);
    std::int64_t seen = 0;
    for (std::size_t i = 0; i < kBins; ++i) {
      seen += bins_[i];
      if (seen > rank) return std::min(max_, (static_cast<double>(i) + 1.0) * kBinS);
    }
    return max_;
  }
  double max() const { return max_; }
  std::int64_t count() const { return count_; }

 private:
  static constexpr std::size_t kBins = 100000;
  static constexpr double kBinS = 2e-6;
  std::vector<std::int64_t> bins_;
  std::int64_t count_ = 0;
  double max_ = 0.0;
};

}  // namespace shoal
