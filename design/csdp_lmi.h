// A small linear-matrix-inequality front end for CSDP (Borchers 1999, "CSDP, a C library
// for semidefinite programming"; Debian package libsdp-dev).
//
// Problem (CSDP's dual form, the natural form of an LMI):
//   minimise   cᵀy
//   subject to F_b(y) = F_b0 + Σ_i y_i F_bi ⪰ 0   for every block b,
// with y ∈ R^k free, each F_bi, F_b0 symmetric. A "diagonal" block is a vector of scalar
// inequalities (an LP block). CSDP is called with printlevel 0 and explicit parameters
// (it never reads param.csdp from the working directory and prints nothing).
#pragma once

#include <Eigen/Dense>
#include <string>
#include <vector>

namespace shoal::design {

class LmiProblem {
 public:
  /// Adds a block of size `size` (>= 1); `diagonal` makes it a block of scalar
  /// inequalities (only diagonal coefficients allowed). Returns the block index.
  int AddBlock(int size, bool diagonal = false);
  /// Adds a free scalar variable with objective coefficient `cost`. Returns its index.
  int AddVariable(double cost);
  /// F_bv += coeff (symmetric; only the upper triangle is read). Zeros are skipped.
  void AddCoefficient(int variable, int block, const Eigen::MatrixXd& coeff);
  /// One entry of F_bv (and its mirror): F_bv(i,j) += value, 0-based.
  void AddCoefficientEntry(int variable, int block, int i, int j, double value);
  /// F_b0 += constant (symmetric; only the upper triangle is read).
  void AddConstant(int block, const Eigen::MatrixXd& constant);

  int num_variables() const { return static_cast<int>(cost_.size()); }
  int num_blocks() const { return static_cast<int>(blocks_.size()); }

  /// F_b(y), for checking a solution outside the solver.
  Eigen::MatrixXd Evaluate(int block, const Eigen::VectorXd& y) const;

  /// Checks what CSDP would otherwise reject with exit(): at least one variable, every
  /// variable used in some block, indices in range, all numbers finite, off-diagonal
  /// entries only in matrix blocks.
  bool IsValid(std::string* why) const;

  struct Entry {
    int block, i, j;  // 0-based, i <= j
    double value;
  };
  struct Block {
    int size;
    bool diagonal;
  };
  const std::vector<Block>& blocks() const { return blocks_; }
  const std::vector<double>& cost() const { return cost_; }
  const std::vector<std::vector<Entry>>& coefficients() const { return coeff_; }
  const std::vector<Eigen::MatrixXd>& constants() const { return constant_; }

 private:
  std::vector<Block> blocks_;
  std::vector<double> cost_;
  std::vector<std::vector<Entry>> coeff_;  // per variable, unmerged (merged at solve time)
  std::vector<Eigen::MatrixXd> constant_;  // per block, full symmetric
};

struct CsdpOptions {
  int max_iterations = 100;  // CSDP maxiter (its default)
  double tolerance = 1e-8;   // CSDP axtol = atytol = objtol (its defaults)
};

/// CSDP's return codes (sdp.c): 0 solved, 1 primal infeasible, 2 dual infeasible,
/// 3 solved to reduced accuracy, 4 maximum iterations, 5 stuck at the edge of primal
/// feasibility, 6 stuck at the edge of dual feasibility, 7 lack of progress, 8 X, Z or O
/// singular, 9 NaN or Inf detected, 10 stopped by a signal. We add -1: the problem was
/// not passed to CSDP because it is malformed (see `message`).
struct CsdpSolution {
  int return_code = -1;
  std::string message;                 // CsdpReturnCodeMeaning(), or why the problem was rejected
  Eigen::VectorXd y;                   // the LMI variables (empty if not solved)
  double objective = 0.0;              // cᵀy at the returned point (CSDP's dual objective)
  double csdp_primal_objective = 0.0;  // CSDP's primal objective (the lower bound)
  double seconds = 0.0;                // wall time inside CSDP, set-up included
  /// True for codes 0 and 3: y is an (approximate) optimum worth checking.
  bool solved() const { return return_code == 0 || return_code == 3; }
};

/// Text for a CSDP return code, phrased for the LMI form above (CSDP's "dual" problem
/// is the LMI; its "primal" is the Lagrange dual of the LMI).
std::string CsdpReturnCodeMeaning(int code);

/// Solves the problem with CSDP. Never prints, never exits: a malformed problem gives
/// return_code -1 with a message.
CsdpSolution SolveWithCsdp(const LmiProblem& problem, const CsdpOptions& options = {});

}  // namespace shoal::design
