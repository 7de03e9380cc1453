#include "core/history.h"

#include "core/control.h"

namespace shoal {

bool StateHistory::Push(const HistorySample& s) {
  if (size_ > 0 && s.utime <= Newest().utime) return false;
  const int cap = capacity();
  if (size_ < cap) {
    buf_[(head_ + size_) & mask_] = s;
    ++size_;
  } else {
    buf_[head_] = s;
    head_ = (head_ + 1) & mask_;
  }
  return true;
}

int StateHistory::FirstAtOrAfter(Micros t) const {
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
  out->eta = a.eta + f * EtaDiff(b.eta, a.eta);
  out->eta(3) = WrapAngle(out->eta(3));
  out->eta(4) = WrapAngle(out->eta(4));
  out->eta_dot = a.eta_dot + f * (b.eta_dot - a.eta_dot);
  return true;
}

}  // namespace shoal
