// Fixed-capacity history of a vehicle's own states, for protocol (10)'s own state at a
// neighbour message's send time and for delayed disturbance arguments.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/types.h"

namespace shoal {

struct HistorySample {
  Micros utime = 0;
  Vec5 eta = Vec5::Zero();
  Vec5 eta_dot = Vec5::Zero();
};

/// Ring buffer of samples with strictly increasing utime. Preallocated: Push() and At()
/// never allocate (safe inside a real-time tick).
class StateHistory {
 public:
  /// The most samples a history may hold (indices are int).
  static constexpr std::int64_t kMaxCapacity = std::int64_t{1} << 30;

  /// Holds at least `capacity` samples (rounded up to a power of two). Throws
  /// std::length_error above kMaxCapacity, std::bad_alloc if memory runs out.
  explicit StateHistory(std::int64_t capacity = 1) {
    if (capacity > kMaxCapacity) {
      throw std::length_error("a state history of " + std::to_string(capacity) +
                              " samples exceeds the limit of " + std::to_string(kMaxCapacity));
    }
    std::int64_t c = 1;
    while (c < capacity) c *= 2;
    buf_.resize(static_cast<std::size_t>(c));
    mask_ = static_cast<int>(c - 1);
  }

  int capacity() const { return static_cast<int>(buf_.size()); }
  int size() const { return size_; }
  bool empty() const { return size_ == 0; }

  /// Appends a sample; returns false (and ignores it) unless utime is newer than the last.
  bool Push(const HistorySample& s);

  /// Appends a sample at `utime` for the caller to fill in place (its eta and eta_dot as
  /// they were); null, and nothing appended, unless utime is newer than the last.
  HistorySample* Append(Micros utime);

  /// The state at utime t: the exact sample if one was pushed at t, otherwise linear
  /// interpolation between its neighbours (angles along the short arc). Returns false
  /// if t is outside [oldest, newest].
  bool At(Micros t, HistorySample* out) const;

  /// The sample pushed at exactly utime t, or null (no copy: valid until the next Push).
  const HistorySample* Exact(Micros t) const {
    if (size_ == 0 || t < Oldest().utime || t > Newest().utime) return nullptr;
    const HistorySample& s = Get(FirstAtOrAfter(t));
    return s.utime == t ? &s : nullptr;
  }

  /// Forgets every sample (the capacity stays).
  void Clear() {
    head_ = 0;
    size_ = 0;
    run_ = 0;
  }

  const HistorySample& Newest() const { return Get(size_ - 1); }
  const HistorySample& Oldest() const { return Get(0); }

 private:
  // How far back from the newest sample At() scans before it searches.
  static constexpr int kRecentSamples = 16;
  // Index of the oldest sample with utime >= t; Oldest().utime <= t <= Newest().utime.
  int FirstAtOrAfter(Micros t) const;

  // i-th oldest sample, 0 <= i < size_.
  const HistorySample& Get(int i) const { return buf_[(head_ + i) & mask_]; }

  std::vector<HistorySample> buf_;
  int mask_ = 0;
  int head_ = 0;  // index of the oldest sample
  int size_ = 0;
  // The newest run_ samples are evenly spaced, step_ apart (a vehicle pushes one sample per
  // control period): a look-up inside that run finds its index by one division.
  int run_ = 0;
  Micros step_ = 0;
};

}  // namespace shoal
