#include "core/theory.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

#include "core/channel_model.h"
#include "core/topology.h"

namespace shoal {
namespace theory {
namespace {

constexpr double kTwoPi = 6.283185307179586;

void SortDescending(std::vector<Complex>* v) {
  std::sort(v->begin(), v->end(), [](const Complex& a, const Complex& b) {
    if (a.real() != b.real()) return a.real() > b.real();
    return a.imag() > b.imag();
  });
}

double MaxEigenvalueSymmetric(const Eigen::MatrixXd& S) {
  const Eigen::MatrixXd sym = 0.5 * (S + S.transpose());
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(sym, Eigen::EigenvaluesOnly);
  return es.eigenvalues().maxCoeff();
}

/// x mod 2 pi in (0, 2 pi]: a crossing at a multiple of 2 pi would be a root on the
/// imaginary axis at tau = 0, excluded once stability at tau = 0 is established.
double PositiveAngle(double x) {
  double r = std::fmod(x, kTwoPi);
  if (r <= 0.0) r += kTwoPi;
  return r;
}

}  // namespace

std::vector<Complex> HEigenvalues(const Eigen::MatrixXd& H) {
  Eigen::EigenSolver<Eigen::MatrixXd> es(H, false);
  std::vector<Complex> out(es.eigenvalues().data(),
                           es.eigenvalues().data() + es.eigenvalues().size());
  SortDescending(&out);
  return out;
}

std::optional<Eigen::MatrixXd> SolveW(const Eigen::MatrixXd& H) {
  const Eigen::Index n = H.rows();
  // H = U T U* with T upper triangular; since H is real, H^T = H* = U T* U*, and
  // W H + H^T W = I becomes X T + T* X = I for X = U* W U.
  Eigen::ComplexSchur<Eigen::MatrixXcd> schur(H.cast<Complex>());
  const Eigen::MatrixXcd& T = schur.matrixT();
  const Eigen::MatrixXcd& U = schur.matrixU();
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!(T(i, i).real() > 0.0)) return std::nullopt;
  }
  // Element (i, j): X_ij (T_jj + conj(T_ii)) = delta_ij - sum_{k<j} X_ik T_kj
  //                                                    - sum_{k<i} conj(T_ki) X_kj.
  Eigen::MatrixXcd X = Eigen::MatrixXcd::Zero(n, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = 0; j < n; ++j) {
      Complex rhs = (i == j) ? Complex(1.0, 0.0) : Complex(0.0, 0.0);
      for (Eigen::Index k = 0; k < j; ++k) rhs -= X(i, k) * T(k, j);
      for (Eigen::Index k = 0; k < i; ++k) rhs -= std::conj(T(k, i)) * X(k, j);
      X(i, j) = rhs / (T(j, j) + std::conj(T(i, i)));
    }
  }
  const Eigen::MatrixXd W = (U * X * U.adjoint()).real();
  return Eigen::MatrixXd(0.5 * (W + W.transpose()));
}

