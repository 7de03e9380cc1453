#include "core/fossen.h"

namespace shoal {

namespace {
struct Deriv {
  Vec5 eta_dot;
  Vec5 nu_dot;
};

// Inlined into each RK4 stage: as a call it returned its two vectors through memory.
// Still water (kCurrent false) leaves out the body-frame current: nu - 0 is nu to the bit,
// so both forms give the same numbers there.
template <bool kCurrent>
[[gnu::always_inline]] inline Deriv F(const FossenModel& model, const AttitudeTrig<double>& c,
                                      const Vec5& nu, const Vec5& tau, const Vec3& current_ned) {
  if constexpr (kCurrent) {
    return {FossenModel::EtaDot(c, nu), model.NuDot(c, nu, tau, BodyCurrent(c, current_ned))};
  } else {
    return {FossenModel::EtaDot(c, nu), model.NuDotStill(c, nu, tau)};
  }
}

template <bool kCurrent>
void Rk4StepIn(const FossenModel& model, const Vec5& tau, const Vec3& current_ned, double dt,
               const AttitudeTrig<double>& trig, PlantState* x, AttitudeTrig<double>* trig_out) {
  const Vec5 eta = x->eta, nu = x->nu;
  const Deriv k1 = F<kCurrent>(model, trig, nu, tau, current_ned);
  const Vec5 eta2 = eta + 0.5 * dt * k1.eta_dot;
  const Deriv k2 = F<kCurrent>(model, ShiftTrig(trig, eta, eta2), nu + 0.5 * dt * k1.nu_dot,
                               tau, current_ned);
  const Vec5 eta3 = eta + 0.5 * dt * k2.eta_dot;
  const Deriv k3 = F<kCurrent>(model, ShiftTrig(trig, eta, eta3), nu + 0.5 * dt * k2.nu_dot,
                               tau, current_ned);
  const Vec5 eta4 = eta + dt * k3.eta_dot;
  const Deriv k4 =
      F<kCurrent>(model, ShiftTrig(trig, eta, eta4), nu + dt * k3.nu_dot, tau, current_ned);
  x->eta = eta + dt / 6.0 * (k1.eta_dot + 2.0 * k2.eta_dot + 2.0 * k3.eta_dot + k4.eta_dot);
  x->nu = nu + dt / 6.0 * (k1.nu_dot + 2.0 * k2.nu_dot + 2.0 * k3.nu_dot + k4.nu_dot);
  if (trig_out != nullptr) *trig_out = ShiftTrig(trig, eta, x->eta);
}
}  // namespace

void Rk4Step(const FossenModel& model, const Vec5& tau, const Vec3& current_ned, double dt,
             const AttitudeTrig<double>& trig, PlantState* x, AttitudeTrig<double>* trig_out) {
  if (current_ned.isZero()) {
    Rk4StepIn<false>(model, tau, current_ned, dt, trig, x, trig_out);
  } else {
    Rk4StepIn<true>(model, tau, current_ned, dt, trig, x, trig_out);
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

}  // namespace shoal
