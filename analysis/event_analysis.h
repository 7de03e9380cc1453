// Per [[event]] of a run's scenario: its window, what it affects, the formation's
// excursion and re-convergence around it, and the channel decisions in its window.
// Definitions: docs/analyze.md, "Events". Used by AnalyseRun (analysis/analysis.h).
#pragma once

#include <string>
#include <vector>

#include "analysis/analysis.h"

namespace shoal {

/// The worst follower at one complete sample (the leader and every follower have a state).
struct WorstSample {
  double t_s = 0.0;
  double position_m = 0.0;    // largest follower position error
  double velocity_mps = 0.0;  // largest follower velocity error
  int position_follower = 0;  // the follower with position_m
  bool violating = false;     // some follower outside the tolerances (FormationMetrics' rule)
};

/// What an event applies to, as text: "every link", "links 0->1, 2->3", "vehicles 2, 3",
/// "the leader", "edges 1<-3 2<-1, leader links 1 3".
std::string EventAffects(const ScenarioEvent& e);

/// One EventAnalysis per event of run.scenario.events that starts by `end_s` (a run ended
/// earlier never saw the others). `samples`: the complete samples in
/// time order (empty without formation metrics: the formation figures stay NaN); `end_s`:
/// the run's end (the last time a state may have); `period_us`: the control period (for a
/// deaf receiver's due times; 0 for a real-time run, whose messages are due at send + tau).
std::vector<EventAnalysis> AnalyseEvents(const RunData& run, const std::vector<WorstSample>& samples,
                                         double end_s, Micros period_us);

}  // namespace shoal
