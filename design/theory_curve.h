// The theory a campaign's stability map draws: per scenario (one per value of the map's
// non-delay axis, built by the caller with that value set), the delay bounds that
// `shoal design` reports, expressed on the campaign's delay axis.
//
// Two bounds, both on the delay bound h of the scenario (the largest delay of any link
// over the whole timeline, theory::DelayBoundsOf):
//   exact margin:  the exact constant-delay margin of protocol (10) (core/theory.h,
//                  ComputeDelayMargin), the smallest over the topologies when the timeline
//                  switches them: DesignReport::GoverningMarginS. It is exact for one
//                  constant delay on own and neighbour states; for a time-varying delay it
//                  is the reference `shoal design` holds h against, not a certificate.
//   Theorem 3:     the largest h for which LMI (27)-(28) is feasible at the scenario's
//                  kappa and Lipschitz data (MaxDelayTheorem3, bisection to 1 ms): a
//                  certificate. None when Theorem 3 does not apply (unbounded delay rate,
//                  an uncertain factor it does not cover, a switching topology) or when the
//                  LMI is infeasible even at h = 0; `why` says which.
//
// On the axis. A campaign sweeps a scenario key, not h. For the key
// channel.delay.base_s the delay model adds a fixed amount to its base (sinusoid and
// uniform: amplitude_s; constant: nothing), so h = base_s + (h - base_s) and a bound B on h
// is the bound B - (h - base_s) on base_s, with h and base_s read from the scenario the
// caller built (any base value gives the same curve). Per-link delay overrides
// ([[channel.link]]) and channel events whose delay does not move with base_s make
// h - base_s depend on base_s; the offset is then taken at the scenario's base_s and the
// point says so in `note`. A bound that the offset alone uses up (B <= h - base_s) has no
// value on the axis: NaN there, and `why` says so.
#pragma once

#include <string>
#include <vector>

#include "core/scenario.h"

namespace shoal {
namespace design {

/// What the campaign's delay axis sets.
enum class DelayAxis {
  kBound,  ///< h itself (a caller that sets every link's delay to the axis value)
  kBase,   ///< channel.delay.base_s
};

/// The delay axis a scenario key sets: true (with *axis) for "channel.delay.base_s";
/// false for every other key (no theory curve is defined along it).
inline bool DelayAxisOfKey(const std::string& key, DelayAxis* axis) {
  if (key != "channel.delay.base_s") return false;
  if (axis) *axis = DelayAxis::kBase;
  return true;
}

struct TheoryCurveOptions {
  DelayAxis axis = DelayAxis::kBase;
};

/// The theory at one scenario. Bounds are NaN where undefined.
struct TheoryPoint {
  double h_s = 0.0;            ///< the scenario's delay bound h
  double axis_offset_s = 0.0;  ///< h - base_s (kBase), 0 (kBound)
  std::string note;            ///< e.g. the offset depends on base_s (per-link overrides)

  double exact_margin_s = 0.0;  ///< on h; NaN when unstable without delay
  double exact_on_axis = 0.0;   ///< exact_margin_s - axis_offset_s, NaN when not > 0
  std::string exact_why;        ///< why exact_on_axis is NaN ("" when defined)

  double theorem3_max_delay_s = 0.0;  ///< on h; NaN when none is certified
  bool theorem3_hit_cap = false;      ///< feasible up to the search cap (1000 s)
  double theorem3_on_axis = 0.0;      ///< theorem3_max_delay_s - axis_offset_s, or NaN
  std::string theorem3_why;           ///< why theorem3_on_axis is NaN ("" when defined)

  double seconds = 0.0;  ///< wall time of this point
};

/// The theory of one scenario: BuildDesignReport with the default request (Theorem 3 at h,
/// its bisection and the paper's multipliers; no empirical margin, tuning or advice).
/// Never throws on a valid scenario.
TheoryPoint ComputeTheoryPoint(const Scenario& s, const TheoryCurveOptions& options = {});

/// One point per scenario, in order.
std::vector<TheoryPoint> ComputeTheoryCurve(const std::vector<Scenario>& scenarios,
                                            const TheoryCurveOptions& options = {});

}  // namespace design
}  // namespace shoal
