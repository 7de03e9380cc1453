#include "design/advise.h"

#include <toml++/toml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "scenario/loader.h"
#include "design/format.h"

namespace shoal {
namespace design {
namespace {

/// Scales c = 2^(j / steps), nearest to 1 first (j = 0, 1, -1, 2, -2, ...), within range.
std::vector<double> ScalesNearestFirst(const AdviceOptions& o) {
  std::vector<double> out;
  const int steps = std::max(1, o.steps_per_doubling);
  const int j_max = static_cast<int>(std::floor(std::log2(o.c_max) * steps + 1e-9));
  const int j_min = static_cast<int>(std::ceil(std::log2(o.c_min) * steps - 1e-9));
  for (int d = 0; d <= std::max(j_max, -j_min); ++d) {
    for (int j : d == 0 ? std::vector<int>{0} : std::vector<int>{d, -d}) {
      if (j >= j_min && j <= j_max) out.push_back(std::pow(2.0, static_cast<double>(j) / steps));
    }
  }
  return out;
}

Theorem3Input Scaled(const Theorem3Input& in, double c) {
  Theorem3Input s = in;
  s.k1 = c * c * in.k1;
  s.k2 = c * in.k2;
  return s;
}

/// The first scale (nearest to 1) whose gains Theorem 3 certifies at h; 0 if none.
double FirstCertifiedScale(const AdviceInput& in, const std::vector<double>& scales,
                           GainAdvice* out) {
  for (double c : scales) {
    Theorem3Result r = CheckTheorem3(Scaled(in.theorem3, c));
    ++out->solves;
    if (r.certifies()) {
      out->certificate = std::move(r);
      return c;
    }
  }
  return 0.0;
}

/// The smallest and largest scale whose gains Theorem 3 certifies at h = 0 (0, 0 if none).
std::pair<double, double> ScalesFeasibleWithoutDelay(const AdviceInput& in,
                                                     const std::vector<double>& scales,
                                                     GainAdvice* out) {
  double lo = 0.0, hi = 0.0;
  for (double c : scales) {
    Theorem3Input at_zero = Scaled(in.theorem3, c);
    at_zero.h_s = 0.0;
    ++out->solves;
    if (!CheckTheorem3(at_zero).certifies()) continue;
    lo = lo == 0.0 ? c : std::min(lo, c);
    hi = std::max(hi, c);
  }
  return {lo, hi};
}

/// Golden-section search of log c in [lo, hi] for the largest max_delay_s (unimodal on the
/// scale family: too little gain loses to the factor, too much to the delay).
double BestMaxDelayScale(const AdviceInput& in, double lo, double hi, const AdviceOptions& o,
                         GainAdvice* out) {
  const double g = 0.5 * (std::sqrt(5.0) - 1.0);
  double a = std::log(lo), b = std::log(hi);
  auto value = [&](double log_c) {
    const MaxDelayResult d = MaxDelayTheorem3(Scaled(in.theorem3, std::exp(log_c)),
                                              o.max_delay_tol_s);
    out->solves += d.solves;
    return d.feasible_at_zero ? d.max_delay_s : -1.0;
  };
  double x1 = b - g * (b - a), x2 = a + g * (b - a);
  double f1 = value(x1), f2 = value(x2);
  for (int i = 0; i < o.golden_steps; ++i) {
    if (f1 >= f2) {
      b = x2, x2 = x1, f2 = f1;
      x1 = b - g * (b - a);
      f1 = value(x1);
    } else {
      a = x1, x1 = x2, f1 = f2;
      x2 = a + g * (b - a);
      f2 = value(x2);
    }
  }
  return std::exp(f1 >= f2 ? x1 : x2);
}

/// Fills the advised gains' numbers at scale c (a max_delay search and the margins).
void Describe(const AdviceInput& in, double c, const AdviceOptions& o, GainAdvice* out) {
  const Theorem3Input scaled = Scaled(in.theorem3, c);
  out->scale = c;
  out->k1 = scaled.k1;
  out->k2 = scaled.k2;
  MaxDelayResult d = MaxDelayTheorem3(scaled, o.max_delay_tol_s);
  out->solves += d.solves;
  out->found = d.feasible_at_zero;
  out->theorem3_max_delay_s = d.feasible_at_zero ? d.max_delay_s : 0.0;
  if (!out->certified_at_h) out->certificate = std::move(d.at_max);
  out->delay_margin_s = theory::ComputeDelayMargin(in.eigenvalues, out->k1, out->k2).tau_s;
  if (in.factor_slopes_known) {
    const theory::FactorDelayMargin f =
        theory::ComputeFactorDelayMargin(in.eigenvalues, out->k1, out->k2, in.lipschitz);
    out->delay_margin_with_factor_s = f.stable_at_zero ? f.tau_s : 0.0;
  }
}

}  // namespace

GainAdvice AdviseGains(const AdviceInput& in, const AdviceOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  GainAdvice out;
  const std::vector<double> scales = ScalesNearestFirst(options);
  const std::string range = "c in [" + G4(options.c_min) + ", " + G4(options.c_max) + "]";
  const double c = FirstCertifiedScale(in, scales, &out);
  if (c > 0.0) {
    out.certified_at_h = true;
    Describe(in, c, options, &out);
    out.how = "the scale c = " + G4(c) + " nearest to the scenario's gains (k1 x c^2, k2 x c; " +
              range + ") at which Theorem 3 certifies h = " + G4(in.theorem3.h_s) + " s";
  } else {
    const auto [lo, hi] = ScalesFeasibleWithoutDelay(in, scales, &out);
    if (lo == 0.0) {
      Describe(in, 1.0, options, &out);
      out.how = "no scale " + range + " of the scenario's gains is certified by Theorem 3, not "
                "even at h = 0: the scenario's gains are kept";
    } else {
      const double step = std::pow(2.0, 1.0 / std::max(1, options.steps_per_doubling));
      const double best = BestMaxDelayScale(in, lo / step, hi * step, options, &out);
      Describe(in, best, options, &out);
      out.how = "no scale " + range + " is certified by Theorem 3 at h = " +
                G4(in.theorem3.h_s) + " s; c = " + G4(best) +
                " maximises the delay Theorem 3 certifies (golden section over log c)";
    }
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

bool WriteScenarioWithGains(const std::string& scenario_path, double k1, double k2,
                            const std::string& out_path, std::string* err) {
  toml::table t;
  try {
    t = toml::parse_file(scenario_path);
  } catch (const toml::parse_error& e) {
    *err = scenario_path + ": " + std::string(e.description());
    return false;
  }
  if (!t["control"].is_table() || !t["run"].is_table()) {
    *err = scenario_path + ": no [control] or [run] table";
    return false;
  }
  t["control"].as_table()->insert_or_assign("k1", k1);
  t["control"].as_table()->insert_or_assign("k2", k2);
  if (const auto name = t["run"]["name"].value<std::string>()) {
    t["run"].as_table()->insert_or_assign("name", *name + "_advised");
  }
  std::ostringstream text;
  text << "# " << scenario_path << " with the gains `shoal design --advise` advises.\n" << t
       << "\n";
  try {
    ParseScenario(text.str(), out_path);
  } catch (const std::exception& e) {
    *err = std::string("the rewritten scenario does not load: ") + e.what();
    return false;
  }
  // Written beside the target and renamed over it: a failed write (a full disk) never
  // leaves a truncated scenario, also when the target is the input scenario itself.
  const std::string tmp = out_path + ".tmp";
  std::ofstream f(tmp);
  f << text.str();
  f.close();
  if (!f || std::rename(tmp.c_str(), out_path.c_str()) != 0) {
    std::remove(tmp.c_str());
    *err = out_path + ": cannot write there";
    return false;
  }
  return true;
}

}  // namespace design
}  // namespace shoal
