// Baseline for the real-time targets: how late does a bare fixed-rate loop wake on this
// machine? Sleeps to absolute CLOCK_MONOTONIC deadlines (as the SIL processes do) and
// prints lateness p50 / p99 / max and how many wake-ups missed a whole period.
//   Usage: build/bench/loop_jitter [RATE_HZ=50] [SECONDS=30]
#include <cstdio>
#include <cstdlib>

#include "runtime/clock.h"

int main(int argc, char** argv) {
  const double rate = argc > 1 ? std::atof(argv[1]) : 50.0;
  const double seconds = argc > 2 ? std::atof(argv[2]) : 30.0;
  const std::int64_t period = static_cast<std::int64_t>(1e9 / rate);
  const std::int64_t n = static_cast<std::int64_t>(seconds * rate);
  shoal::LatenessStats stats;
  std::int64_t missed = 0;
  const std::int64_t t0 = shoal::MonotonicNs() + period;
  for (std::int64_t k = 0; k < n; ++k) {
    const std::int64_t deadline = t0 + k * period;
    shoal::SleepUntilNs(deadline);
    const std::int64_t late = shoal::MonotonicNs() - deadline;
    stats.Add(static_cast<double>(late) * 1e-9);
    missed += late > period;
  }
  std::printf("%lld wake-ups at %.0f Hz: lateness p50 %.3f ms, p99 %.3f ms, max %.3f ms; "
              "%lld later than one period\n",
              static_cast<long long>(n), rate, stats.Quantile(0.5) * 1e3,
              stats.Quantile(0.99) * 1e3, stats.max() * 1e3, static_cast<long long>(missed));
  return 0;
}
