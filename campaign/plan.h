// Every point's scenario, checked before any point runs (docs/campaigns.md): the base
// scenario with the campaign's `set`, the command line's --set and the point's axis values
// applied, validated as `shoal sim` would. A bad value is a CampaignError that names where
// it came from ("sweep.toml:12: axis channel.delay.base_s: channel.delay.base_s: must be
// ...").
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "campaign/campaign_file.h"
#include "campaign/points.h"
#include "scenario/overrides.h"

namespace shoal {

struct PointPlan {
  double duration_s = 0;       // simulated seconds of the point's run
};

/// The base scenario's text (a regular file of at most 16 MiB); throws CampaignError.
std::string ReadScenarioText(const std::string& path);

/// The overrides of every point, in order: campaign `set`, `cli_set` (--set on shoal
/// sweep), then the axes. Throws CampaignError on a bad set entry.
std::vector<ScenarioOverride> BaseOverrides(const Campaign& c,
                                            const std::vector<std::string>& cli_set);

/// The overrides of one point: `base`, then its axis values (origin: the axis' line).
std::vector<ScenarioOverride> PointOverrides(const Campaign& c,
                                             const std::vector<ScenarioOverride>& base,
                                             const CampaignPoint& p);

/// Validates every point's scenario; throws CampaignError with the first problem. With
/// refuse_large, a point whose run shoal sim/run would refuse as large (over 1 h or
/// 4 GiB at the campaign's engine) is such a problem too.
std::vector<PointPlan> PlanPoints(const Campaign& c, const std::string& scenario_text,
                                  const std::vector<ScenarioOverride>& base,
                                  const std::vector<CampaignPoint>& points,
                                  bool refuse_large = false);

/// Seconds a point may run before it counts as hung: campaign.timeout_s, else
/// 60 s + 10 x its duration at the engine's slowest expected speed (realtime 1x,
/// lockstep 10x, sim 100x).
double PointTimeout(const Campaign& c, const PointPlan& plan);

}  // namespace shoal
