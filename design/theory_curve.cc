#include "design/theory_curve.h"

#include <chrono>
#include <cmath>
#include <limits>

#include "core/theory.h"
#include "design/format.h"
#include "design/report.h"

namespace shoal {
namespace design {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// The delay models whose h is base_s plus a fixed amount.
bool HasBase(DelayKind k) {
  return k == DelayKind::kConstant || k == DelayKind::kSinusoid || k == DelayKind::kUniform;
}

/// h - base_s, or NaN (with *why) when base_s does not set the delay.
double AxisOffset(const Scenario& s, DelayAxis axis, double h_s, std::string* note,
                  std::string* why) {
  if (axis == DelayAxis::kBound) return 0.0;
  if (!HasBase(s.delay.kind)) {
    *why = std::string("the delay model \"") + DelayKindName(s.delay.kind) +
           "\" has no base_s: channel.delay.base_s does not set its delay";
    return kNaN;
  }
  bool fixed_parts = !s.links.empty();
  for (const ScenarioEvent& e : s.events) fixed_parts = fixed_parts || e.delay.has_value();
  if (fixed_parts) {
    *note = "per-link delays or channel events: h - base_s (" + G4(h_s - s.delay.base_s) +
            " s) taken at base_s = " + G4(s.delay.base_s) + " s";
  }
  return h_s - s.delay.base_s;
}

/// bound - offset when positive; else NaN and why.
double OnAxis(double bound, double offset, const std::string& offset_why, std::string* why) {
  if (!why->empty()) return kNaN;
  if (!std::isfinite(offset)) {
    *why = offset_why;
    return kNaN;
  }
  if (!(bound - offset > 0.0)) {
    *why = "the delay model's own variation (h - base_s = " + G4(offset) +
           " s) uses up the bound " + G4(bound) + " s";
    return kNaN;
  }
  return bound - offset;
}

void SetTheorem3(const DesignReport& r, TheoryPoint* p) {
  const Theorem3Section& t = r.theorem3;
  if (r.switching) {
    p->theorem3_why = "the topology switches: Theorem 3 covers one fixed topology";
  } else if (!t.evaluated) {
    p->theorem3_why = "Theorem 3 does not apply: " + t.not_evaluated_reason;
  } else if (!t.max_delay.input_valid) {
    p->theorem3_why = "Theorem 3's input is invalid: " + t.max_delay.message;
  } else if (!t.max_delay.feasible_at_zero) {
    p->theorem3_why = "Theorem 3's LMI is infeasible even at h = 0";
  } else {
    p->theorem3_max_delay_s = t.max_delay.max_delay_s;
    p->theorem3_hit_cap = t.max_delay.hit_cap;
    return;
  }
  p->theorem3_max_delay_s = kNaN;
}

}  // namespace

TheoryPoint ComputeTheoryPoint(const Scenario& s, const TheoryCurveOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  TheoryPoint p;
  // The report of `shoal design` with its default request: the same bounds, the same
  // rules for when Theorem 3 applies.
  DesignRequest q;
  const DesignReport r = BuildDesignReport(s, q);
  p.h_s = r.delay.h_s;
  const double margin = r.GoverningMarginS();
  SetTheorem3(r, &p);
  std::string offset_why;
  p.axis_offset_s = AxisOffset(s, o.axis, p.h_s, &p.note, &offset_why);
  if (margin > 0.0) {
    p.exact_margin_s = margin;
  } else {
    p.exact_margin_s = kNaN;
    p.exact_why = "unstable without delay (some eigenvalue of H gives no margin)";
  }
  p.exact_on_axis = OnAxis(p.exact_margin_s, p.axis_offset_s, offset_why, &p.exact_why);
  p.theorem3_on_axis =
      OnAxis(p.theorem3_max_delay_s, p.axis_offset_s, offset_why, &p.theorem3_why);
  p.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return p;
}

std::vector<TheoryPoint> ComputeTheoryCurve(const std::vector<Scenario>& scenarios,
                                            const TheoryCurveOptions& o) {
  std::vector<TheoryPoint> out;
  out.reserve(scenarios.size());
  for (const Scenario& s : scenarios) out.push_back(ComputeTheoryPoint(s, o));
  return out;
}

}  // namespace design
}  // namespace shoal
