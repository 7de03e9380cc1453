// The stability map of a sweep (docs/campaigns.md): the points' pass/fail over the map's two
// axes with the theory of `shoal design` on the same axes, the exact constant-delay margin
// and Theorem 3's certified delay (design/theory_curve.h). The theory is computed once,
// before the points run, and kept in campaign.json, so that `shoal sweep merge` draws the
// same map from the shards' files.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "campaign/campaign_file.h"
#include "campaign/points.h"
#include "campaign/results.h"
#include "scenario/overrides.h"

namespace shoal {

/// summary.json's "theory": when one map axis is channel.delay.base_s, the two bounds on
/// it at each value of the other map axis (its grid values; 12 values over its sampled
/// range for lhs), the other axes held at the first point's values; otherwise the bounds
/// at the first point's scenario, for reference. Throws CampaignError if a scenario of
/// the curve does not load.
nlohmann::ordered_json MapTheory(const Campaign& c, const std::string& scenario_text,
                                 const std::vector<ScenarioOverride>& base,
                                 const std::vector<CampaignPoint>& points);

/// Draws DIR/stability_map.png from `summary` (its map and theory) and the rows. False
/// with *why when the map cannot be drawn (no finished point, an axis whose values are
/// not numbers, the PNG failed).
bool DrawStabilityMap(const std::string& dir, const nlohmann::ordered_json& summary,
                      const Rows& rows, std::string* why);

}  // namespace shoal
