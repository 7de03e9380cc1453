// Property tests of core/history: exact recall of pushed samples, the time window,
// overflow, ordering, and linear interpolation (angles along the short arc), for evenly
// and unevenly spaced buffers.
#include "core/history.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <utility>
#include <vector>

#include "core/control.h"
#include "core/follower.h"
#include "core/swarm.h"
#include "core/rng.h"

namespace shoal {
namespace {

double U(Rng* rng, double lo, double hi) { return lo + (hi - lo) * rng->Uniform(); }

HistorySample RandomSample(Rng* rng, Micros utime) {
  HistorySample s;
  s.utime = utime;
  s.eta << U(rng, -100, 100), U(rng, -100, 100), U(rng, -20, 20), U(rng, -0.5, 0.5),
      U(rng, -kPi, kPi);
  for (int i = 0; i < 5; ++i) s.eta_dot(i) = U(rng, -2, 2);
  return s;
}

/// Bitwise equality of two samples (an exact sample must not pass through arithmetic).
bool BitwiseEqual(const HistorySample& a, const HistorySample& b) {
  return a.utime == b.utime && std::memcmp(a.eta.data(), b.eta.data(), sizeof(double) * 5) == 0 &&
         std::memcmp(a.eta_dot.data(), b.eta_dot.data(), sizeof(double) * 5) == 0;
}

/// Independent linear interpolation between a and b at t (angles along the short arc).
HistorySample Lerp(const HistorySample& a, const HistorySample& b, Micros t) {
  const double f = static_cast<double>(t - a.utime) / static_cast<double>(b.utime - a.utime);
  HistorySample out;
  out.utime = t;
  for (int i = 0; i < 5; ++i) {
    double d = b.eta(i) - a.eta(i);
    if (i >= 3) {
      while (d > kPi) d -= 2.0 * kPi;
      while (d <= -kPi) d += 2.0 * kPi;
    }
    double v = a.eta(i) + f * d;
    if (i >= 3) v = std::atan2(std::sin(v), std::cos(v));
    out.eta(i) = v;
    out.eta_dot(i) = a.eta_dot(i) + f * (b.eta_dot(i) - a.eta_dot(i));
  }
  return out;
}

void ExpectNear(const HistorySample& got, const HistorySample& want, double tol) {
  EXPECT_EQ(got.utime, want.utime);
  for (int i = 0; i < 5; ++i) {
    double de = got.eta(i) - want.eta(i);
    if (i >= 3) de = WrapAngle(de);  // pi and -pi are the same heading
    EXPECT_NEAR(de, 0.0, tol) << "eta(" << i << ") at t=" << want.utime;
    EXPECT_NEAR(got.eta_dot(i), want.eta_dot(i), tol) << "eta_dot(" << i << ") at t=" << want.utime;
  }
}

TEST(StateHistoryTest, EmptyHasNothing) {
  StateHistory h(4);
  HistorySample out;
  EXPECT_TRUE(h.empty());
  EXPECT_EQ(h.size(), 0);
  EXPECT_FALSE(h.At(0, &out));
  EXPECT_FALSE(h.At(1000, &out));
}

TEST(StateHistoryTest, HoldsAtLeastTheRequestedCapacity) {
  // "At least `capacity` samples": fill to capacity() and every sample is still there;
  // one more and exactly the oldest is gone.
  Rng rng(8);
  for (int requested : {-3, 0, 1, 2, 3, 5, 8, 100, 129, 1000}) {
    StateHistory h(requested);
    const int cap = h.capacity();
    ASSERT_GE(cap, std::max(requested, 1)) << requested;
    std::vector<HistorySample> pushed;
    for (int k = 0; k < cap; ++k) {
      pushed.push_back(RandomSample(&rng, 1000 * (k + 1)));
      ASSERT_TRUE(h.Push(pushed.back()));
    }
    ASSERT_EQ(h.size(), cap);
    HistorySample out;
    for (const HistorySample& s : pushed) {
      ASSERT_TRUE(h.At(s.utime, &out)) << requested;
      ASSERT_TRUE(BitwiseEqual(out, s));
    }
    ASSERT_TRUE(h.Push(RandomSample(&rng, 1000 * (cap + 1))));
    EXPECT_EQ(h.size(), cap);
    EXPECT_FALSE(h.At(pushed[0].utime, &out)) << requested;
    if (cap > 1) {
      EXPECT_TRUE(BitwiseEqual(h.Oldest(), pushed[1])) << requested;
    }
  }
}

TEST(StateHistoryTest, ReturnsExactPushedSamplesAndRejectsOutsideWindow) {
  Rng rng(1);
  StateHistory h(16);
  std::vector<HistorySample> pushed;
  Micros t = 1000;
  for (int k = 0; k < 10; ++k) {
    pushed.push_back(RandomSample(&rng, t));
    ASSERT_TRUE(h.Push(pushed.back()));
    t += 500 + static_cast<Micros>(rng.Uniform() * 30000);
  }
  EXPECT_EQ(h.size(), 10);
  EXPECT_TRUE(BitwiseEqual(h.Oldest(), pushed.front()));
  EXPECT_TRUE(BitwiseEqual(h.Newest(), pushed.back()));
  for (const HistorySample& s : pushed) {
    HistorySample out;
    ASSERT_TRUE(h.At(s.utime, &out)) << s.utime;
    EXPECT_TRUE(BitwiseEqual(out, s)) << s.utime;
  }
  HistorySample out;
  EXPECT_FALSE(h.At(pushed.front().utime - 1, &out));
  EXPECT_FALSE(h.At(pushed.back().utime + 1, &out));
  EXPECT_FALSE(h.At(-1000000, &out));
}

TEST(StateHistoryTest, PushRejectsNonIncreasingTime) {
  Rng rng(2);
  StateHistory h(8);
  const HistorySample a = RandomSample(&rng, 5000);
  ASSERT_TRUE(h.Push(a));
  HistorySample same_time = RandomSample(&rng, 5000);
  HistorySample older = RandomSample(&rng, 4999);
  EXPECT_FALSE(h.Push(same_time));
  EXPECT_FALSE(h.Push(older));
  EXPECT_EQ(h.size(), 1);
  EXPECT_TRUE(BitwiseEqual(h.Newest(), a));
  HistorySample out;
  ASSERT_TRUE(h.At(5000, &out));
  EXPECT_TRUE(BitwiseEqual(out, a));
  // And after a rejection, newer samples are still accepted.
  EXPECT_TRUE(h.Push(RandomSample(&rng, 5001)));
  EXPECT_EQ(h.size(), 2);
}

TEST(StateHistoryTest, AppendHandsOutTheNewestSampleToFillInPlace) {
  Rng rng(4);
  StateHistory h(4);
  const int cap = h.capacity();
  std::vector<HistorySample> want;
  for (int k = 0; k < cap + 3; ++k) {  // past the capacity: the slot of the oldest is reused
    const HistorySample s = RandomSample(&rng, 20000 * k);
    HistorySample* d = h.Append(s.utime);
    ASSERT_NE(d, nullptr) << k;
    EXPECT_EQ(d->utime, s.utime);
    d->eta = s.eta;
    d->eta_dot = s.eta_dot;
    want.push_back(s);
    EXPECT_EQ(d, &h.Newest()) << k;
    EXPECT_EQ(h.size(), std::min(k + 1, cap));
  }
  // Filled in place, the samples are what Push would have stored, look-ups included.
  StateHistory pushed(4);
  for (const HistorySample& s : want) ASSERT_TRUE(pushed.Push(s));
  HistorySample a, b;
  for (Micros t = want[3].utime; t <= want.back().utime; t += 5000) {
    ASSERT_EQ(h.At(t, &a), pushed.At(t, &b)) << t;
    EXPECT_TRUE(BitwiseEqual(a, b)) << t;
  }
  // Not newer than the newest: nothing appended, nothing changed.
  EXPECT_EQ(h.Append(want.back().utime), nullptr);
  EXPECT_EQ(h.Append(want.back().utime - 1), nullptr);
  EXPECT_EQ(h.size(), cap);
  EXPECT_TRUE(BitwiseEqual(h.Newest(), want.back()));
}

TEST(StateHistoryTest, OverflowDropsTheOldest) {
  Rng rng(3);
  StateHistory h(8);
  const int cap = h.capacity();
  ASSERT_GE(cap, 8);
  std::vector<HistorySample> pushed;
  for (int k = 0; k < 21; ++k) {
    pushed.push_back(RandomSample(&rng, 20000 * k));
    ASSERT_TRUE(h.Push(pushed.back()));
    ASSERT_EQ(h.size(), std::min(k + 1, cap));
    ASSERT_TRUE(BitwiseEqual(h.Oldest(), pushed[std::max(0, k + 1 - cap)]));
  }
  HistorySample out;
  for (int k = 0; k < 21; ++k) {
    const bool kept = k >= 21 - cap;
    ASSERT_EQ(h.At(pushed[k].utime, &out), kept) << k;
    if (kept) {
      EXPECT_TRUE(BitwiseEqual(out, pushed[k])) << k;
    }
  }
  // Between the newest dropped sample and the oldest kept one is outside the window.
  EXPECT_FALSE(h.At(pushed[21 - cap].utime - 10000, &out));
}

TEST(StateHistoryTest, InterpolatesLinearlyAlongTheShortArc) {
  StateHistory h(4);
  HistorySample a, b;
  a.utime = 0;
  a.eta << 0.0, 10.0, -4.0, 0.2, 3.0;
  a.eta_dot << 1.0, 0.0, 2.0, -1.0, 0.5;
  b.utime = 1000;
  b.eta << 4.0, 6.0, -4.0, 0.4, -3.0;  // heading crosses +-pi: 2 pi - 6 = 0.2832 rad apart
  b.eta_dot << 3.0, -2.0, 2.0, 1.0, 0.5;
  ASSERT_TRUE(h.Push(a));
  ASSERT_TRUE(h.Push(b));
  const double arc = 2.0 * kPi - 6.0;
  HistorySample out;
  ASSERT_TRUE(h.At(250, &out));
  EXPECT_EQ(out.utime, 250);
  EXPECT_NEAR(out.eta(0), 1.0, 1e-15);
  EXPECT_NEAR(out.eta(1), 9.0, 1e-15);
  EXPECT_NEAR(out.eta(2), -4.0, 1e-15);
  EXPECT_NEAR(out.eta(3), 0.25, 1e-15);
  EXPECT_NEAR(out.eta(4), 3.0 + 0.25 * arc, 1e-14);  // 3.0708, not 1.5 (the long way)
  EXPECT_NEAR(out.eta_dot(0), 1.5, 1e-15);
  EXPECT_NEAR(out.eta_dot(1), -0.5, 1e-15);
  EXPECT_NEAR(out.eta_dot(3), -0.5, 1e-15);
  // Past the crossing the heading is wrapped back into (-pi, pi].
  ASSERT_TRUE(h.At(750, &out));
  EXPECT_NEAR(out.eta(4), 3.0 + 0.75 * arc - 2.0 * kPi, 1e-14);  // -3.0708
  EXPECT_GT(out.eta(4), -kPi);
  EXPECT_LE(out.eta(4), kPi);
  // The other direction (from -3 to 3) too.
  StateHistory g(4);
  std::swap(a.eta, b.eta);
  ASSERT_TRUE(g.Push(a));
  ASSERT_TRUE(g.Push(b));
  ASSERT_TRUE(g.At(250, &out));
  EXPECT_NEAR(out.eta(4), -3.0 - 0.25 * arc, 1e-14);
}

TEST(StateHistoryTest, InterpolationHasTheBitsOfTheVectorForm) {
  // At() interpolates component by component (so that its stores can be forwarded); it must
  // give, to the bit, a.eta + f EtaDiff(b.eta, a.eta) with the angles wrapped again, and
  // a.eta_dot + f (b.eta_dot - a.eta_dot), also across +-pi.
  Rng rng(12);
  StateHistory h(64);
  std::vector<HistorySample> pushed;
  for (int k = 0; k < 40; ++k) {
    HistorySample s = RandomSample(&rng, 1000 + 20000 * k);
    s.eta(3) = U(&rng, -kPi, kPi);
    s.eta(4) = U(&rng, -kPi, kPi);
    ASSERT_TRUE(h.Push(s));
    pushed.push_back(s);
  }
  int across_pi = 0;
  for (int k = 0; k + 1 < static_cast<int>(pushed.size()); ++k) {
    const HistorySample& a = pushed[k];
    const HistorySample& b = pushed[k + 1];
    across_pi += std::abs(b.eta(4) - a.eta(4)) > kPi;
    for (Micros dt : {1, 777, 10000, 19999}) {
      const Micros t = a.utime + dt;
      const double f = static_cast<double>(t - a.utime) / static_cast<double>(b.utime - a.utime);
      Vec5 d = b.eta - a.eta;
      d(3) = WrapAngle(d(3));
      d(4) = WrapAngle(d(4));
      Vec5 want = a.eta + f * d;
      want(3) = WrapAngle(want(3));
      want(4) = WrapAngle(want(4));
      const Vec5 want_dot = a.eta_dot + f * (b.eta_dot - a.eta_dot);
      HistorySample got;
      ASSERT_TRUE(h.At(t, &got));
      EXPECT_EQ(got.utime, t);
      ASSERT_EQ(std::memcmp(got.eta.data(), want.data(), sizeof(double) * 5), 0)
          << "t " << t << ": " << got.eta.transpose() << " against " << want.transpose();
      ASSERT_EQ(std::memcmp(got.eta_dot.data(), want_dot.data(), sizeof(double) * 5), 0);
    }
  }
  EXPECT_GT(across_pi, 5);
}

TEST(StateHistoryTest, EvenlySpacedBufferAfterWrapAround) {
  // The fast path (interpolated index) on a full ring buffer whose head has moved.
  Rng rng(5);
  StateHistory h(100);
  const int cap = h.capacity();  // at least 100 (rounded up to a power of two)
  ASSERT_GE(cap, 100);
  std::vector<HistorySample> pushed;
  const Micros period = 20000;
  for (int k = 0; k < 237; ++k) {
    pushed.push_back(RandomSample(&rng, 1000000 + period * k));
    ASSERT_TRUE(h.Push(pushed.back()));
  }
  const int first = 237 - cap;
  HistorySample out;
  for (int k = first; k < 237; ++k) {
    ASSERT_TRUE(h.At(pushed[k].utime, &out)) << k;
    ASSERT_TRUE(BitwiseEqual(out, pushed[k])) << k;
  }
  for (int k = first; k + 1 < 237; ++k) {
    for (Micros dt : {Micros(1), Micros(7000), Micros(10000), period - 1}) {
      const Micros t = pushed[k].utime + dt;
      ASSERT_TRUE(h.At(t, &out)) << t;
      ExpectNear(out, Lerp(pushed[k], pushed[k + 1], t), 1e-12);
    }
  }
  EXPECT_FALSE(h.At(pushed[first].utime - 1, &out));
  EXPECT_FALSE(h.At(pushed.back().utime + 1, &out));
}

TEST(StateHistoryTest, UnevenlySpacedBufferAfterWrapAround) {
  // Irregular spacing (jittered ticks, a gap) defeats the index guess: the binary search
  // must find every sample and bracket every time in between.
  Rng rng(6);
  StateHistory h(64);
  const int cap = h.capacity();
  ASSERT_GE(cap, 64);
  std::vector<HistorySample> pushed;
  Micros t = 0;
  for (int k = 0; k < 150; ++k) {
    t += 1 + static_cast<Micros>(rng.Uniform() * 50000);
    if (k == 120) t += 2000000;  // a long gap inside the kept window
    pushed.push_back(RandomSample(&rng, t));
    ASSERT_TRUE(h.Push(pushed.back()));
  }
  const int first = 150 - cap;
  HistorySample out;
  for (int k = first; k < 150; ++k) {
    ASSERT_TRUE(h.At(pushed[k].utime, &out)) << k;
    ASSERT_TRUE(BitwiseEqual(out, pushed[k])) << k;
  }
  for (int n = 0; n < 5000; ++n) {
    const Micros lo = pushed[first].utime, hi = pushed.back().utime;
    const Micros q = lo + static_cast<Micros>(rng.Uniform() * static_cast<double>(hi - lo));
    int k = first;
    while (pushed[k + 1].utime < q) ++k;
    ASSERT_TRUE(h.At(q, &out)) << q;
    if (pushed[k + 1].utime == q) {
      ASSERT_TRUE(BitwiseEqual(out, pushed[k + 1]));
    } else if (pushed[k].utime == q) {
      ASSERT_TRUE(BitwiseEqual(out, pushed[k]));
    } else {
      ExpectNear(out, Lerp(pushed[k], pushed[k + 1], q), 1e-12);
    }
  }
}

TEST(StateHistoryTest, EveryFillFindsEverySampleAroundTheRecentScan) {
  // Look-ups of the newest 16 samples scan back from the newest; older ones search. At
  // every fill (below, at and above 16 samples, then wrapped), every sample and every
  // time between two samples is found, on both sides of the scan's boundary.
  Rng rng(7);
  StateHistory h(32);
  std::vector<HistorySample> pushed;
  Micros t = 0;
  HistorySample out;
  for (int n = 1; n <= 80; ++n) {
    t += 1 + static_cast<Micros>(rng.Uniform() * 30000);
    pushed.push_back(RandomSample(&rng, t));
    ASSERT_TRUE(h.Push(pushed.back()));
    const int first = std::max(0, n - h.capacity());
    for (int k = first; k < n; ++k) {
      ASSERT_TRUE(h.At(pushed[k].utime, &out)) << n << " " << k;
      ASSERT_TRUE(BitwiseEqual(out, pushed[k])) << n << " " << k;
      if (k + 1 < n && pushed[k + 1].utime - pushed[k].utime > 1) {
        const Micros q = pushed[k].utime + 1;
        ASSERT_TRUE(h.At(q, &out)) << n << " " << k;
        ExpectNear(out, Lerp(pushed[k], pushed[k + 1], q), 1e-12);
      }
    }
    EXPECT_FALSE(h.At(pushed[first].utime - 1, &out)) << n;
    EXPECT_FALSE(h.At(pushed.back().utime + 1, &out)) << n;
  }
}

TEST(StateHistoryTest, EvenlySpacedRunsAfterUnevenSamplesFindEverySample) {
  // A run of evenly spaced samples is looked up by division. Runs of several spacings
  // follow each other, some right after a sample only 1 us older than the run's first:
  // every sample, every time just after one and just before one is found as a search
  // finds it, through the wrap of the buffer.
  Rng rng(11);
  StateHistory h(32);
  std::vector<HistorySample> pushed;
  Micros t = 0;
  HistorySample out;
  const Micros steps[] = {20000, 3, 1, 17};
  for (int run = 0; run < 24; ++run) {
    const Micros step = steps[run % 4];
    const int len = 1 + static_cast<int>(rng.Uniform() * 9);
    t += run % 3 == 0 ? 1 : step;
    for (int k = 0; k < len; ++k, t += step) {
      pushed.push_back(RandomSample(&rng, t));
      ASSERT_TRUE(h.Push(pushed.back()));
      const int n = static_cast<int>(pushed.size());
      const int first = std::max(0, n - h.capacity());
      for (int i = first; i < n; ++i) {
        ASSERT_TRUE(h.At(pushed[i].utime, &out)) << run << " " << i;
        ASSERT_TRUE(BitwiseEqual(out, pushed[i])) << run << " " << i;
        if (i + 1 < n && pushed[i + 1].utime - pushed[i].utime > 1) {
          for (const Micros q : {pushed[i].utime + 1, pushed[i + 1].utime - 1}) {
            ASSERT_TRUE(h.At(q, &out)) << run << " " << i << " " << q;
            ExpectNear(out, Lerp(pushed[i], pushed[i + 1], q), 1e-12);
          }
        }
      }
      EXPECT_FALSE(h.At(pushed[first].utime - 1, &out));
      EXPECT_FALSE(h.At(pushed.back().utime + 1, &out));
    }
    t -= step;
  }
}

// The history is sized by the neighbour timeout, the largest delay and two periods, but
// never beyond the run's ticks (+2): a delay of 1e9 s once asked for 5e10 samples.
TEST(StateHistoryTest, FollowerHistoryIsBoundedByTheRun) {
  Scenario s;
  s.followers = 1;
  s.leader_links = {1};
  s.offsets_m = {{0.0, 0.0, 0.0}};
  s.initial.resize(1);
  s.control_rate_hz = 50.0;
  s.duration_s = 600.0;
  s.neighbour_timeout_s = 1.0;
  s.delay.kind = DelayKind::kConstant;
  s.delay.base_s = 0.5;
  EXPECT_EQ(Follower::HistoryCapacity(s), 79);  // ceil(1.54 / 0.02) + 2
  s.delay.base_s = 1e9;
  EXPECT_EQ(Follower::HistoryCapacity(s), 30002);  // 30001 ticks + 1
  EXPECT_EQ(Follower::HistoryCapacity(s, 10.0), 502);
  s.duration_s = 1e9;
  EXPECT_EQ(Follower::HistoryCapacity(s), std::int64_t{50000000002});
  EXPECT_THROW(StateHistory(Follower::HistoryCapacity(s)), std::length_error);
  s.duration_s = 600.0;
  const Topology topo = Topology::Build(1, {}, {1});
  const Follower f(s, topo, 1, nullptr, 20.0);  // would need 400 GB sized by the delay
  EXPECT_EQ(f.id(), 1);
}

// The estimate behind --allow-large: a run of years is large, the same run for 600 s is
// not, and the memory counts the histories bounded by the run.
TEST(StateHistoryTest, RunEstimateFlagsRunsOfYears) {
  Scenario s;
  s.followers = 1;
  s.leader_links = {1};
  s.offsets_m = {{0.0, 0.0, 0.0}};
  s.initial.resize(1);
  s.duration_s = 600.0;
  const RunEstimate short_run = EstimateRun(s);
  EXPECT_EQ(short_run.ticks, 30001);
  EXPECT_EQ(short_run.links, 1);
  EXPECT_FALSE(short_run.large());
  EXPECT_TRUE(LargeRunRefusal(s).empty());
  const RunEstimate years = EstimateRun(s, 1e8);
  EXPECT_EQ(years.ticks, 5000000001);
  EXPECT_TRUE(years.large());
  EXPECT_GT(years.wall_seconds, 3600.0);
  EXPECT_NE(LargeRunRefusal(s, 1e8).find("--allow-large"), std::string::npos);
  s.delay.kind = DelayKind::kConstant;
  s.delay.base_s = 1e9;  // every sample of the run kept: 5e9 samples
  EXPECT_GT(EstimateRun(s, 1e8).memory_bytes, 5e9 * sizeof(HistorySample));
}

}  // namespace
}  // namespace shoal
