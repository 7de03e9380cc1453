#include "design/csdp_lmi.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <tuple>

extern "C" {
#include <csdp/declarations.h>
}

namespace shoal::design {

int LmiProblem::AddBlock(int size, bool diagonal) {
  blocks_.push_back({size, diagonal});
  constant_.push_back(Eigen::MatrixXd::Zero(std::max(size, 0), std::max(size, 0)));
  return static_cast<int>(blocks_.size()) - 1;
}

int LmiProblem::AddVariable(double cost) {
  cost_.push_back(cost);
  coeff_.emplace_back();
  return static_cast<int>(cost_.size()) - 1;
}

void LmiProblem::AddCoefficientEntry(int variable, int block, int i, int j, double value) {
  if (value == 0.0) return;
  if (i > j) std::swap(i, j);
  coeff_.at(variable).push_back({block, i, j, value});
}

void LmiProblem::AddCoefficient(int variable, int block, const Eigen::MatrixXd& coeff) {
  for (int j = 0; j < coeff.cols(); ++j) {
    for (int i = 0; i <= j && i < coeff.rows(); ++i) {
      AddCoefficientEntry(variable, block, i, j, coeff(i, j));
    }
  }
}

void LmiProblem::AddConstant(int block, const Eigen::MatrixXd& constant) {
  Eigen::MatrixXd& c = constant_.at(block);
  for (int j = 0; j < c.cols() && j < constant.cols(); ++j) {
    for (int i = 0; i <= j && i < constant.rows(); ++i) {
      c(i, j) += constant(i, j);
      if (i != j) c(j, i) = c(i, j);
    }
  }
}

Eigen::MatrixXd LmiProblem::Evaluate(int block, const Eigen::VectorXd& y) const {
  Eigen::MatrixXd f = constant_.at(block);
  for (int v = 0; v < num_variables() && v < y.size(); ++v) {
    for (const Entry& e : coeff_[v]) {
      if (e.block != block) continue;
      f(e.i, e.j) += y(v) * e.value;
      if (e.i != e.j) f(e.j, e.i) += y(v) * e.value;
    }
  }
  return f;
}

bool LmiProblem::IsValid(std::string* why) const {
  std::ostringstream msg;
  if (blocks_.empty()) msg << "the LMI has no blocks";
  if (cost_.empty()) msg << "the LMI has no variables";
  for (size_t b = 0; b < blocks_.size() && msg.str().empty(); ++b) {
    if (blocks_[b].size < 1) msg << "block " << b << " has size " << blocks_[b].size;
    if (!constant_[b].allFinite()) msg << "block " << b << " has a non-finite constant term";
    if (blocks_[b].diagonal && !constant_[b].isDiagonal(0.0)) {
      msg << "diagonal block " << b << " has an off-diagonal constant";
    }
  }
  for (size_t v = 0; v < cost_.size() && msg.str().empty(); ++v) {
    if (!std::isfinite(cost_[v])) msg << "variable " << v << " has a non-finite cost";
    bool used = false;
    for (const Entry& e : coeff_[v]) {
      if (e.block < 0 || e.block >= num_blocks() || e.i < 0 || e.j >= blocks_[e.block].size) {
        msg << "variable " << v << " has an entry outside block " << e.block;
        break;
      }
      if (!std::isfinite(e.value)) {
        msg << "variable " << v << " has a non-finite coefficient in block " << e.block;
        break;
      }
      if (blocks_[e.block].diagonal && e.i != e.j) {
        msg << "variable " << v << " has an off-diagonal entry in diagonal block " << e.block;
        break;
      }
      used = true;
    }
    if (msg.str().empty() && !used) msg << "variable " << v << " appears in no block";
  }
  if (why) *why = msg.str();
  return msg.str().empty();
}

std::string CsdpReturnCodeMeaning(int code) {
  switch (code) {
    case -1:
      return "problem rejected before calling CSDP";
    case 0:
      return "solved to full accuracy";
    case 1:
      return "LMI objective unbounded below (CSDP primal infeasible, certificate found)";
    case 2:
      return "LMI constraints infeasible (CSDP dual infeasible, certificate found)";
    case 3:
      return "solved to reduced accuracy (partial success)";
    case 4:
      return "failure: maximum iterations reached";
    case 5:
      return "failure: stuck at the edge of primal feasibility";
    case 6:
      return "failure: stuck at the edge of dual feasibility";
    case 7:
      return "failure: lack of progress";
    case 8:
      return "failure: X, Z or O was singular";
    case 9:
      return "failure: NaN or Inf detected";
    case 10:
      return "failure: stopped by a signal";
    default:
      return "unknown CSDP return code " + std::to_string(code);
  }
}

namespace {

template <typename T>
T* Alloc(size_t count) {
  // CSDP frees what it is given with free(): allocate with calloc.
  return static_cast<T*>(std::calloc(count, sizeof(T)));
}

// Owns every CSDP structure of one solve and frees it on every path.
struct CsdpWorkspace {
  int n = 0, k = 0;
  blockmatrix C{0, nullptr}, X{0, nullptr}, Z{0, nullptr};
  double* a = nullptr;
  double* y = nullptr;
  constraintmatrix* constraints = nullptr;
  bool solution_allocated = false;