std::optional<Theorem1> ComputeTheorem1(const Eigen::MatrixXd& H, double k1, double k2,
                                        double alpha, double beta) {
  const std::optional<Eigen::MatrixXd> w = SolveW(H);
  if (!w) return std::nullopt;
  const Eigen::Index n = H.rows();
  Theorem1 t;
  t.W = *w;
  {
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(t.W, Eigen::EigenvaluesOnly);
    t.W_eigenvalues = es.eigenvalues();
  }
  t.lambda_max_W = t.W_eigenvalues.maxCoeff();
  const bool W_pd = t.W_eigenvalues.minCoeff() > 0.0;

  t.M = t.W - alpha * beta * t.W * H - H.transpose() * t.W;
  {
    const Eigen::MatrixXd M2 = t.M * t.M;
    Eigen::EigenSolver<Eigen::MatrixXd> es(M2, false);
    t.M2_eigenvalues.assign(es.eigenvalues().data(),
                            es.eigenvalues().data() + es.eigenvalues().size());
    SortDescending(&t.M2_eigenvalues);
    t.lambda_max_M2 = t.M2_eigenvalues.front().real();
  }
  t.lambda_max_MtM = MaxEigenvalueSymmetric(t.M.transpose() * t.M);

  const double ab = alpha * beta;
  const double a2 = alpha * alpha;
  if (ab - t.lambda_max_M2 > 0.0) {
    t.k1_min = std::max(a2, 2.0 * a2 * t.lambda_max_W / (ab - t.lambda_max_M2));
    t.k2_min = std::max(a2 * beta, 2.0 * a2 * beta * t.lambda_max_W / (ab - t.lambda_max_M2));
  }
  if (ab - t.lambda_max_MtM > 0.0) {
    t.k1_min_corrected = std::max(a2, 2.0 * a2 * t.lambda_max_W / (ab - t.lambda_max_MtM));
    t.k2_min_corrected =
        std::max(a2 * beta, 2.0 * a2 * beta * t.lambda_max_W / (ab - t.lambda_max_MtM));
  }

  // Q = [k1 W, alpha W; alpha W, W] = [k1, alpha; alpha, 1] (x) W: positive definite iff
  // W > 0 and k1 > alpha^2.
  t.Q_positive_definite = W_pd && k1 > a2;
  Eigen::MatrixXd Q(2 * n, 2 * n);
  Q << k1 * t.W, alpha * t.W, alpha * t.W, t.W;
  Eigen::MatrixXd AB = Eigen::MatrixXd::Zero(2 * n, 2 * n);
  AB.topRightCorner(n, n).setIdentity();
  AB.bottomLeftCorner(n, n) = -k1 * H;
  AB.bottomRightCorner(n, n) = -k2 * H;
  t.P = Q * AB + AB.transpose() * Q;
  t.P = 0.5 * (t.P + t.P.transpose());
  t.P_max_eigenvalue = MaxEigenvalueSymmetric(t.P);
  t.certifies = t.Q_positive_definite && t.P_max_eigenvalue < 0.0;
  return t;
}

Theorem2 ComputeTheorem2(const Theorem1& t1, double alpha, double beta, double rho0) {
  Theorem2 t;
  t.rho0 = rho0;
  const double lw = t1.lambda_max_W;
  const double ab = alpha * beta;
  const double a2 = alpha * alpha;

  t.k11 = (3.0 * alpha + 1.0) * rho0 * lw / alpha;
  t.k21 = beta * t.k11;
  const double den = ab - 2.0 * t1.lambda_max_M2;
  if (den > 0.0) {
    t.k12 = (2.0 * a2 * lw + alpha * (alpha + 3.0) / 2.0 * rho0 * lw) / den;
    t.k22 = beta * *t.k12;
    t.k1_min = std::max(t.k11, *t.k12);
    t.k2_min = std::max(t.k21, *t.k22);
  }

  t.k11_corrected = 2.0 * (3.0 * alpha + 1.0) * rho0 * lw / alpha;
  t.k21_corrected = beta * t.k11_corrected;
  const double den_c = ab - 2.0 * t1.lambda_max_MtM;
  if (den_c > 0.0) {
    t.k12_corrected = (2.0 * a2 * lw + alpha * (alpha + 3.0) * rho0 * lw) / den_c;
    t.k22_corrected = beta * *t.k12_corrected;
    t.k1_min_corrected = std::max(t.k11_corrected, *t.k12_corrected);
    t.k2_min_corrected = std::max(t.k21_corrected, *t.k22_corrected);
  }

  // P~ of (26) with the factor 2 restored, for the gains of t1 (P holds for any k2).
  const Eigen::Index n = t1.W.rows();
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(n, n);
  const Eigen::MatrixXd& P = t1.P;
  Eigen::MatrixXd Pt = P;
  Pt.topLeftCorner(n, n) += (3.0 * alpha + 1.0) * rho0 * lw * I;
  Pt.bottomRightCorner(n, n) += (alpha + 3.0) * rho0 * lw * I;
  t.P_tilde_max_eigenvalue = MaxEigenvalueSymmetric(Pt);
  t.certifies = t1.Q_positive_definite && t.P_tilde_max_eigenvalue < 0.0;
  return t;
}

