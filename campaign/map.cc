#include "campaign/map.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <set>

#include "campaign/plan.h"
#include "design/module.h"
#include "design/theory_curve.h"
#include "render/campaign_figures.h"
#include "scenario/loader.h"

namespace shoal {
namespace {

using ojson = nlohmann::ordered_json;

constexpr int kLhsCurveValues = 12;

ojson Number(double v) { return std::isfinite(v) ? ojson(v) : ojson(); }

double ToDouble(const ojson& v) {
  return v.is_number() ? v.get<double>() : std::numeric_limits<double>::quiet_NaN();
}

int AxisIndex(const Campaign& c, const std::string& key) {
  for (std::size_t a = 0; a < c.axes.size(); ++a) {
    if (c.axes[a].key == key) return static_cast<int>(a);
  }
  return -1;
}

/// The values of axis `a` the curve is computed at, as (number, TOML text).
std::vector<std::pair<double, std::string>> CurveValues(const Campaign& c, int a,
                                                        const std::vector<CampaignPoint>& points) {
  std::vector<std::pair<double, std::string>> out;
  std::set<std::string> seen;
  if (c.sampling == CampaignSampling::kGrid) {
    for (const CampaignPoint& p : points) {
      const ojson& v = p.json[static_cast<std::size_t>(a)];
      if (v.is_number() && seen.insert(p.values[static_cast<std::size_t>(a)]).second) {
        out.emplace_back(v.get<double>(), p.values[static_cast<std::size_t>(a)]);
      }
    }
  } else {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (const CampaignPoint& p : points) {
      const double v = ToDouble(p.json[static_cast<std::size_t>(a)]);
      if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
    }
    const bool log = c.axes[static_cast<std::size_t>(a)].log && lo > 0;
    for (int i = 0; i < kLhsCurveValues && lo <= hi; ++i) {
      const double f = static_cast<double>(i) / (kLhsCurveValues - 1);
      const double v = log ? lo * std::pow(hi / lo, f) : lo + (hi - lo) * f;
      out.emplace_back(v, TomlFloatText(v));
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

ojson TheoryJson(const design::TheoryPoint& t, const ojson& at) {
  ojson o;
  o["at"] = at;
  o["h_s"] = Number(t.h_s);
  o["exact_margin_s"] = Number(t.exact_margin_s);
  o["exact_on_axis"] = Number(t.exact_on_axis);
  o["exact_why"] = t.exact_why;
  o["theorem3_max_delay_s"] = Number(t.theorem3_max_delay_s);
  o["theorem3_on_axis"] = Number(t.theorem3_on_axis);
  o["theorem3_why"] = t.theorem3_why;
  o["note"] = t.note;
  return o;
}

design::TheoryPoint TheoryAt(const Campaign& c, const std::string& text,
                             const std::vector<ScenarioOverride>& overrides) {
  try {
    std::string error;
    const DesignModule* m = LoadDesignModule(&error);
    if (m == nullptr) throw CampaignError("the stability map's theory: " + error);
    return m->theory_point(ParseScenario(text, c.scenario, overrides));
  } catch (const ScenarioError& e) {
    throw CampaignError(e.what());
  }
}

std::string UnitOf(const std::string& key) {
  const auto ends = [&](const char* s) {
    const std::string suffix = s;
    return key.size() > suffix.size() && key.compare(key.size() - suffix.size(), suffix.size(), suffix) == 0;
  };
  if (ends("_mps")) return "m/s";
  if (ends("_hz")) return "Hz";
  if (ends("_s")) return "s";
  if (ends("_m")) return "m";
  return "";
}

}  // namespace

nlohmann::ordered_json MapTheory(const Campaign& c, const std::string& scenario_text,
                                 const std::vector<ScenarioOverride>& base,
                                 const std::vector<CampaignPoint>& points) {
  ojson theory;
  if (points.empty()) return theory;
  std::string x, y;
  MapAxes(c, &x, &y);
  design::DelayAxis kind;
  const std::string delay = design::DelayAxisOfKey(x, &kind)   ? x
                            : design::DelayAxisOfKey(y, &kind) ? y
                                                               : std::string();
  const std::string along = delay.empty() ? "" : delay == x ? y : x;
  theory["what"] = "shoal design's exact constant-delay margin and Theorem 3's certified delay "
                   "(docs/theory.md), as bounds on the delay axis";
  theory["delay_axis"] = delay.empty() ? ojson() : ojson(delay);
  theory["along"] = along.empty() ? ojson() : ojson(along);
  theory["points"] = ojson::array();
  const std::vector<ScenarioOverride> first = PointOverrides(c, base, points[0]);
  const int a = along.empty() ? -1 : AxisIndex(c, along);
  if (a < 0) {
    theory["points"].push_back(TheoryJson(TheoryAt(c, scenario_text, first), ojson()));
    return theory;
  }
  for (const auto& [value, text] : CurveValues(c, a, points)) {
    std::vector<ScenarioOverride> o = first;
    o[base.size() + static_cast<std::size_t>(a)].value = text;
    theory["points"].push_back(TheoryJson(TheoryAt(c, scenario_text, o), value));
  }
  return theory;
}

namespace {

bool MapPoints(const std::string& x, const std::string& y, const Rows& rows,
               render::StabilityMapData* d, std::string* why) {
  for (const auto& [index, row] : rows) {
    const double vx = ToDouble(row.value(x, ojson()));
    const double vy = y.empty() ? 0.0 : ToDouble(row.value(y, ojson()));
    if (!std::isfinite(vx) || !std::isfinite(vy)) {
      *why = "point " + std::to_string(index) + " has no number on the map's axes (" + x +
             (y.empty() ? "" : ", " + y) + ")";
      return false;
    }
    d->x_values.push_back(vx);
    if (!y.empty()) d->y_values.push_back(vy);
    const std::string status = row.value("status", "");
    d->outcome.push_back(status != "ok" ? status : row.value("pass", false) ? "pass" : "fail");
  }
  if (d->outcome.empty()) *why = "no finished point";
  return !d->outcome.empty();
}

void MapCurves(const ojson& theory, render::StabilityMapData* d) {
  const ojson delay = theory.value("delay_axis", ojson());
  if (!delay.is_string() || !theory.contains("points")) return;
  d->delay_on_y = d->has_y && delay.get<std::string>() == d->y.label;
  for (const ojson& p : theory["points"]) {
    d->curve_at.push_back(ToDouble(p.value("at", ojson())));
    d->exact_margin.push_back(ToDouble(p.value("exact_on_axis", ojson())));
    d->theorem3.push_back(ToDouble(p.value("theorem3_on_axis", ojson())));
    if (d->exact_note.empty()) d->exact_note = p.value("exact_why", "");
    if (d->theorem3_note.empty()) d->theorem3_note = p.value("theorem3_why", "");
  }
}

}  // namespace

bool DrawStabilityMap(const std::string& dir, const nlohmann::ordered_json& summary,
                      const Rows& rows, std::string* why) {
  const ojson map = summary.value("map", ojson());
  const std::string x = map.is_object() ? map.value("x", "") : "";
  const std::string y = map.is_object() ? map.value("y", "") : "";
  if (x.empty()) {
    *why = "the campaign has no axis";
    return false;
  }
  render::StabilityMapData d;
  d.title = std::filesystem::path(summary.value("campaign", "campaign")).stem().string();
  d.x = {x, UnitOf(x), map.value("x_log", false)};
  d.has_y = !y.empty();
  if (d.has_y) d.y = {y, UnitOf(y), map.value("y_log", false)};
  if (!MapPoints(x, y, rows, &d, why)) return false;
  std::string criteria;
  for (const ojson& c : summary.value("criteria", ojson::array())) {
    criteria += (criteria.empty() ? "pass: " : ", ") + c.get<std::string>();
  }
  d.subtitle = criteria;
  MapCurves(summary.value("theory", ojson()), &d);
  return render::RenderStabilityMap(d, dir + "/stability_map.png", why);
}

}  // namespace shoal
