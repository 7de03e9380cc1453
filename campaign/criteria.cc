#include "campaign/criteria.h"

#include <cmath>

namespace shoal {
namespace {

void Flatten(const nlohmann::ordered_json& j, const std::string& prefix,
             nlohmann::ordered_json* out) {
  for (auto it = j.begin(); it != j.end(); ++it) {
    const std::string key = prefix.empty() ? it.key() : prefix + "." + it.key();
    if (it->is_object()) {
      Flatten(*it, key, out);
    } else if (it->is_primitive() && !it->is_null()) {
      (*out)[key] = *it;
    }
  }
}

std::string Shown(const nlohmann::ordered_json& v) {
  return v.dump(-1, ' ', false, nlohmann::ordered_json::error_handler_t::replace);
}

/// "" when `value` meets `c`, else why not.
std::string Failure(const CampaignCriterion& c, const nlohmann::ordered_json& value) {
  if (c.equals) {
    const nlohmann::json& want = *c.equals;
    bool equal = false;
    if (want.is_number() && value.is_number()) {
      equal = want.get<double>() == value.get<double>();
    } else if (want.is_boolean() && value.is_boolean()) {
      equal = want.get<bool>() == value.get<bool>();
    } else if (want.is_string() && value.is_string()) {
      equal = want.get<std::string>() == value.get<std::string>();
    }
    return equal ? "" : c.key + " = " + Shown(value) + ", not " + want.dump();
  }
  if (!value.is_number()) return c.key + " = " + Shown(value) + ", not a number";
  const double v = value.get<double>();
  if (std::isnan(v)) return c.key + " = nan";
  if (c.min && v < *c.min) return c.key + " = " + Shown(value) + " < min " + nlohmann::json(*c.min).dump();
  if (c.max && v > *c.max) return c.key + " = " + Shown(value) + " > max " + nlohmann::json(*c.max).dump();
  return "";
}

}  // namespace

nlohmann::ordered_json FlattenScalars(const nlohmann::ordered_json& j) {
  nlohmann::ordered_json out = nlohmann::ordered_json::object();
  if (j.is_object()) Flatten(j, "", &out);
  return out;
}

Judgement JudgeRun(const std::vector<CampaignCriterion>& criteria,
                   const nlohmann::ordered_json& run) {
  const nlohmann::ordered_json flat = FlattenScalars(run);
  Judgement j;
  for (const CampaignCriterion& c : criteria) {
    const auto it = flat.find(c.key);
    const std::string failure =
        it == flat.end() ? c.key + ": missing from the run's JSON" : Failure(c, *it);
    if (failure.empty()) continue;
    if (!j.why.empty()) j.why += "; ";
    j.why += failure;
  }
  j.pass = j.why.empty();
  return j;
}

}  // namespace shoal