Lipschitz LipschitzOf(const DisturbanceConfig& d) {
  Lipschitz l;
  switch (d.kind) {
    case DisturbanceKind::kNone:
      l.applicable = true;
      l.G = Eigen::MatrixXd::Zero(5, 5);
      l.J = Eigen::MatrixXd::Zero(5, 5);
      l.slopes_known = true;
      l.note = "no uncertain factor: F = 0, rho0 = 0 (Theorem 2 reduces to a Theorem 1-type bound)";
      break;
    case DisturbanceKind::kPaperExample2: {
      // f is separable per component; the largest slopes of its terms:
      //   0.4 tanh(v1): 0.4;  0.01 sin(x2) - 0.45 tanh(v2): 0.01, 0.45;  -0.01 cos(x3): 0.01;
      //   0.48 tanh(v4): 0.48;  0.02 sin(x5) - 0.5 tanh(v5): 0.02, 0.5.
      Eigen::VectorXd g(5), j(5);
      g << 0.0, 0.01, 0.01, 0.0, 0.02;
      j << 0.4, 0.45, 0.0, 0.48, 0.5;
      l.G = g.asDiagonal();
      l.J = j.asDiagonal();
      // Signed slope ranges [dx min, dx max, dv min, dv max]: tanh' in (0, 1], and
      // sin' / cos' take both signs along the way.
      l.slopes_known = true;
      l.slopes << 0.0, 0.0, 0.0, 0.4,  //
          -0.01, 0.01, -0.45, 0.0,     //
          -0.01, 0.01, 0.0, 0.0,       //
          0.0, 0.0, 0.0, 0.48,         //
          -0.02, 0.02, -0.5, 0.0;
      l.applicable = d.relative_to_leader;
      l.note = d.relative_to_leader
                   ? "paper Example 2's F~ felt as f(x_i) - f(x_0) (relative_to_leader = true): "
                     "the uncertain term of the error system (13); rho0 = max(||G||, ||J||)"
                   : "paper Example 2's F~ felt as the absolute f(x_i) (relative_to_leader = "
                     "false): it does not vanish at consensus, so the error system (13) and "
                     "Theorems 2-3 do not describe the run (expect a bias of about H^-1 f / k1)";
      break;
    }
    case DisturbanceKind::kOceanCurrent:
      l.applicable = false;
      l.note =
          "ocean current: an exogenous disturbance acting through the relative velocity "
          "nu - nu_c; it does not vanish at consensus and is not a Lipschitz function of "
          "the formation error, so Assumption 2 gives no rho0 (give --rho0 to evaluate "
          "Theorem 2 for an assumed bound)";
      return l;
  }
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eg(l.G.transpose() * l.G, Eigen::EigenvaluesOnly);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> ej(l.J.transpose() * l.J, Eigen::EigenvaluesOnly);
  // G and J are symmetric here, so G^T G = G^2 as the paper writes it.
  l.lambda_max_G2 = eg.eigenvalues().maxCoeff();
  l.lambda_max_J2 = ej.eigenvalues().maxCoeff();
  l.rho0 = std::max(std::sqrt(l.lambda_max_G2), std::sqrt(l.lambda_max_J2));
  return l;
}

DelayBounds DelayBoundsOf(const DelayConfig& c) {
  DelayBounds b;
  switch (c.kind) {
    case DelayKind::kNone:
      b.h_s = 0.0;
      b.kappa = 0.0;
      break;
    case DelayKind::kConstant:
      b.h_s = c.base_s;
      b.kappa = 0.0;
      break;
    case DelayKind::kSinusoid:
      b.h_s = c.base_s + c.amplitude_s;
      b.kappa = c.amplitude_s * c.omega_rad_s;
      b.time_varying = c.amplitude_s > 0.0 && c.omega_rad_s > 0.0;
      b.constant = !b.time_varying;
      break;
    case DelayKind::kUniform:
      b.h_s = c.base_s + c.amplitude_s;
      b.time_varying = c.amplitude_s > 0.0;
      b.constant = !b.time_varying;
      if (!b.time_varying) b.kappa = 0.0;  // amplitude 0: a constant delay
      break;
    case DelayKind::kAcoustic:
    case DelayKind::kTrace:
      // Treated as a delay bounded by its maximum; its rate follows the vehicles' range
      // rate or the measured series, so Assumption 3 is not guaranteed: kappa unbounded.
      b.h_s = MaxDelaySeconds(c);
      b.time_varying = MaxDelaySeconds(c) > MinDelaySeconds(c);
      b.constant = !b.time_varying;
      if (!b.time_varying) b.kappa = 0.0;
      break;
  }
  return b;
}

