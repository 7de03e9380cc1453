#include "core/history.h"

#include "core/control.h"

namespace shoal {

bool StateHistory::Push(const HistorySample& s) {
  HistorySample* d = Append(s.utime);
  if (d == nullptr) return false;
  *d = s;
  return true;
}

HistorySample* StateHistory::Append(Micros utime) {
  if (size_ > 0 && utime <= Newest().utime) return nullptr;
  if (size_ > 0 && run_ >= 2 && utime - Newest().utime == step_) {
    ++run_;
  } else if (size_ > 0) {
    step_ = utime - Newest().utime;
    run_ = 2;
  } else {
    run_ = 1;
  }
  HistorySample* d;
  if (size_ < capacity()) {
    d = &buf_[(head_ + size_) & mask_];
    ++size_;
  } else {
    d = &buf_[head_];
    head_ = (head_ + 1) & mask_;
  }
  if (run_ > size_) run_ = size_;
  d->utime = utime;
  return d;
}

int StateHistory::FirstAtOrAfter(Micros t) const {
  // Within the newest evenly spaced run, the j-th sample back from the newest is at
  // Newest - j step: the first at or after t is j = floor((Newest - t) / step) back, unless
  // t falls before the run's oldest sample (the sample before the run may be nearer).
  if (run_ >= 2) {
    const Micros back = Newest().utime - t;
    const Micros j = back / step_;
    if (j < run_ - 1 || (j == run_ - 1 && j * step_ == back)) {
      return size_ - 1 - static_cast<int>(j);
    }
  }
  // Most look-ups are a few samples back (a neighbour message's delay, the uncertain
  // factor's delay): scan back from the newest, without the division of the guess below.
  if (size_ > kRecentSamples && Get(size_ - kRecentSamples).utime < t) {
    int i = size_ - 1;
    while (Get(i - 1).utime >= t) --i;
    return i;
  }
  // Samples are usually evenly spaced: try the interpolated index first.
  const Micros span = Newest().utime - Oldest().utime;
  if (span > 0) {
    const int guess = static_cast<int>((t - Oldest().utime) * (size_ - 1) / span);
    if (Get(guess).utime == t) return guess;
  }
  // Binary search for the first sample with utime >= t.
  int lo = 0, hi = size_ - 1;
  while (lo < hi) {
    const int mid = (lo + hi) / 2;
    if (Get(mid).utime < t) {
      lo = mid + 1;
    } else {
      hi = mid;
    }
  }
  return lo;
}

bool StateHistory::At(Micros t, HistorySample* out) const {
  if (size_ == 0 || t < Oldest().utime || t > Newest().utime) return false;
  const int lo = FirstAtOrAfter(t);
  const HistorySample& b = Get(lo);
  if (b.utime == t) {
    *out = b;
    return true;
  }
  const HistorySample& a = Get(lo - 1);  // lo > 0 since t > Oldest().utime
  const double f = static_cast<double>(t - a.utime) / static_cast<double>(b.utime - a.utime);
  out->utime = t;
  // a.eta + f EtaDiff(b.eta, a.eta), the angles wrapped again, one component at a time
  // with the same operations, stored by Vec5Of (see there).
  // (Components as expressions, not a loop over an array: the array would be stored and
  // read back in pairs, the very load that stalls.)
  const auto lerp = [&](int k) { return a.eta(k) + f * (b.eta(k) - a.eta(k)); };
  const auto lerp_angle = [&](int k) {
    return WrapAngle(a.eta(k) + f * WrapAngle(b.eta(k) - a.eta(k)));
  };
  out->eta = Vec5Of(lerp(0), lerp(1), lerp(2), lerp_angle(3), lerp_angle(4));
  out->eta_dot = a.eta_dot + f * (b.eta_dot - a.eta_dot);
  return true;
}

}  // namespace shoal
