// Pass criteria of a campaign, judged on the JSON a point's run printed.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "campaign/campaign_file.h"

namespace shoal {

/// The scalars of a JSON object as dotted keys, in document order: {"a": {"b": 1}} gives
/// "a.b" = 1. Arrays and nulls are left out (a row holds scalars only).
nlohmann::ordered_json FlattenScalars(const nlohmann::ordered_json& j);

struct Judgement {
  bool pass = false;
  std::string why;  // "" when it passes; else each failed criterion with its value
};

/// Judges `run` (a run's --json object) against every criterion. A metric the run does
/// not have fails ("x: missing from the run's JSON"); so does a value of another type.
Judgement JudgeRun(const std::vector<CampaignCriterion>& criteria,
                   const nlohmann::ordered_json& run);

}  // namespace shoal
