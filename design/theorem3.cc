#include "design/theorem3.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>
#include <vector>

#include <nlohmann/json.hpp>

namespace shoal::design {
namespace {

using Eigen::MatrixXd;

constexpr double kInf = std::numeric_limits<double>::infinity();

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

MatrixXd SystemA(int n) {
  MatrixXd a = MatrixXd::Zero(2 * n, 2 * n);
  a.topRightCorner(n, n).setIdentity();
  return a;
}

MatrixXd SystemB(const MatrixXd& H, double k1, double k2) {
  const int n = static_cast<int>(H.rows());
  MatrixXd b = MatrixXd::Zero(2 * n, 2 * n);
  b.bottomLeftCorner(n, n) = -k1 * H;
  b.bottomRightCorner(n, n) = -k2 * H;
  return b;
}

MatrixXd SystemE2(int n) {
  MatrixXd e = MatrixXd::Zero(2 * n, n);
  e.bottomRows(n).setIdentity();
  return e;
}

double MinEig(const MatrixXd& m) {
  if (m.size() == 0 || !m.allFinite()) return -kInf;
  const MatrixXd s = 0.5 * (m + m.transpose());
  Eigen::SelfAdjointEigenSolver<MatrixXd> es(s, Eigen::EigenvaluesOnly);
  return es.eigenvalues()(0);
}

double MaxEig(const MatrixXd& m) {
  if (m.size() == 0 || !m.allFinite()) return kInf;
  const MatrixXd s = 0.5 * (m + m.transpose());
  Eigen::SelfAdjointEigenSolver<MatrixXd> es(s, Eigen::EigenvaluesOnly);
  return es.eigenvalues()(es.eigenvalues().size() - 1);
}

// A matrix-valued decision variable laid out in the SDP's variable vector.
struct MatrixVariable {
  enum Kind { kSymmetric, kFull, kDiagonal };
  Kind kind = kSymmetric;
  int rows = 0;
  int first = 0;                             // index of its first scalar variable
  std::vector<std::pair<int, int>> entries;  // (i, j) of each scalar, i <= j if symmetric

