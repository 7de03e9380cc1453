// The one run of `shoal soak` (docs/campaigns.md): the campaign's grid points become
// consecutive phases of a single run, each `[soak] phase_s` long. Each phase is a `channel`
// event of the timeline (docs/scenario.md, "Timeline events") that gives every link the
// phase's delay and loss models (the scenario's with the phase's values set) from its
// start to the next phase's, [[channel.link]] overrides included. Only what a `channel` event can change
// mid-run can be stepped: keys under channel.delay and channel.loss.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "campaign/campaign_file.h"
#include "core/scenario.h"
#include "scenario/overrides.h"

namespace shoal {

struct SoakPlanPhase {
  double start_s = 0, end_s = 0;
  std::string label;      // "channel.delay.base_s = 0.15"
  nlohmann::json values;  // {"channel.delay.base_s": 0.15}
};

struct SoakPlan {
  std::vector<SoakPlanPhase> phases;
  /// The overrides that make the run's scenario from the base: the campaign's `set`, the
  /// command line's --set, and the timeline with the phases' events (`event`, the base
  /// scenario's events kept).
  std::vector<ScenarioOverride> overrides;
  Scenario scenario;  // validated, with the overrides applied
  double duration_s = 0;
};

/// Plans the soak of campaign `c`; `scenario_text` is its base scenario's text and `base`
/// BaseOverrides(c, --set). Throws CampaignError naming the campaign's line for a campaign
/// soak cannot run (no [soak], sim engine, lhs sampling, an axis outside channel.delay and
/// channel.loss) and for a scenario that does not load.
SoakPlan PlanSoak(const Campaign& c, const std::string& scenario_text,
                  const std::vector<ScenarioOverride>& base);

}  // namespace shoal
