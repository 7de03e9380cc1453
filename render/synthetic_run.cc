#include "render/synthetic_run.h"

#include <cmath>
#include <random>

namespace shoal::render {
namespace {

constexpr double kPi = 3.14159265358979323846;

double Wrap(double a) { return std::remainder(a, 2.0 * kPi); }

struct Kinematics {
  std::vector<double> x, y, z, vx, vy, vz;
};

// Attitude: the leader's (psi_ref, theta_ref; null for the leader itself, whose attitude
// follows its velocity) plus a decaying oscillating offset.
void FinishVehicle(const std::vector<double>& t, const Kinematics& k, const VehicleSeries* ref,
                   double dpsi0, double dtheta0, VehicleSeries* v) {
  const std::size_t n = t.size();
  for (auto& a : v->eta) a.resize(n);
  for (auto& a : v->nu) a.resize(n);
  v->t_s = t;
  std::vector<double> psi_unwrapped(n);
  double prev = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double horizontal = std::hypot(k.vx[i], k.vy[i]);
    const double offset =
        std::exp(-t[i] / 8.0) * std::cos(0.4 * t[i]) + 2e-3 * std::sin(0.7 * t[i]);
    double psi = ref ? ref->eta[4][i] + dpsi0 * offset : std::atan2(k.vy[i], k.vx[i]);
    if (i > 0) psi = prev + Wrap(psi - prev);  // continuous
    prev = psi;
    psi_unwrapped[i] = psi;
    const double theta = ref ? ref->eta[3][i] + dtheta0 * offset : std::atan2(-k.vz[i], horizontal);
    v->eta[0][i] = k.x[i];
    v->eta[1][i] = k.y[i];
    v->eta[2][i] = k.z[i];
    v->eta[3][i] = theta;
    v->eta[4][i] = psi;
    // Body velocities: R = Rz(psi) Ry(theta), nu_lin = R^T p_dot.
    const double a = std::cos(psi) * k.vx[i] + std::sin(psi) * k.vy[i];
    const double b = -std::sin(psi) * k.vx[i] + std::cos(psi) * k.vy[i];
    v->nu[0][i] = std::cos(theta) * a - std::sin(theta) * k.vz[i];
    v->nu[1][i] = b;
    v->nu[2][i] = std::sin(theta) * a + std::cos(theta) * k.vz[i];
  }
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t i0 = i > 0 ? i - 1 : i, i1 = i + 1 < n ? i + 1 : i;
    const double dt = t[i1] - t[i0];
    const double q = dt > 0 ? (v->eta[3][i1] - v->eta[3][i0]) / dt : 0.0;
    const double psi_dot = dt > 0 ? (psi_unwrapped[i1] - psi_unwrapped[i0]) / dt : 0.0;
    v->nu[3][i] = q;
    v->nu[4][i] = psi_dot * std::cos(v->eta[3][i]);
  }
}

// The paper's helix and its velocity at the times t.
Kinematics LeaderKinematics(const std::vector<double>& t) {
  const std::size_t n = t.size();
  const double a = 0.0022 * kPi, b = 0.0011 * kPi;
  Kinematics leader;
  for (auto* v : {&leader.x, &leader.y, &leader.z, &leader.vx, &leader.vy, &leader.vz})
    v->resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double s = t[i];
    leader.x[i] = 60 * std::cos(a * s) + 25 * std::sin(b * s);
    leader.y[i] = 60 * std::sin(a * s) + 25 * std::cos(b * s);
    leader.z[i] = -0.12 * s;
    leader.vx[i] = -60 * a * std::sin(a * s) + 25 * b * std::cos(b * s);
    leader.vy[i] = 60 * a * std::cos(a * s) - 25 * b * std::sin(b * s);
    leader.vz[i] = -0.12;
  }
  return leader;
}

// scenarios/paper_example2.toml: offsets, initial positions, headings and pitch.
const double kOffsets[5][3] = {{6, 6, 0}, {6, -6, 0}, {-6, 6, 0}, {-6, -6, 0}, {0, 0, 5}};
const double kStart[5][3] = {{75, 13, 5}, {50, 39, -6}, {42, 21, 8}, {72, 45, -6}, {64, 9, 10}};
const double kHeading[5] = {0.5, 2.0, 3.5, 5.0, 1.2};
const double kPitch[5] = {0.10, -0.15, 0.05, -0.10, 0.12};
const double kBias[5] = {0.016, 0.032, 0.016, 0.049, 0.032};  // docs/examples.md: PD bias on the helix

