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

/// Lateness statistics over a run: preallocated, no allocation per sample.
class LatenessStats {
 public:
  explicit LatenessStats(std::size_t capacity = 1 << 20) { samples_.reserve(capacity); }
  void Add(double late_s) {
    if (samples_.size() < samples_.capacity()) samples_.push_back(late_s);
    max_ = std::max(max_, late_s);
  }
  /// Quantile q in [0, 1] of the samples so far (0 if none). O(n), call at report rate.
  double Quantile(double q) {
    if (samples_.empty()) return 0.0;
    scratch_ = samples_;
    const std::size_t k = std::min(scratch_.size() - 1,
                                   static_cast<std::size_t>(q * (scratch_.size() - 1) + 0.5));
    std::nth_element(scratch_.begin(), scratch_.begin() + k, scratch_.end());
    return scratch_[k];
  }
  double max() const { return max_; }
  std::size_t count() const { return samples_.size(); }

 private:
  std::vector<double> samples_;
  std::vector<double> scratch_;
  double max_ = 0.0;
};

}  // namespace shoal