DelayBounds DelayBoundsOf(const Scenario& s) {
  const Topology topo = Topology::Build(s.followers, s.edges, s.leader_links);
  std::vector<DelayConfig> models;
  for (const Link& l : BuildLinks(s, topo)) models.push_back(l.delay);
  if (s.disturbance.kind == DisturbanceKind::kPaperExample2) models.push_back(s.delay);

  DelayBounds out;
  out.kappa = 0.0;
  bool first = true;
  double first_value = 0.0;
  for (const DelayConfig& c : models) {
    const DelayBounds b = DelayBoundsOf(c);
    out.h_s = std::max(out.h_s, b.h_s);
    if (!b.kappa || !out.kappa) {
      out.kappa.reset();
    } else {
      out.kappa = std::max(*out.kappa, *b.kappa);
    }
    out.time_varying = out.time_varying || b.time_varying;
    // "constant": one and the same constant value everywhere.
    const double value = b.h_s;
    if (!b.constant || (!first && value != first_value)) out.constant = false;
    if (first) first_value = value;
    first = false;
  }
  return out;
}

/// Whether both roots of s^2 + b s + c lie in the open left half-plane. The root of the
/// larger magnitude comes from -(b + disc) / 2 with the sign that adds, the other as c
/// over it: -b + disc cancels when |4c| << |b|^2 (k1 = 1e-6, k2 = 1e6 gives a root at
/// -1e-12 that the textbook formula puts at 0 or to the right of it).
static bool BothRootsStable(Complex b, Complex c) {
  Complex disc = std::sqrt(b * b - 4.0 * c);
  if (std::real(std::conj(b) * disc) < 0.0) disc = -disc;
  const Complex r1 = -0.5 * (b + disc);
  if (r1 == Complex(0.0, 0.0)) return false;  // b = c = 0: a double root at 0
  const Complex r2 = c / r1;
  return r1.real() < 0.0 && r2.real() < 0.0;
}

EigenMargin EigenDelayMargin(Complex lambda, double k1, double k2) {
  EigenMargin m;
  m.lambda = lambda;
  // tau = 0: s^2 + lambda k2 s + lambda k1 = 0.
  m.stable_at_zero = BothRootsStable(lambda * k2, lambda * k1);

  // |s^2| = |lambda| |k1 + k2 s| at s = j w:  w^4 = |lambda|^2 (k1^2 + k2^2 w^2).
  const double a2 = std::norm(lambda);
  const double u =
      0.5 * (a2 * k2 * k2 + std::sqrt(a2 * a2 * k2 * k2 * k2 * k2 + 4.0 * a2 * k1 * k1));
  const double w = std::sqrt(u);
  m.tau_s = std::numeric_limits<double>::infinity();
  const Complex j(0.0, 1.0);
  for (const double sign : {1.0, -1.0}) {
    const double omega = sign * w;
    // e^{-j omega tau} = omega^2 / (lambda (k1 + j k2 omega)): omega tau = phi (mod 2 pi).
    const double phi = std::arg(lambda * Complex(k1, k2 * omega));
    const double tau = omega > 0.0 ? PositiveAngle(phi) / omega : PositiveAngle(-phi) / w;
    if (tau < m.tau_s) {
      m.tau_s = tau;
      m.omega_rad_s = omega;
    }
  }
  // ds/dtau = s lambda (k2 s + k1) e^{-s tau} / (2 s + lambda k2 e^{-s tau}
  //                                             - tau lambda (k2 s + k1) e^{-s tau}).
  const Complex s = j * m.omega_rad_s;
  const Complex e = std::exp(-s * m.tau_s);
  const Complex g = lambda * (k2 * s + k1) * e;
  const Complex ds = s * g / (2.0 * s + lambda * k2 * e - m.tau_s * g);
  m.crossing_direction = ds.real();
  return m;
}