  blockmatrix work1{0, nullptr}, work2{0, nullptr}, work3{0, nullptr};
  blockmatrix bestx{0, nullptr}, bestz{0, nullptr}, cholxinv{0, nullptr}, cholzinv{0, nullptr};
  blockmatrix Zi{0, nullptr}, dZ{0, nullptr}, dX{0, nullptr};
  std::vector<double*> vectors;  // work vectors
  sparseblock** byblocks = nullptr;
  constraintmatrix fill{nullptr};
  bool work_allocated = false;

  ~CsdpWorkspace() {
    if (work_allocated) {
      free_mat(work1);
      free_mat(work2);
      free_mat(work3);
      free_mat_packed(bestx);
      free_mat_packed(bestz);
      free_mat_packed(cholxinv);
      free_mat_packed(cholzinv);
      free_mat(Zi);
      free_mat(dZ);
      free_mat(dX);
    }
    for (double* v : vectors) std::free(v);
    std::free(byblocks);
    for (sparseblock* p = fill.blocks; p != nullptr;) {
      sparseblock* next = p->next;
      std::free(p->entries);
      std::free(p->iindices);
      std::free(p->jindices);
      std::free(p);
      p = next;
    }
    if (solution_allocated) {
      free_prob(n, k, C, a, constraints, X, y, Z);
    } else {
      // free_prob frees C, a and constraints too; without a solution free them here.
      if (C.blocks) {
        for (int b = 1; b <= C.nblocks; ++b) std::free(C.blocks[b].data.mat);
        std::free(C.blocks);
      }
      std::free(a);
      if (constraints) {
        for (int i = 1; i <= k; ++i) {
          for (sparseblock* p = constraints[i].blocks; p != nullptr;) {
            sparseblock* next = p->next;
            std::free(p->entries);
            std::free(p->iindices);
            std::free(p->jindices);
            std::free(p);
            p = next;
          }
        }
        std::free(constraints);
      }
    }
  }