// Follower f's (0-based) positions and velocities, and its position error in es.
Kinematics FollowerKinematics(int f, const std::vector<double>& t, const Kinematics& leader,
                              ErrorSeries* es) {
  const std::size_t n = t.size();
  const double a = 0.0022 * kPi, T = 12.0, w = 0.25;
  double e0[3];
  for (int c = 0; c < 3; ++c) {
    const double l0 = c == 0 ? leader.x[0] : c == 1 ? leader.y[0] : leader.z[0];
    e0[c] = kStart[f][c] - l0 - kOffsets[f][c];
  }
  Kinematics k;
  for (auto* v : {&k.x, &k.y, &k.z, &k.vx, &k.vy, &k.vz}) v->resize(n);
  es->position_m.resize(n);
  const double phase = 0.7 * f;
  for (std::size_t i = 0; i < n; ++i) {
    const double s = t[i];
    const double decay = std::exp(-s / T);
    const double g = decay * (std::cos(w * s) + std::sin(w * s) / (w * T));
    const double gd = -decay * std::sin(w * s) * (w + 1.0 / (w * T * T));
    // Delay-induced wobble at tau's frequency (1 rad/s), decaying more slowly.
    // (plus a small persistent part: the delayed law never settles exactly).
    const double wob = 0.25 * std::exp(-s / 25.0) + 0.003;
    const double wx = wob * std::sin(s + phase),
                 wxd = wob * (std::cos(s + phase) - std::sin(s + phase) / 25.0);
    // Steady bias towards the helix axis.
    const double rb = kBias[f] * (1.0 - decay);
    const double cx = -std::cos(a * s), cy = -std::sin(a * s);
    const double e[3] = {e0[0] * g + wx + rb * cx, e0[1] * g + rb * cy, e0[2] * g + 0.5 * wx};
    const double ed[3] = {e0[0] * gd + wxd, e0[1] * gd, e0[2] * gd + 0.5 * wxd};
    k.x[i] = leader.x[i] + kOffsets[f][0] + e[0];
    k.y[i] = leader.y[i] + kOffsets[f][1] + e[1];
    k.z[i] = leader.z[i] + kOffsets[f][2] + e[2];
    k.vx[i] = leader.vx[i] + ed[0];
    k.vy[i] = leader.vy[i] + ed[1];
    k.vz[i] = leader.vz[i] + ed[2];
    es->position_m[i] = std::sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
  }
  return k;
}

// Adds follower f (0-based) to the run; returns the last time it was outside 0.5 m /
// 0.05 m/s (-1 if never).
double AddFollower(int f, const std::vector<double>& t, const Kinematics& leader,
                   SyntheticRun* run) {
  const std::size_t n = t.size();
  ErrorSeries es;
  es.id = f + 1;
  es.t_s = t;
  const Kinematics k = FollowerKinematics(f, t, leader, &es);
  es.velocity_mps.resize(n);
  es.attitude_rad.resize(n);
  VehicleSeries v;
  v.id = f + 1;
  const VehicleSeries& l = run->vehicles[0];
  FinishVehicle(t, k, &l, Wrap(kHeading[f] - l.eta[4][0]), kPitch[f] - l.eta[3][0], &v);
  double last_bad = -1.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double dv[5] = {k.vx[i] - leader.vx[i], k.vy[i] - leader.vy[i], k.vz[i] - leader.vz[i],
                          v.nu[3][i] - l.nu[3][i], v.nu[4][i] - l.nu[4][i]};
    double sq = 0.0;
    for (double d : dv) sq += d * d;
    es.velocity_mps[i] = std::sqrt(sq);
    es.attitude_rad[i] =
        std::hypot(Wrap(v.eta[3][i] - l.eta[3][i]), Wrap(v.eta[4][i] - l.eta[4][i]));
    if (es.position_m[i] > 0.5 || es.velocity_mps[i] > 0.05) last_bad = t[i];
  }
  run->vehicles.push_back(std::move(v));
  run->errors.push_back(std::move(es));
  return last_bad;
}

// Channel: the paper's topology (Fig. 1), tau(t) = 0.1 + 0.05 cos t, delivery at the first
// tick at or after send + tau, seeded Bernoulli drops.
void AddChannel(const std::vector<double>& t, double duration_s, double dt,
                double drop_probability, unsigned seed, SyntheticRun* run) {
  const int links[10][2] = {{0, 1}, {0, 3}, {0, 5}, {3, 1}, {1, 2},
                            {5, 2}, {1, 3}, {5, 4}, {2, 5}, {4, 5}};
  const auto tau = [](double s) { return 0.1 + 0.05 * std::cos(s); };
  for (double s = 0.0; s <= duration_s + 1e-9; s += 0.01) {
    run->tau_t_s.push_back(s);
    run->tau_s.push_back(tau(s));
  }
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  for (const auto& lk : links) {
    LinkSeries ls;
    ls.from = lk[0];
    ls.to = lk[1];
    ls.sent_s.reserve(t.size());
    ls.delay_s.reserve(t.size());
    for (double ti : t) {
      if (uni(rng) < drop_probability) {
        ls.dropped_s.push_back(ti);
        continue;
      }
      const double ticks = std::ceil(tau(ti) / dt - 1e-9);
      ls.sent_s.push_back(ti);
      ls.delay_s.push_back(ticks * dt);
    }
    run->links.push_back(std::move(ls));
  }
}

}  // namespace

SyntheticRun MakeSyntheticRun(double duration_s, double rate_hz, double drop_probability,
                              unsigned seed) {
  SyntheticRun run;
  const double dt = 1.0 / rate_hz;
  const auto n = static_cast<std::size_t>(std::floor(duration_s * rate_hz)) + 1;
  std::vector<double> t(n);
  for (std::size_t i = 0; i < n; ++i) t[i] = static_cast<double>(i) * dt;
  const Kinematics leader = LeaderKinematics(t);
  VehicleSeries lv;
  lv.id = 0;
  FinishVehicle(t, leader, nullptr, 0.0, 0.0, &lv);
  run.vehicles.push_back(std::move(lv));
  double bad = -1.0;
  for (int f = 0; f < 5; ++f) bad = std::max(bad, AddFollower(f, t, leader, &run));
  run.converged_s = bad < t.back() ? bad + dt : -1.0;
  AddChannel(t, duration_s, dt, drop_probability, seed, &run);
  run.topology = {{0, 1}, {0, 3}, {0, 5}, {1, 3}, {1, 2}, {2, 5}, {4, 5}};
  return run;
}

}  // namespace shoal::render
