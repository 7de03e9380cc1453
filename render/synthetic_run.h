// Synthetic data shaped like a Shoal run of the paper's Example 2, for the render demo,
// the render benchmark and the render tests (library shoal_render_synthetic; not used by
// shoal_render itself).
//
// Leader: the paper's helix x0 = 60 cos(0.0022 pi t) + 25 sin(0.0011 pi t),
// y0 = 60 sin(0.0022 pi t) + 25 cos(0.0011 pi t), z0 = -0.12 t. Followers start at the
// positions of scenarios/paper_example2.toml and converge to a 12 m square around the
// leader (follower 5 5 m below it) with a damped oscillation, e(t) = e(0) e^{-t/T}
// (cos wt + sin(wt)/(wT)), T = 12 s, w = 0.25 rad/s, plus the small steady bias of a PD
// law on a helix. The leader's attitude follows its velocity; a follower's is the leader's
// plus a decaying oscillating offset from its initial heading and pitch. Channel: the
// paper topology's 10 links, tau(t) = 0.1 + 0.05 cos t,
// delivery at the first 20 ms tick after send + tau (as in lockstep), seeded Bernoulli
// drops.
#pragma once

#include <vector>

#include "render/shoal_figures.h"

namespace shoal::render {

struct SyntheticRun {
  std::vector<VehicleSeries> vehicles;  // leader first
  std::vector<ErrorSeries> errors;      // followers
  std::vector<LinkSeries> links;
  std::vector<double> tau_t_s, tau_s;         // tau(t) every 10 ms
  std::vector<std::pair<int, int>> topology;  // undirected vehicle pairs of the links
  double converged_s = -1.0;                  // last time any follower was outside 0.5 m / 0.05 m/s
};

/// duration_s at rate_hz for the leader and 5 followers; drop_probability per message.
SyntheticRun MakeSyntheticRun(double duration_s, double rate_hz, double drop_probability,
                              unsigned seed);

}  // namespace shoal::render