  double* Vec(size_t count) {
    vectors.push_back(Alloc<double>(count));
    return vectors.back();
  }
};

// C = -F0 (CSDP: sum_i y_i A_i - C = Z >= 0).
void FillCostMatrix(const LmiProblem& problem, CsdpWorkspace* ws) {
  const auto& blocks = problem.blocks();
  const int nblocks = problem.num_blocks();
  ws->C.nblocks = nblocks;
  ws->C.blocks = Alloc<blockrec>(nblocks + 1);
  for (int b = 0; b < nblocks; ++b) {
    blockrec& r = ws->C.blocks[b + 1];
    const int s = blocks[b].size;
    const Eigen::MatrixXd& f0 = problem.constants()[b];
    r.blocksize = s;
    if (blocks[b].diagonal) {
      r.blockcategory = DIAG;
      r.data.vec = Alloc<double>(s + 1);
      for (int i = 0; i < s; ++i) r.data.vec[i + 1] = -f0(i, i);
    } else {
      r.blockcategory = MATRIX;
      r.data.mat = Alloc<double>(static_cast<size_t>(s) * s);
      for (int j = 0; j < s; ++j) {
        for (int i = 0; i < s; ++i) {
          // Exactly symmetric (CSDP checks C == C^T bit for bit).
          r.data.mat[static_cast<size_t>(j) * s + i] = -f0(std::min(i, j), std::max(i, j));
        }
      }
    }
  }
  ws->a = Alloc<double>(ws->k + 1);
  for (int v = 0; v < ws->k; ++v) ws->a[v + 1] = problem.cost()[v];
}

// A variable's entries sorted by (block, j, i), duplicates summed, zeros dropped.
std::vector<LmiProblem::Entry> MergedEntries(std::vector<LmiProblem::Entry> e) {
  std::sort(e.begin(), e.end(), [](const auto& l, const auto& r) {
    return std::tie(l.block, l.j, l.i) < std::tie(r.block, r.j, r.i);
  });
  std::vector<LmiProblem::Entry> merged;
  for (const auto& x : e) {
    if (!merged.empty() && merged.back().block == x.block && merged.back().i == x.i &&
        merged.back().j == x.j) {
      merged.back().value += x.value;
    } else {
      merged.push_back(x);
    }
  }
  merged.erase(
      std::remove_if(merged.begin(), merged.end(), [](const auto& x) { return x.value == 0.0; }),
      merged.end());
  return merged;
}

// Constraint v + 1's list of sparse blocks, built in decreasing block order by prepending
// so that it ends up increasing.
void FillConstraint(const LmiProblem& problem, int v, const std::vector<LmiProblem::Entry>& merged,
                    CsdpWorkspace* ws) {
  const auto& blocks = problem.blocks();
  size_t end = merged.size();
  while (end > 0) {
    const int blk = merged[end - 1].block;
    size_t begin = end;
    while (begin > 0 && merged[begin - 1].block == blk) --begin;
    const int count = static_cast<int>(end - begin);
    sparseblock* p = Alloc<sparseblock>(1);
    p->blocknum = blk + 1;
    p->blocksize = blocks[blk].size;
    p->constraintnum = v + 1;
    p->numentries = count;
    p->entries = Alloc<double>(count + 1);
    p->iindices = Alloc<int>(count + 1);
    p->jindices = Alloc<int>(count + 1);
    for (int q = 0; q < count; ++q) {
      p->entries[q + 1] = merged[begin + q].value;
      p->iindices[q + 1] = merged[begin + q].i + 1;
      p->jindices[q + 1] = merged[begin + q].j + 1;
    }
    // Dense arithmetic pays off only when a block is well filled; both paths are exact.
    const long upper = static_cast<long>(p->blocksize) * (p->blocksize + 1) / 2;
    p->issparse = (blocks[blk].diagonal || 4L * count < upper) ? 1 : 0;
    p->next = ws->constraints[v + 1].blocks;
    p->nextbyblock = nullptr;
    ws->constraints[v + 1].blocks = p;
    end = begin;
  }
}

// Constraint matrices A_i = F_i, merged, sorted, upper triangle, 1-based; then, per block,
// the chain of every constraint's entry for that block, in constraint order. Returns "" or
// why the problem is malformed.
std::string FillConstraints(const LmiProblem& problem, CsdpWorkspace* ws) {
  const int k = ws->k;
  const int nblocks = problem.num_blocks();
  ws->constraints = Alloc<constraintmatrix>(k + 1);
  for (int v = 0; v < k; ++v) {
    const std::vector<LmiProblem::Entry> merged = MergedEntries(problem.coefficients()[v]);
    if (merged.empty()) {
      return "malformed LMI: variable " + std::to_string(v) +
             " has coefficients that cancel to zero in every block";
    }
    FillConstraint(problem, v, merged, ws);
  }
  ws->byblocks = Alloc<sparseblock*>(nblocks + 1);
  std::vector<sparseblock*> last(nblocks + 1, nullptr);
  for (int v = 1; v <= k; ++v) {
    for (sparseblock* p = ws->constraints[v].blocks; p != nullptr; p = p->next) {
      if (last[p->blocknum] == nullptr) {
        ws->byblocks[p->blocknum] = p;
      } else {
        last[p->blocknum]->nextbyblock = p;
      }
      last[p->blocknum] = p;
    }
  }
  return "";
}

paramstruc CsdpParameters(const CsdpOptions& options) {
  paramstruc params;
  params.axtol = options.tolerance;
  params.atytol = options.tolerance;
  params.objtol = options.tolerance;
  params.pinftol = 1.0e8;
  params.dinftol = 1.0e8;
  params.maxiter = options.max_iterations;
  params.minstepfrac = 0.90;
  params.maxstepfrac = 0.97;
  params.minstepp = 1.0e-8;
  params.minstepd = 1.0e-8;
  params.usexzgap = 1;
  params.tweakgap = 0;
  params.affine = 0;
  params.perturbobj = 1;
  params.fastmode = 0;
  return params;
}

// Working storage as CSDP's sdp() expects it, the initial point, and the solve itself.
int RunSdp(const CsdpOptions& options, CsdpWorkspace* ws, double* pobj, double* dobj) {
  const int k = ws->k;
  alloc_mat(ws->C, &ws->work1);
  alloc_mat(ws->C, &ws->work2);
  alloc_mat(ws->C, &ws->work3);
  alloc_mat_packed(ws->C, &ws->bestx);
  alloc_mat_packed(ws->C, &ws->bestz);
  alloc_mat_packed(ws->C, &ws->cholxinv);
  alloc_mat_packed(ws->C, &ws->cholzinv);
  alloc_mat(ws->C, &ws->Zi);
  alloc_mat(ws->C, &ws->dZ);
  alloc_mat(ws->C, &ws->dX);
  ws->work_allocated = true;
  const size_t nk = static_cast<size_t>(std::max(ws->n, k)) + 1;
  double* workvec[8];
  for (double*& w : workvec) w = ws->Vec(nk);
  double* diagO = ws->Vec(nk);
  double* besty = ws->Vec(k + 1);
  double* rhs = ws->Vec(k + 1);
  double* dy = ws->Vec(k + 1);
  double* dy1 = ws->Vec(k + 1);
  double* Fp = ws->Vec(k + 1);
  const size_t ldam = (k % 2 == 0) ? k + 1 : k;
  double* O = ws->Vec(ldam * ldam);

  const int printlevel = 0;
  makefill(k, ws->C, ws->constraints, &ws->fill, ws->work1, printlevel);
  sort_entries(k, ws->C, ws->constraints);
  initsoln(ws->n, k, ws->C, ws->a, ws->constraints, &ws->X, &ws->y, &ws->Z);
  ws->solution_allocated = true;
  return sdp(ws->n, k, ws->C, ws->a, 0.0, ws->constraints, ws->byblocks, ws->fill, ws->X, ws->y,
             ws->Z, ws->cholxinv, ws->cholzinv, pobj, dobj, ws->work1, ws->work2, ws->work3,
             workvec[0], workvec[1], workvec[2], workvec[3], workvec[4], workvec[5], workvec[6],
             workvec[7], diagO, ws->bestx, besty, ws->bestz, ws->Zi, O, rhs, ws->dZ, ws->dX, dy,
             dy1, Fp, printlevel, CsdpParameters(options));
}

}  // namespace

CsdpSolution SolveWithCsdp(const LmiProblem& problem, const CsdpOptions& options) {
  CsdpSolution out;
  std::string why;
  if (!problem.IsValid(&why)) {
    out.return_code = -1;
    out.message = "malformed LMI: " + why;
    return out;
  }
  if (options.max_iterations < 1 || !(options.tolerance > 0.0)) {
    out.return_code = -1;
    out.message = "CSDP options: max_iterations must be >= 1 and tolerance > 0";
    return out;
  }
  const auto start = std::chrono::steady_clock::now();
  CsdpWorkspace ws;
  ws.k = problem.num_variables();
  ws.n = 0;
  for (const auto& b : problem.blocks()) ws.n += b.size;
  FillCostMatrix(problem, &ws);
  if (const std::string e = FillConstraints(problem, &ws); !e.empty()) {
    out.return_code = -1;
    out.message = e;
    return out;
  }
  double pobj = 0.0, dobj = 0.0;
  const int ret = RunSdp(options, &ws, &pobj, &dobj);
  out.return_code = ret;
  out.message = CsdpReturnCodeMeaning(ret);
  out.y.resize(ws.k);
  for (int v = 0; v < ws.k; ++v) out.y(v) = ws.y[v + 1];
  out.objective = dobj;
  out.csdp_primal_objective = pobj;
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace shoal::design
