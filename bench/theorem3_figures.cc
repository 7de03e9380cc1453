// Theorem 3 figures for docs/theory_theorem3.md, measured (not a test): the LMI (27)-(28)
// with every multiplier free (CSDP), on the paper's topology, for the scenario's gains.
//   build/bench/theorem3_figures [k1 k2 h kappa lambda_G2 lambda_J2]
// Defaults: k1 = 0.18, k2 = 1.152 (scenarios/paper_example2.toml), h = 0.15 s,
// kappa = 0.05 (tau = 0.1 + 0.05 cos t), lambda_max(G^2) = 0.0004, lambda_max(J^2) = 0.25.
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <string>

#include "core/topology.h"
#include "design/theorem3.h"

using shoal::design::Theorem3Form;
using shoal::design::Theorem3Input;

namespace {

double CpuMs(std::clock_t since) {
  return 1e3 * static_cast<double>(std::clock() - since) / CLOCKS_PER_SEC;
}

void Report(const char* label, Theorem3Input in) {
  std::printf("== %s: k1=%g k2=%g h=%g kappa=%g lambda_G2=%g lambda_J2=%g form=%s\n", label, in.k1,
              in.k2, in.h_s, in.kappa, in.lambda_G2, in.lambda_J2,
              in.form == Theorem3Form::kCorrected ? "corrected" : "as_printed");
  std::clock_t c0 = std::clock();
  const auto r = shoal::design::CheckTheorem3(in);
  std::printf(
      "  at h=%g: feasible=%d csdp=%d (%s) solver_margin=%.3e verified_margin=%.3e "
      "lambda_max(Xi)=%.4e  [wall %.0f ms, cpu %.0f ms, %d variables]\n",
      in.h_s, r.feasible, r.csdp_return_code, r.csdp_status.c_str(), r.solver_margin,
      r.check.margin, r.check.xi_max_eigenvalue, 1e3 * r.seconds, CpuMs(c0), r.lmi_variables);
  c0 = std::clock();
  const auto d = shoal::design::MaxDelayTheorem3(in);
  std::printf(
      "  max_delay_s=%.4f (infeasible from %.4f, feasible_at_zero=%d, %d solves, "
      "%d failures) [wall %.0f ms, cpu %.0f ms]: %s\n",
      d.max_delay_s, d.infeasible_from_s, d.feasible_at_zero, d.solves, d.solver_failures,
      1e3 * d.seconds, CpuMs(c0), d.message.c_str());
  c0 = std::clock();
  const auto p = shoal::design::PaperMultipliersMaxEigenvalue(in);
  std::printf(
      "  paper_multipliers_max_eigenvalue=%.6f (solver %.6f, csdp=%d) "
      "[wall %.0f ms, cpu %.0f ms]\n",
      p.max_eigenvalue, p.solver_value, p.csdp_return_code, 1e3 * p.seconds, CpuMs(c0));
}

}  // namespace

int main(int argc, char** argv) {
  const auto topo = shoal::Topology::Build(
      5, {{1, 3}, {2, 1}, {2, 5}, {3, 1}, {4, 5}, {5, 2}, {5, 4}}, {1, 3, 5});
  Theorem3Input in;
  in.H = topo.H();
  in.k1 = 0.18;
  in.k2 = 1.152;
  in.h_s = 0.15;
  in.kappa = 0.05;
  in.lambda_G2 = 0.0004;
  in.lambda_J2 = 0.25;
  if (argc == 7) {
    in.k1 = std::atof(argv[1]);
    in.k2 = std::atof(argv[2]);
    in.h_s = std::atof(argv[3]);
    in.kappa = std::atof(argv[4]);
    in.lambda_G2 = std::atof(argv[5]);
    in.lambda_J2 = std::atof(argv[6]);
    Report("custom", in);
    in.form = Theorem3Form::kAsPrinted;
    Report("custom, as printed", in);
    return 0;
  }
  if (argc != 1) {
    std::fprintf(stderr, "usage: %s [k1 k2 h kappa lambda_G2 lambda_J2]\n", argv[0]);
    return 2;
  }
  Report("paper Example 2 data, scenario gains", in);
  in.form = Theorem3Form::kAsPrinted;
  Report("paper Example 2 data, scenario gains, as printed", in);
  in.form = Theorem3Form::kCorrected;
  in.lambda_G2 = 0.0;
  in.lambda_J2 = 0.0;
  Report("no uncertain factor (delay only), scenario gains", in);
  in.kappa = 0.0;
  Report("no uncertain factor, constant delay (kappa = 0), scenario gains", in);
  return 0;
}