  static MatrixVariable Make(Kind kind, int rows, LmiProblem* p) {
    MatrixVariable v;
    v.kind = kind;
    v.rows = rows;
    v.first = p->num_variables();
    for (int j = 0; j < rows; ++j) {
      for (int i = 0; i < rows; ++i) {
        const bool take =
            kind == kFull || (kind == kSymmetric && i <= j) || (kind == kDiagonal && i == j);
        if (take) {
          v.entries.emplace_back(i, j);
          p->AddVariable(0.0);
        }
      }
    }
    return v;
  }
  int size() const { return static_cast<int>(entries.size()); }
  // The matrix when scalar q is 1 and all others 0.
  MatrixXd Basis(int q) const {
    MatrixXd e = MatrixXd::Zero(rows, rows);
    const auto [i, j] = entries[q];
    e(i, j) = 1.0;
    if (kind == kSymmetric) e(j, i) = 1.0;
    return e;
  }
  MatrixXd Value(const Eigen::VectorXd& y) const {
    MatrixXd m = MatrixXd::Zero(rows, rows);
    for (int q = 0; q < size(); ++q) {
      const auto [i, j] = entries[q];
      m(i, j) = y(first + q);
      if (kind == kSymmetric) m(j, i) = y(first + q);
    }
    return m;
  }
};

Theorem3Multipliers Zeros(int n) {
  const int m = 2 * n;
  return {MatrixXd::Zero(m, m), MatrixXd::Zero(m, m), MatrixXd::Zero(m, m),
          MatrixXd::Zero(m, m), MatrixXd::Zero(m, m), MatrixXd::Zero(n, n)};
}

std::string FormName(Theorem3Form f) {
  return f == Theorem3Form::kCorrected ? "corrected" : "as_printed";
}

}  // namespace

bool Theorem3Input::IsValid(std::string* why) const {
  std::ostringstream m;
  if (H.rows() == 0 || H.rows() != H.cols()) {
    m << "H must be a non-empty square matrix (got " << H.rows() << "x" << H.cols() << ")";
  } else if (!H.allFinite()) {
    m << "H has a non-finite entry";
  } else if (!std::isfinite(k1) || k1 <= 0.0) {
    m << "k1 must be a finite number > 0 (got " << k1 << ")";
  } else if (!std::isfinite(k2) || k2 <= 0.0) {
    m << "k2 must be a finite number > 0 (got " << k2 << ")";
  } else if (!std::isfinite(h_s) || h_s < 0.0) {
    m << "h (delay bound) must be a finite number >= 0 s (got " << h_s << ")";
  } else if (!std::isfinite(kappa) || kappa < 0.0 || kappa >= 1.0) {
    m << "kappa (bound on the delay rate) must satisfy 0 <= kappa < 1 (got " << kappa << ")";
  } else if (!std::isfinite(lambda_G2) || lambda_G2 < 0.0) {
    m << "lambda_max(G^2) must be a finite number >= 0 (got " << lambda_G2 << ")";
  } else if (!std::isfinite(lambda_J2) || lambda_J2 < 0.0) {
    m << "lambda_max(J^2) must be a finite number >= 0 (got " << lambda_J2 << ")";
  }
  if (why) *why = m.str();
  return m.str().empty();
}

Theorem3Multipliers PaperMultipliers(int n) {
  const int m = 2 * n;
  return {MatrixXd::Zero(m, m),     0.1 * MatrixXd::Identity(m, m),
          MatrixXd::Identity(m, m), 0.3 * MatrixXd::Identity(m, m),
          MatrixXd::Zero(m, m),     0.6 * MatrixXd::Identity(n, n)};
}

MatrixXd AssembleXi(const Theorem3Input& in, const Theorem3Multipliers& mu) {
  const int n = static_cast<int>(in.H.rows());
  const int m = 2 * n;
  const double h = in.h_s;
  const double c = 1.0 - in.kappa;
  const MatrixXd A = SystemA(n);
  const MatrixXd B = SystemB(in.H, in.k1, in.k2);
  const MatrixXd E2 = SystemE2(n);
  const MatrixXd& Q = mu.Q;
  const MatrixXd& Z = mu.Z;

  MatrixXd Q1 = MatrixXd::Zero(m, m);
  Q1.topLeftCorner(n, n) = 2.0 * in.lambda_G2 * mu.Phi;
  Q1.bottomRightCorner(n, n) = 2.0 * in.lambda_J2 * mu.Phi;
  const MatrixXd ZA = Z * A, ZB = Z * B, ZE2 = Z * E2;  // ZE2 = C2

  const MatrixXd x11 = Q * A + A.transpose() * Q + h * mu.X + mu.Y + mu.Y.transpose() +
                       h * A.transpose() * ZA + mu.Psi + Q1;
  const MatrixXd x12 = Q * B - mu.Y + h * A.transpose() * ZB;
  MatrixXd x13 = h * A.transpose() * ZE2;
  if (in.form == Theorem3Form::kCorrected) x13 += Q * E2;  // 2εᵀQ E2 F̃ from V̇1
  const MatrixXd x22 = -c * mu.Psi + h * B.transpose() * ZB;
  const MatrixXd x23 = h * B.transpose() * ZE2;
  const MatrixXd x33 = h * E2.transpose() * ZE2 - c * mu.Phi;

  MatrixXd xi(m + m + n, m + m + n);
  xi.block(0, 0, m, m) = x11;
  xi.block(0, m, m, m) = x12;
  xi.block(0, 2 * m, m, n) = x13;
  xi.block(m, 0, m, m) = x12.transpose();
  xi.block(m, m, m, m) = x22;
  xi.block(m, 2 * m, m, n) = x23;
  xi.block(2 * m, 0, n, m) = x13.transpose();
  xi.block(2 * m, m, n, m) = x23.transpose();
  xi.block(2 * m, 2 * m, n, n) = x33;
  return 0.5 * (xi + xi.transpose());
}

Theorem3Check CheckMultipliers(const Theorem3Input& in, const Theorem3Multipliers& mu) {
  Theorem3Check c;
  c.margin = -kInf;
  const int n = static_cast<int>(in.H.rows());
  const int m = 2 * n;
  auto square = [](const MatrixXd& x, int size) { return x.rows() == size && x.cols() == size; };
  if (n == 0 || !square(in.H, n) || !square(mu.Q, m) || !square(mu.Psi, m) || !square(mu.Z, m) ||
      !square(mu.X, m) || !square(mu.Y, m) || !square(mu.Phi, n)) {
    c.xi_max_eigenvalue = kInf;
    return c;  // wrong shapes: no certificate
  }
  MatrixXd xyz(2 * m, 2 * m);
  xyz << mu.X, mu.Y, mu.Y.transpose(), mu.Z;
  c.xi_max_eigenvalue = MaxEig(AssembleXi(in, mu));
  c.q_min_eigenvalue = MinEig(mu.Q);
  c.psi_min_eigenvalue = MinEig(mu.Psi);
  c.z_min_eigenvalue = MinEig(mu.Z);
  c.phi_min_eigenvalue = MinEig(mu.Phi);
  c.xyz_min_eigenvalue = MinEig(xyz);
  MatrixXd off = mu.Phi;
  off.diagonal().setZero();
  c.phi_off_diagonal = off.size() ? off.cwiseAbs().maxCoeff() : 0.0;
  c.scale = mu.Q.trace() + mu.Psi.trace() + mu.X.trace() + mu.Z.trace() + mu.Phi.trace();
  const double worst = std::min({-c.xi_max_eigenvalue, c.q_min_eigenvalue, c.psi_min_eigenvalue,
                                 c.phi_min_eigenvalue, c.xyz_min_eigenvalue});
  c.margin =
      (std::isfinite(worst) && c.scale > 0.0 && std::isfinite(c.scale)) ? worst / c.scale : -kInf;
  // The corrected Q1 bound is valid for a diagonal Φ only.
  if (in.form == Theorem3Form::kCorrected && c.phi_off_diagonal != 0.0) c.margin = -kInf;
  return c;
}

namespace {

// The feasibility SDP of CheckTheorem3: its variables and blocks.
struct Theorem3Sdp {
  using MV = MatrixVariable;
  LmiProblem p;
  MV Q, Psi, Z, X, Y, Phi;
  int t = -1;
  int b_xi = -1, b_q = -1, b_psi = -1, b_xyz = -1, b_phi = -1, b_lp = -1;
  int norm_row = 0;
};

void DeclareVariablesAndBlocks(int n, bool corrected, Theorem3Sdp* sdp) {
  using MV = MatrixVariable;
  const int m = 2 * n;
  LmiProblem& p = sdp->p;
  sdp->Q = MV::Make(MV::kSymmetric, m, &p);
  sdp->Psi = MV::Make(MV::kSymmetric, m, &p);
  sdp->Z = MV::Make(MV::kSymmetric, m, &p);
  sdp->X = MV::Make(MV::kSymmetric, m, &p);
  sdp->Y = MV::Make(MV::kFull, m, &p);
  sdp->Phi = MV::Make(corrected ? MV::kDiagonal : MV::kSymmetric, n, &p);
  sdp->t = p.AddVariable(-1.0);  // maximise t

  sdp->b_xi = p.AddBlock(5 * n);
  sdp->b_q = p.AddBlock(m);
  sdp->b_psi = p.AddBlock(m);
  sdp->b_xyz = p.AddBlock(2 * m);
  // Corrected form: φ_i − t >= 0 (i < n) and the normalisation in one LP block.
  // As printed: Φ − tI ⪰ 0 as a matrix block and the normalisation as an LP block.
  sdp->b_phi = corrected ? -1 : p.AddBlock(n);
  sdp->b_lp = p.AddBlock(corrected ? n + 1 : 1, /*diagonal=*/true);
  sdp->norm_row = corrected ? n : 0;
}

// −Ξ − tI ⪰ 0: Ξ is linear in the multipliers, so each scalar's coefficient is −Ξ at its
// basis matrix (the same AssembleXi the Eigen check uses).
void AddXiBlock(const Theorem3Input& in, Theorem3Sdp* sdp) {
  const int n = static_cast<int>(in.H.rows());
  auto xi_coefficient = [&](const MatrixVariable& var, MatrixXd Theorem3Multipliers::*field) {
    for (int q = 0; q < var.size(); ++q) {
      Theorem3Multipliers mu = Zeros(n);
      mu.*field = var.Basis(q);
      sdp->p.AddCoefficient(var.first + q, sdp->b_xi, -AssembleXi(in, mu));
    }
  };
  xi_coefficient(sdp->Q, &Theorem3Multipliers::Q);
  xi_coefficient(sdp->Psi, &Theorem3Multipliers::Psi);
  xi_coefficient(sdp->Z, &Theorem3Multipliers::Z);
  xi_coefficient(sdp->X, &Theorem3Multipliers::X);
  xi_coefficient(sdp->Y, &Theorem3Multipliers::Y);
  xi_coefficient(sdp->Phi, &Theorem3Multipliers::Phi);
  sdp->p.AddCoefficient(sdp->t, sdp->b_xi, -MatrixXd::Identity(5 * n, 5 * n));
}

// Q − tI ⪰ 0, Ψ − tI ⪰ 0 and [X Y; Yᵀ Z] − tI ⪰ 0.
void AddDefinitenessBlocks(int m, Theorem3Sdp* sdp) {
  LmiProblem& p = sdp->p;
  const MatrixVariable &Q = sdp->Q, &Psi = sdp->Psi, &X = sdp->X, &Y = sdp->Y, &Z = sdp->Z;
  for (int q = 0; q < Q.size(); ++q) p.AddCoefficient(Q.first + q, sdp->b_q, Q.Basis(q));
  p.AddCoefficient(sdp->t, sdp->b_q, -MatrixXd::Identity(m, m));
  for (int q = 0; q < Psi.size(); ++q) p.AddCoefficient(Psi.first + q, sdp->b_psi, Psi.Basis(q));
  p.AddCoefficient(sdp->t, sdp->b_psi, -MatrixXd::Identity(m, m));

  for (int q = 0; q < X.size(); ++q) {
    MatrixXd e = MatrixXd::Zero(2 * m, 2 * m);
    e.topLeftCorner(m, m) = X.Basis(q);
    p.AddCoefficient(X.first + q, sdp->b_xyz, e);
  }
  for (int q = 0; q < Y.size(); ++q) {
    MatrixXd e = MatrixXd::Zero(2 * m, 2 * m);
    e.topRightCorner(m, m) = Y.Basis(q);
    e.bottomLeftCorner(m, m) = Y.Basis(q).transpose();
    p.AddCoefficient(Y.first + q, sdp->b_xyz, e);
  }
  for (int q = 0; q < Z.size(); ++q) {
    MatrixXd e = MatrixXd::Zero(2 * m, 2 * m);
    e.bottomRightCorner(m, m) = Z.Basis(q);
    p.AddCoefficient(Z.first + q, sdp->b_xyz, e);
  }
  p.AddCoefficient(sdp->t, sdp->b_xyz, -MatrixXd::Identity(2 * m, 2 * m));
}

// Φ − tI ⪰ 0 (per entry in the corrected form) and 1 − (tr Q + tr Ψ + tr X + tr Z + tr Φ) >= 0.
void AddPhiAndNormalisation(int n, bool corrected, Theorem3Sdp* sdp) {
  LmiProblem& p = sdp->p;
  const MatrixVariable& Phi = sdp->Phi;
  if (corrected) {
    for (int i = 0; i < n; ++i) {
      p.AddCoefficientEntry(Phi.first + i, sdp->b_lp, i, i, 1.0);
      p.AddCoefficientEntry(sdp->t, sdp->b_lp, i, i, -1.0);
    }
  } else {
    for (int q = 0; q < Phi.size(); ++q) p.AddCoefficient(Phi.first + q, sdp->b_phi, Phi.Basis(q));
    p.AddCoefficient(sdp->t, sdp->b_phi, -MatrixXd::Identity(n, n));
  }
  const int rows = corrected ? n + 1 : 1;
  MatrixXd one = MatrixXd::Zero(rows, rows);
  one(sdp->norm_row, sdp->norm_row) = 1.0;
  p.AddConstant(sdp->b_lp, one);
  for (const MatrixVariable* var : {&sdp->Q, &sdp->Psi, &sdp->X, &sdp->Z, &sdp->Phi}) {
    for (int q = 0; q < var->size(); ++q) {
      if (var->entries[q].first == var->entries[q].second) {
        p.AddCoefficientEntry(var->first + q, sdp->b_lp, sdp->norm_row, sdp->norm_row, -1.0);
      }
    }
  }
}

// The solver's answer, re-checked with Eigen, and the one-line message.
void ReadSolution(const Theorem3Sdp& sdp, const CsdpSolution& s, const Theorem3Options& options,
                  Theorem3Result* r) {
  const Theorem3Input& in = r->input;
  r->csdp_return_code = s.return_code;
  r->csdp_status = s.message;
  if (s.y.size() == sdp.p.num_variables()) {
    r->certificate = {sdp.Q.Value(s.y), sdp.Psi.Value(s.y), sdp.Z.Value(s.y),
                      sdp.X.Value(s.y), sdp.Y.Value(s.y),   sdp.Phi.Value(s.y)};
    r->solver_margin = s.y(sdp.t);
    r->check = CheckMultipliers(in, r->certificate);
  } else {
    r->certificate = Zeros(static_cast<int>(in.H.rows()));
    r->solver_margin = 0.0;
    r->check.margin = -kInf;
  }
  std::ostringstream msg;
  char num[64];
  if (!s.solved()) {
    msg << "not certified: CSDP returned " << s.return_code << " (" << s.message << ")";
  } else if (!(r->check.margin >= options.strict_margin)) {
    std::snprintf(num, sizeof(num), "%.3g", r->check.margin);
    msg << "infeasible: the best multipliers found satisfy the LMI with margin " << num << " < "
        << options.strict_margin << " (normalised)";
  } else {
    r->feasible = true;
    std::snprintf(num, sizeof(num), "%.3g", r->check.margin);
    msg << "feasible: lambda_max(Xi) = " << r->check.xi_max_eigenvalue << ", normalised margin "
        << num;
    if (in.form != Theorem3Form::kCorrected) msg << " (as-printed form: not a proof)";
  }
  r->message = msg.str();
}

}  // namespace

Theorem3Result CheckTheorem3(const Theorem3Input& in, const Theorem3Options& options) {
  const auto start = std::chrono::steady_clock::now();
  Theorem3Result r;
  r.input = in;
  r.strict_margin = options.strict_margin;
  r.check.margin = -kInf;
  std::string why;
  if (!in.IsValid(&why)) {
    r.message = "invalid input: " + why;
    r.csdp_status = CsdpReturnCodeMeaning(-1);
    return r;
  }
  r.input_valid = true;
  const int n = static_cast<int>(in.H.rows());
  const bool corrected = in.form == Theorem3Form::kCorrected;
  Theorem3Sdp sdp;
  DeclareVariablesAndBlocks(n, corrected, &sdp);
  AddXiBlock(in, &sdp);
  AddDefinitenessBlocks(2 * n, &sdp);
  AddPhiAndNormalisation(n, corrected, &sdp);
  r.lmi_variables = sdp.p.num_variables();
  ReadSolution(sdp, SolveWithCsdp(sdp.p, options.csdp), options, &r);
  r.seconds = Seconds(start);
  return r;
}

MaxDelayResult MaxDelayTheorem3(Theorem3Input in, double tol_s, const Theorem3Options& options,
                                double h_cap_s) {
  const auto start = std::chrono::steady_clock::now();
  MaxDelayResult r;
  r.h_cap_s = h_cap_s;
  in.h_s = 0.0;
  std::string why;
  if (!in.IsValid(&why)) {
    r.message = "invalid input: " + why;
    return r;
  }
  if (!(tol_s > 0.0) || !std::isfinite(tol_s) || !(h_cap_s > 0.0) || !std::isfinite(h_cap_s)) {
    r.message = "invalid search: tolerance and cap must be finite and > 0";
    return r;
  }
  r.input_valid = true;
  auto feasible_at = [&](double h, Theorem3Result* keep) {
    in.h_s = h;
    Theorem3Result res = CheckTheorem3(in, options);
    ++r.solves;
    if (res.csdp_return_code != 0 && res.csdp_return_code != 3) ++r.solver_failures;
    const bool ok = res.feasible;
    if (ok && keep) *keep = std::move(res);
    return ok;
  };

  if (!feasible_at(0.0, &r.at_max)) {
    r.feasible_at_zero = false;
    r.max_delay_s = 0.0;
    r.infeasible_from_s = 0.0;
    r.message =
        "infeasible at h = 0: Theorem 3 certifies no delay for these gains and "
        "Lipschitz data";
    r.seconds = Seconds(start);
    return r;
  }
  r.feasible_at_zero = true;
  double lo = 0.0, hi = std::min(0.1, h_cap_s);
  while (feasible_at(hi, &r.at_max)) {
    lo = hi;
    if (hi >= h_cap_s) {
      r.hit_cap = true;
      r.max_delay_s = hi;
      r.infeasible_from_s = kInf;
      r.message = "feasible up to the search cap h = " + std::to_string(h_cap_s) + " s";
      r.seconds = Seconds(start);
      return r;
    }
    hi = std::min(2.0 * hi, h_cap_s);
  }
  while (hi - lo > tol_s) {
    const double mid = 0.5 * (lo + hi);
    if (feasible_at(mid, &r.at_max)) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  r.max_delay_s = lo;
  r.infeasible_from_s = hi;
  std::ostringstream msg;
  msg << "feasible for h <= " << lo << " s, infeasible at " << hi << " s";
  if (r.solver_failures > 0) {
    msg << " (" << r.solver_failures << " CSDP failures counted as infeasible)";
  }
  r.message = msg.str();
  r.seconds = Seconds(start);
  return r;
}

PaperMultipliersResult PaperMultipliersMaxEigenvalue(const Theorem3Input& in,
                                                     const Theorem3Options& options, double q_min) {
  const auto start = std::chrono::steady_clock::now();
  PaperMultipliersResult r;
  r.q_min = q_min;
  std::string why;
  if (!in.IsValid(&why)) {
    r.message = "invalid input: " + why;
    r.csdp_status = CsdpReturnCodeMeaning(-1);
    return r;
  }
  if (!std::isfinite(q_min) || q_min < 0.0) {
    r.message = "invalid input: q_min must be a finite number >= 0";
    r.csdp_status = CsdpReturnCodeMeaning(-1);
    return r;
  }
  r.input_valid = true;
  const int n = static_cast<int>(in.H.rows());
  const int m = 2 * n;
  const Theorem3Multipliers paper = PaperMultipliers(n);

  LmiProblem p;
  const MatrixVariable Q = MatrixVariable::Make(MatrixVariable::kSymmetric, m, &p);
  const int t = p.AddVariable(1.0);  // minimise t
  const int b_xi = p.AddBlock(5 * n);
  const int b_q = p.AddBlock(m);
  // tI − Ξ(Q) ⪰ 0 with Ξ(Q) = Ξ(0; paper) + Ξ(Q; 0).
  p.AddConstant(b_xi, -AssembleXi(in, paper));
  for (int q = 0; q < Q.size(); ++q) {
    Theorem3Multipliers mu = Zeros(n);
    mu.Q = Q.Basis(q);
    p.AddCoefficient(Q.first + q, b_xi, -AssembleXi(in, mu));
    p.AddCoefficient(Q.first + q, b_q, Q.Basis(q));
  }
  p.AddCoefficient(t, b_xi, MatrixXd::Identity(5 * n, 5 * n));
  p.AddConstant(b_q, -q_min * MatrixXd::Identity(m, m));

  const CsdpSolution s = SolveWithCsdp(p, options.csdp);
  r.csdp_return_code = s.return_code;
  r.csdp_status = s.message;
  r.solved = s.solved();
  if (s.y.size() == p.num_variables()) {
    r.Q = Q.Value(s.y);
    r.solver_value = s.y(t);
    Theorem3Multipliers mu = paper;
    mu.Q = r.Q;
    r.max_eigenvalue = MaxEig(AssembleXi(in, mu));
  } else {
    r.max_eigenvalue = kInf;
  }
  std::ostringstream msg;
  if (!r.solved) {
    msg << "CSDP returned " << s.return_code << " (" << s.message << ")";
  } else {
    msg << "min over Q of lambda_max(Xi) with the paper's X, Y, Z, Psi, Phi: " << r.max_eigenvalue
        << (r.max_eigenvalue < 0.0 ? " (certifies)" : " (no certificate)");
  }
  r.message = msg.str();
  r.seconds = Seconds(start);
  return r;
}

namespace {

using Json = nlohmann::ordered_json;

// nlohmann writes a double in its shortest round-trip form (so a certificate re-reads to
// the same matrices) and a non-finite one as null.
Json MatrixJson(const MatrixXd& m) {
  Json rows = Json::array();
  for (int i = 0; i < m.rows(); ++i) {
    Json row = Json::array();
    for (int j = 0; j < m.cols(); ++j) row.push_back(m(i, j));
    rows.push_back(std::move(row));
  }
  return rows;
}

Json CheckJson(const Theorem3Check& c) {
  Json j;
  j["margin"] = c.margin;
  j["xi_max_eigenvalue"] = c.xi_max_eigenvalue;
  j["q_min_eigenvalue"] = c.q_min_eigenvalue;
  j["psi_min_eigenvalue"] = c.psi_min_eigenvalue;
  j["z_min_eigenvalue"] = c.z_min_eigenvalue;
  j["phi_min_eigenvalue"] = c.phi_min_eigenvalue;
  j["xyz_min_eigenvalue"] = c.xyz_min_eigenvalue;
  j["scale"] = c.scale;
  return j;
}

}  // namespace

std::string CertificateJson(const Theorem3Result& r) {
  const Theorem3Input& in = r.input;
  Json o;
  o["theorem"] = 3;
  o["form"] = FormName(in.form);
  o["n"] = in.H.rows();
  o["k1"] = in.k1;
  o["k2"] = in.k2;
  o["h_s"] = in.h_s;
  o["kappa"] = in.kappa;
  o["lambda_G2"] = in.lambda_G2;
  o["lambda_J2"] = in.lambda_J2;
  o["H"] = MatrixJson(in.H);
  o["feasible"] = r.feasible;
  o["certifies"] = r.certifies();
  o["message"] = r.message;
  o["csdp_return_code"] = r.csdp_return_code;
  o["csdp_status"] = r.csdp_status;
  o["solver_margin"] = r.solver_margin;
  o["strict_margin"] = r.strict_margin;
  o["check"] = CheckJson(r.check);
  const Theorem3Multipliers& c = r.certificate;
  o["matrices"] = {{"Q", MatrixJson(c.Q)}, {"Psi", MatrixJson(c.Psi)}, {"Z", MatrixJson(c.Z)},
                   {"X", MatrixJson(c.X)}, {"Y", MatrixJson(c.Y)},     {"Phi", MatrixJson(c.Phi)}};
  // replace: a scenario name that is not valid UTF-8 must not abort the certificate.
  return o.dump(2, ' ', false, Json::error_handler_t::replace) + "\n";
}

bool WriteCertificate(const Theorem3Result& result, const std::string& path, std::string* err) {
  std::ofstream f(path);
  if (!f) {
    if (err) *err = "cannot open " + path + " for writing";
    return false;
  }
  f << CertificateJson(result);
  f.close();
  if (!f) {
    if (err) *err = "error while writing " + path;
    return false;
  }
  return true;
}

}  // namespace shoal::design
