#include "core/control.h"

#include <algorithm>

#include "core/fossen_lanes.h"

namespace shoal {

namespace {
using lanes::TrigL;
using lanes::Vec5L;

// SaturatedFeedbackLinearise of one to four jobs in the lanes of L (a short pack repeats its
// first job in the spare lanes, whose results are dropped). Inlined into each
// instruction-set variant below.
template <typename L>
[[gnu::always_inline]] inline void ForcePack(const FossenModel& model, ForceJob* const* pack,
                                             int count) {
  constexpr int kLanes = lanes::Count<L>::kLanes;
  const ForceJob* j[kLanes];
  for (int i = 0; i < kLanes; ++i) j[i] = pack[i < count ? i : 0];
  using lanes::Gather;
  TrigL<L> c;
  c.ct = Gather<L>([&](int i) { return j[i]->trig.ct; });
  c.st = Gather<L>([&](int i) { return j[i]->trig.st; });
  c.cp = Gather<L>([&](int i) { return j[i]->trig.cp; });
  c.sp = Gather<L>([&](int i) { return j[i]->trig.sp; });
  Vec5L<L> nu, a, lim, tau, demand;
  for (int k = 0; k < 5; ++k) {
    nu.v[k] = Gather<L>([&](int i) { return j[i]->nu(k); });
    a.v[k] = Gather<L>([&](int i) { return j[i]->a(k); });
    lim.v[k] = Gather<L>([&](int i) { return j[i]->tau_max(k); });
  }
  FossenLanes(model).SaturatedFeedbackLinearise(c, nu, a, lim, &tau, &demand);
  // Unrolled, so that each lane is taken from the register by its constant index: a
  // vector stored whole and read back a lane at a time stalls as the gather would.
#pragma GCC unroll 8
  for (int i = 0; i < lanes::Count<L>::kLanes; ++i) {
    if (i >= count) break;
    ForceJob& j = *pack[i];
    // By Vec5Of: Forced() reads the force whole right after.
    j.tau = Vec5Of(lanes::At(tau.v[0], i), lanes::At(tau.v[1], i), lanes::At(tau.v[2], i),
                   lanes::At(tau.v[3], i), lanes::At(tau.v[4], i));
    j.wanted = Vec5Of(lanes::At(demand.v[0], i), lanes::At(demand.v[1], i),
                      lanes::At(demand.v[2], i), lanes::At(demand.v[3], i),
                      lanes::At(demand.v[4], i));
    j.saturated = SaturationChanged(j.tau, j.wanted);
  }
}

__attribute__((target("avx512f"))) void ForcePackAvx512(const FossenModel& model,
                                                        ForceJob* const* pack, int count) {
  ForcePack<Lanes8>(model, pack, count);
}

__attribute__((target("avx2"))) void ForcePackAvx2(const FossenModel& model,
                                                   ForceJob* const* pack, int count) {
  ForcePack<Lanes4>(model, pack, count);
}

void ForcePackBase(const FossenModel& model, ForceJob* const* pack, int count) {
  ForcePack<Lanes4>(model, pack, count);
}
}  // namespace

void SaturatedFeedbackLineariseMany(const FossenModel& model, ForceJob* const* jobs, int count,
                                    LaneCode code) {
  code = BestLaneCode(code);
  const int width = code == LaneCode::kAvx512 ? 8 : 4;
  for (int first = 0; first < count; first += width) {
    const int n = std::min(width, count - first);
    if (n == 1) {
      ForcePack<double>(model, jobs + first, 1);
    } else {
      (code == LaneCode::kAvx512 ? ForcePackAvx512
       : code == LaneCode::kAvx2 ? ForcePackAvx2
                                 : ForcePackBase)(model, jobs + first, n);
    }
  }
}

}  // namespace shoal
