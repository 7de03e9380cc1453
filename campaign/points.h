// The points of a campaign (docs/campaigns.md): grid in nested-loop order (first axis
// slowest) or a seeded Latin hypercube in draw order, numbered 0..P-1.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "campaign/campaign_file.h"

namespace shoal {

/// One point: a value per axis (in the campaign's axis order).
struct CampaignPoint {
  std::int64_t index = 0;
  std::vector<std::string> values;  // TOML value text, as --set takes it
  std::vector<nlohmann::json> json;  // the same values, for result rows
};

/// Every point of a validated campaign, in point order. Deterministic: the same campaign
/// (and lhs seed) gives the same points on every platform and library version.
std::vector<CampaignPoint> MakePoints(const Campaign& c);

}  // namespace shoal