DelayMargin ComputeDelayMargin(const std::vector<Complex>& eigenvalues, double k1, double k2) {
  DelayMargin d;
  d.stable_at_zero = true;
  d.tau_s = std::numeric_limits<double>::infinity();
  for (const Complex& l : eigenvalues) {
    d.per_eigenvalue.push_back(EigenDelayMargin(l, k1, k2));
    const EigenMargin& m = d.per_eigenvalue.back();
    d.stable_at_zero = d.stable_at_zero && m.stable_at_zero;
    if (m.tau_s < d.tau_s) {
      d.tau_s = m.tau_s;
      d.critical = static_cast<int>(d.per_eigenvalue.size()) - 1;
    }
  }
  if (!d.stable_at_zero) d.tau_s = 0.0;
  return d;
}

EigenMargin GeneralDelayMargin(Complex a, Complex b) {
  EigenMargin m;
  m.stable_at_zero = BothRootsStable(a, b);
  m.tau_s = std::numeric_limits<double>::infinity();

  // Real roots of p(w) = w^4 + c2 w^2 + c1 w + c0 from its companion matrix, polished.
  const double c2 = -std::norm(a), c1 = 2.0 * std::imag(a * std::conj(b)), c0 = -std::norm(b);
  Eigen::Matrix4d C = Eigen::Matrix4d::Zero();
  C(1, 0) = C(2, 1) = C(3, 2) = 1.0;
  C(0, 3) = -c0;
  C(1, 3) = -c1;
  C(2, 3) = -c2;
  Eigen::EigenSolver<Eigen::Matrix4d> es(C, false);
  const double scale = 1.0 + std::sqrt(std::abs(c2)) + std::sqrt(std::sqrt(std::abs(c0)));
  const Complex j(0.0, 1.0);
  for (int k = 0; k < 4; ++k) {
    const Complex r = es.eigenvalues()(k);
    if (std::abs(r.imag()) > 1e-6 * scale) continue;
    double w = r.real();
    for (int it = 0; it < 4; ++it) {
      const double p = ((w * w + c2) * w + c1) * w + c0;
      const double dp = (4.0 * w * w + 2.0 * c2) * w + c1;
      if (dp == 0.0) break;
      w -= p / dp;
    }
    if (w == 0.0) continue;
    const double phi = std::arg(j * w * a + b);
    const double tau = w > 0.0 ? PositiveAngle(phi) / w : PositiveAngle(-phi) / -w;
    if (tau < m.tau_s) {
      m.tau_s = tau;
      m.omega_rad_s = w;
    }
  }
  if (std::isfinite(m.tau_s)) {
    const Complex s = j * m.omega_rad_s;
    const Complex e = std::exp(-s * m.tau_s);
    const Complex g = (a * s + b) * e;
    m.crossing_direction = (s * g / (2.0 * s + a * e - m.tau_s * g)).real();
  }
  return m;
}

FactorDelayMargin ComputeFactorDelayMargin(const std::vector<Complex>& eigenvalues, double k1,
                                           double k2, const Lipschitz& l) {
  FactorDelayMargin f;
  if (!l.slopes_known) return f;
  f.available = true;
  f.stable_at_zero = true;
  f.tau_s = std::numeric_limits<double>::infinity();
  for (const Complex& lambda : eigenvalues) {
    for (int c = 0; c < 5; ++c) {
      for (int gi = 0; gi < 2; ++gi) {
        for (int ji = 2; ji < 4; ++ji) {
          const double g = l.slopes(c, gi), jv = l.slopes(c, ji);
          const EigenMargin m = GeneralDelayMargin(lambda * k2 - jv, lambda * k1 - g);
          const double tau = m.stable_at_zero ? m.tau_s : 0.0;
          if (!m.stable_at_zero) f.stable_at_zero = false;
          if (tau < f.tau_s) {
            f.tau_s = tau;
            f.lambda = lambda;
            f.component = c;
            f.x_slope = g;
            f.v_slope = jv;
            f.omega_rad_s = m.omega_rad_s;
          }
        }
      }
    }
  }
  return f;
}

}  // namespace theory
}  // namespace shoal
