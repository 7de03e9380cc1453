// Clocks and fixed-rate loops for the real-time mode. Nothing in core/ reads a clock.
#pragma once

#include <time.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <memory>
#include <new>
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

/// The geometric bins of health2_t's lateness_window_bins: bin 0 below 1 us, bin i in
/// 1..kOctaves * kPerOctave holds [2^((i-1)/8), 2^(i/8)) us, the last bin what is beyond.
/// 9 % wide: a quantile between 1 us and 1.049 s read from them is within 9 % above the
/// exact one, whatever the window's length, at 162 counts a report (below 1 us it reads
/// as up to 1 us; beyond 1.049 s, as the largest sample).
struct LatenessBins {
  static constexpr int kPerOctave = 8;
  static constexpr int kOctaves = 20;  // up to 2^20 us = 1.049 s
  static constexpr int kCount = kPerOctave * kOctaves + 2;

  static int Index(double late_s) {
    const double us = late_s * 1e6;
    if (!(us >= 1.0)) return 0;  // NaN too: never out of range
    const double i = std::floor(std::log2(us) * kPerOctave) + 1.0;
    return i >= kCount - 1 ? kCount - 1 : static_cast<int>(i);
  }
  /// The upper edge of bin i in seconds (infinity for the last bin).
  static double UpperS(int i) {
    if (i >= kCount - 1) return std::numeric_limits<double>::infinity();
    return std::exp2(static_cast<double>(i) / kPerOctave) * 1e-6;
  }
  /// Quantile q in [0, 1] of `count` samples in `bins` (kCount sums) whose maximum is
  /// `max_s`: the upper edge of the bin holding the sample of rank q (count - 1), nearest,
  /// capped by the maximum; 0 if no samples. As LatenessStats::Quantile.
  template <typename Count>
  static double Quantile(const Count* bins, std::int64_t count, double max_s, double q) {
    if (count <= 0) return 0.0;
    const auto rank = static_cast<std::int64_t>(q * static_cast<double>(count - 1) + 0.5);
    std::int64_t seen = 0;
    for (int i = 0; i < kCount; ++i) {
      seen += bins[i];
      if (seen > rank) return std::min(max_s, UpperS(i));
    }
    return max_s;
  }
};

/// Lateness samples since the last Take(): what a health report says of its own second.
class LatenessWindow {
 public:
  void Add(double late_s) {
    std::int32_t& n = bins_[static_cast<std::size_t>(LatenessBins::Index(late_s))];
    if (n < std::numeric_limits<std::int32_t>::max()) ++n;  // the count itself stays exact
    ++count_;
    max_ = std::max(max_, late_s);
  }
  const std::array<std::int32_t, LatenessBins::kCount>& bins() const { return bins_; }
  std::int64_t count() const { return count_; }
  double max() const { return max_; }
  /// This window, and a new empty one begins.
  LatenessWindow Take() {
    LatenessWindow w = *this;
    *this = LatenessWindow();
    return w;
  }

 private:
  std::array<std::int32_t, LatenessBins::kCount> bins_{};
  std::int64_t count_ = 0;
  double max_ = 0.0;
};

/// Lateness statistics over a run, in a fixed histogram: Add() is O(1) and never
/// allocates, and a quantile costs O(bins) whatever the run length, so reporting from
/// inside a real-time loop stays cheap. Resolution 2 us up to 200 ms; later samples fall
/// in an overflow bin (reported as the exact maximum). The 800 kB of bins come from calloc,
/// which takes fresh zero pages from the kernel for a block this large instead of writing
/// zeros: a process pays only for the pages its samples reach (none in lockstep, which has
/// no lateness), not 200 page faults and a memset at its start. Under mlockall (real time)
/// the pages are made at once, before the loop.
class LatenessStats {
 public:
  LatenessStats()
      : bins_(static_cast<std::int64_t*>(std::calloc(kBins + 1, sizeof(std::int64_t)))) {
    if (bins_ == nullptr) throw std::bad_alloc();
  }
  LatenessStats(const LatenessStats& o) : LatenessStats() { *this = o; }
  LatenessStats& operator=(const LatenessStats& o) {
    if (this != &o) {
      std::copy(o.bins_.get(), o.bins_.get() + kBins + 1, bins_.get());
      count_ = o.count_;
      max_ = o.max_;
      window_ = o.window_;
    }
    return *this;
  }

  void Add(double late_s) {
    const double b = late_s / kBinS;
    const std::size_t i =
        b <= 0.0 ? 0 : (b >= kBins ? kBins : static_cast<std::size_t>(b));
    ++bins_[i];
    ++count_;
    max_ = std::max(max_, late_s);
    window_.Add(late_s);
  }
  /// The samples since the previous call (or the start), for a health report.
  LatenessWindow TakeWindow() { return window_.Take(); }
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
  struct Free {
    void operator()(std::int64_t* p) const { std::free(p); }
  };
  std::unique_ptr<std::int64_t[], Free> bins_;
  std::int64_t count_ = 0;
  double max_ = 0.0;
  LatenessWindow window_;
};

}  // namespace shoal
