#include "core/fossen.h"

#include "core/fossen_lanes.h"

namespace shoal {

namespace {
// RK4 in a current: nu_r = nu - nu_c, with nu_c from each stage's attitude.
struct Deriv {
  Vec5 eta_dot;
  Vec5 nu_dot;
};

[[gnu::always_inline]] inline Deriv F(const FossenModel& model, const AttitudeTrig<double>& c,
                                      const Vec5& nu, const Vec5& tau, const Vec3& current_ned) {
  return {FossenModel::EtaDot(c, nu), model.NuDot(c, nu, tau, BodyCurrent(c, current_ned))};
}

void Rk4StepInCurrent(const FossenModel& model, const Vec5& tau, const Vec3& current_ned,
                      double dt, const AttitudeTrig<double>& trig, PlantState* x,
                      AttitudeTrig<double>* trig_out) {
  const Vec5 eta = x->eta, nu = x->nu;
  const Deriv k1 = F(model, trig, nu, tau, current_ned);
  const Vec5 eta2 = eta + 0.5 * dt * k1.eta_dot;
  const Deriv k2 =
      F(model, ShiftTrig(trig, eta, eta2), nu + 0.5 * dt * k1.nu_dot, tau, current_ned);
  const Vec5 eta3 = eta + 0.5 * dt * k2.eta_dot;
  const Deriv k3 =
      F(model, ShiftTrig(trig, eta, eta3), nu + 0.5 * dt * k2.nu_dot, tau, current_ned);
  const Vec5 eta4 = eta + dt * k3.eta_dot;
  const Deriv k4 = F(model, ShiftTrig(trig, eta, eta4), nu + dt * k3.nu_dot, tau, current_ned);
  x->eta = eta + dt / 6.0 * (k1.eta_dot + 2.0 * k2.eta_dot + 2.0 * k3.eta_dot + k4.eta_dot);
  x->nu = nu + dt / 6.0 * (k1.nu_dot + 2.0 * k2.nu_dot + 2.0 * k3.nu_dot + k4.nu_dot);
  if (trig_out != nullptr) *trig_out = ShiftTrig(trig, eta, x->eta);
}
}  // namespace

void Rk4Step(const FossenModel& model, const Vec5& tau, const Vec3& current_ned, double dt,
             const AttitudeTrig<double>& trig, PlantState* x, AttitudeTrig<double>* trig_out) {
  if (current_ned.isZero()) {
    // Still water: the lane code with one lane, which IntegrateMany runs four wide.
    lanes::Vec5L<double> eta, nu, t;
    for (int k = 0; k < 5; ++k) {
      eta.v[k] = x->eta(k);
      nu.v[k] = x->nu(k);
      t.v[k] = tau(k);
    }
    lanes::TrigL<double> c{trig.ct, trig.st, trig.cp, trig.sp}, out;
    FossenLanes(model).Rk4Still(t, dt, c, &eta, &nu, trig_out ? &out : nullptr);
    for (int k = 0; k < 5; ++k) {
      x->eta(k) = eta.v[k];
      x->nu(k) = nu.v[k];
    }
    if (trig_out != nullptr) {
      trig_out->ct = out.ct;
      trig_out->st = out.st;
      trig_out->cp = out.cp;
      trig_out->sp = out.sp;
    }
  } else {
    Rk4StepInCurrent(model, tau, current_ned, dt, trig, x, trig_out);
  }
}

void Integrate(const FossenModel& model, const Vec5& tau, const Vec3& current_ned,
               double period_s, int substeps, PlantState* x,
               const AttitudeTrig<double>* trig, AttitudeTrig<double>* trig_out) {
  const double dt = period_s / substeps;
  for (int s = 0; s < substeps; ++s) {
    AttitudeTrig<double>* out = s + 1 == substeps ? trig_out : nullptr;
    if (s == 0 && trig != nullptr) {
      Rk4Step(model, tau, current_ned, dt, *trig, x, out);
    } else {
      Rk4Step(model, tau, current_ned, dt, AttitudeTrig<double>(x->eta), x, out);
    }
  }
}

namespace {
using lanes::Set;
using lanes::TrigL;
using lanes::Vec5L;

// AttitudeTrig of each lane: the given one, or afresh from the lane's eta.
template <typename L>
[[gnu::always_inline]] inline TrigL<L> LaneTrig(const Vec5L<L>& eta,
                                                const AttitudeTrig<double>* const* given) {
  TrigL<L> t;
  bool all_given = true;
  for (int i = 0; i < lanes::Count<L>::kLanes; ++i) all_given = all_given && given[i] != nullptr;
  if (all_given) {
    using lanes::Gather;
    t.ct = Gather<L>([&](int i) { return given[i]->ct; });
    t.st = Gather<L>([&](int i) { return given[i]->st; });
    t.cp = Gather<L>([&](int i) { return given[i]->cp; });
    t.sp = Gather<L>([&](int i) { return given[i]->sp; });
    return t;
  }
  for (int i = 0; i < lanes::Count<L>::kLanes; ++i) {
    AttitudeTrig<double> c = given[i] != nullptr ? *given[i] : AttitudeTrig<double>(Vec5::Zero());
    if (given[i] == nullptr) {
      c.ct = std::cos(eta.v[3][i]);
      c.st = std::sin(eta.v[3][i]);
      c.cp = std::cos(eta.v[4][i]);
      c.sp = std::sin(eta.v[4][i]);
    }
    Set(&t.ct, i, c.ct);
    Set(&t.st, i, c.st);
    Set(&t.cp, i, c.cp);
    Set(&t.sp, i, c.sp);
  }
  return t;
}

// Integrate() of two or more still-water jobs in the lanes of L (a short pack repeats its
// first job in the spare lanes, whose results are dropped). Inlined into each
// instruction-set variant below.
template <typename L>
[[gnu::always_inline]] inline void IntegratePack(const FossenModel& model, double dt, int substeps,
                                                 PlantJob* const* pack, int count) {
  constexpr int kLanes = lanes::Count<L>::kLanes;
  const AttitudeTrig<double>* given[kLanes];
  const PlantJob* j[kLanes];
  for (int i = 0; i < kLanes; ++i) {
    j[i] = pack[i < count ? i : 0];
    given[i] = j[i]->trig;
  }
  using lanes::Gather;
  Vec5L<L> eta, nu, tau;
  for (int k = 0; k < 5; ++k) {
    eta.v[k] = Gather<L>([&](int i) { return j[i]->x->eta(k); });
    nu.v[k] = Gather<L>([&](int i) { return j[i]->x->nu(k); });
    tau.v[k] = Gather<L>([&](int i) { return j[i]->tau(k); });
  }
  const FossenLanes fossen(model);
  TrigL<L> out;
  for (int s = 0; s < substeps; ++s) {
    // As in Integrate(): the given trig for the first substep, afresh for the others.
    const TrigL<L> t = LaneTrig(eta, given);
    for (int i = 0; i < kLanes; ++i) given[i] = nullptr;
    fossen.Rk4Still(tau, dt, t, &eta, &nu, s + 1 == substeps ? &out : nullptr);
  }
  // Unrolled, so that each lane is taken from the register by its constant index: a
  // vector stored whole and read back a lane at a time stalls as the gather would.
#pragma GCC unroll 8
  for (int i = 0; i < lanes::Count<L>::kLanes; ++i) {
    if (i >= count) break;
    // By Vec5Of: the state is read whole right after (Follower::Integrated).
    pack[i]->x->eta = Vec5Of(eta.v[0][i], eta.v[1][i], eta.v[2][i], eta.v[3][i], eta.v[4][i]);
    pack[i]->x->nu = Vec5Of(nu.v[0][i], nu.v[1][i], nu.v[2][i], nu.v[3][i], nu.v[4][i]);
    if (pack[i]->trig_out != nullptr) {
      pack[i]->trig_out->ct = out.ct[i];
      pack[i]->trig_out->st = out.st[i];
      pack[i]->trig_out->cp = out.cp[i];
      pack[i]->trig_out->sp = out.sp[i];
    }
  }
}

__attribute__((target("avx512f"))) void IntegratePackAvx512(const FossenModel& model, double dt,
                                                            int substeps, PlantJob* const* pack,
                                                            int count) {
  IntegratePack<Lanes8>(model, dt, substeps, pack, count);
}

__attribute__((target("avx2"))) void IntegratePackAvx2(const FossenModel& model, double dt,
                                                       int substeps, PlantJob* const* pack,
                                                       int count) {
  IntegratePack<Lanes4>(model, dt, substeps, pack, count);
}

void IntegratePackBase(const FossenModel& model, double dt, int substeps, PlantJob* const* pack,
                       int count) {
  IntegratePack<Lanes4>(model, dt, substeps, pack, count);
}
}  // namespace

LaneCode BestLaneCode(LaneCode asked) {
  static const LaneCode best = __builtin_cpu_supports("avx512f") ? LaneCode::kAvx512
                               : __builtin_cpu_supports("avx2")  ? LaneCode::kAvx2
                                                                 : LaneCode::kBase;
  return asked == LaneCode::kBest ? best : asked;
}

bool CpuRuns(LaneCode code) {
  const LaneCode best = BestLaneCode(LaneCode::kBest);
  return code == LaneCode::kBase || code == LaneCode::kBest || code == best ||
         (code == LaneCode::kAvx2 && best == LaneCode::kAvx512);
}

void IntegrateMany(const FossenModel& model, double period_s, int substeps, PlantJob* jobs,
                   int count, LaneCode code) {
  code = BestLaneCode(code);
  const int width = code == LaneCode::kAvx512 ? 8 : 4;
  const double dt = period_s / substeps;
  PlantJob* pack[8];
  int filled = 0;
  auto flush = [&] {
    if (filled == 1) {
      PlantJob& j = *pack[0];
      Integrate(model, j.tau, j.current_ned, period_s, substeps, j.x, j.trig, j.trig_out);
    } else if (filled > 1) {
      (code == LaneCode::kAvx512 ? IntegratePackAvx512
       : code == LaneCode::kAvx2 ? IntegratePackAvx2
                                 : IntegratePackBase)(model, dt, substeps, pack, filled);
    }
    filled = 0;
  };
  for (int i = 0; i < count; ++i) {
    PlantJob& j = jobs[i];
    if (!j.current_ned.isZero()) {
      Integrate(model, j.tau, j.current_ned, period_s, substeps, j.x, j.trig, j.trig_out);
      continue;
    }
    pack[filled++] = &j;
    if (filled == width) flush();
  }
  flush();
}

}  // namespace shoal
