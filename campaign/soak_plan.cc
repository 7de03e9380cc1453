#include "campaign/soak_plan.h"

#include <algorithm>
#include <sstream>

#include <toml++/toml.h>

#include "campaign/points.h"
#include "campaign/plan.h"
#include "scenario/loader.h"

namespace shoal {
namespace {

/// Timeline limit of the scenario loader (docs/scenario.md): phases and the base
/// scenario's own events share it.
constexpr std::size_t kMaxEvents = 10000;

[[noreturn]] void Fail(const Campaign& c, int line, const std::string& what) {
  throw CampaignError(c.path + ":" + std::to_string(line) + ": " + what);
}

bool IsChannelModelKey(const std::string& key) {
  for (const char* table : {"channel.delay", "channel.loss"}) {
    const std::string t = table;
    if (key == t || key.rfind(t + ".", 0) == 0) return true;
  }
  return false;
}

void CheckSoakable(const Campaign& c) {
  if (!c.soak.present) {
    Fail(c, 1, "no [soak] table; shoal soak needs one (phase_s, settle_s; docs/campaigns.md)");
  }
  if (c.engine == CampaignEngine::kSim) {
    Fail(c, 1, "campaign.engine: a soak is one shoal run, in lockstep or realtime (got \"sim\"); "
               "set engine = \"lockstep\" or \"realtime\"");
  }
  if (c.sampling != CampaignSampling::kGrid) {
    Fail(c, 1, "campaign.sampling: a soak's phases are the grid's points in order (got "
               "\"lhs\"); remove sampling");
  }
  // Settings of sweep points that a soak has no use for: silently ignoring them would let a
  // user believe they took effect.
  const std::pair<bool, const char*> unused[] = {
      {c.duration_s > 0, "campaign.duration_s (the run lasts phases x soak.phase_s)"},
      {c.timeout_s > 0, "campaign.timeout_s (a soak is one run, stopped with Ctrl-C)"},
      {c.workers > 0, "campaign.workers (a soak is one run)"},
      {!c.map_x.empty() || !c.map_y.empty(), "[map] (a soak draws soak.png)"}};
  for (const auto& [given, what] : unused) {
    if (given) throw CampaignError(c.path + ": " + what + ": not used by shoal soak; remove it");
  }
  if (c.axes.empty()) Fail(c, 1, "a soak needs at least one [[axis]]: its values are the phases");
  for (const CampaignAxis& axis : c.axes) {
    if (!IsChannelModelKey(axis.key)) {
      Fail(c, axis.line,
           "axis " + axis.key + ": a soak steps only what a channel event changes mid-run; "
           "use a key under channel.delay or channel.loss (sweep the others with shoal sweep)");
    }
  }
}

/// The tree of the scenario with `overrides` applied.
toml::table EffectiveTree(const Campaign& c, const std::string& text,
                          const std::vector<ScenarioOverride>& overrides) {
  try {
    return toml::parse(ApplyOverridesToText(text, c.scenario, overrides), c.scenario);
  } catch (const ScenarioError& e) {
    throw CampaignError(e.what());
  } catch (const toml::parse_error& e) {
    throw CampaignError(c.scenario + ": " + std::string(e.description()));
  }
}

/// A copy of `node` written inline, tables inside tables too, so that it fits in one value.
toml::table InlineCopy(const toml::table& t) {
  toml::table copy = t;
  copy.is_inline(true);
  for (auto&& [key, value] : copy) {
    if (auto* sub = value.as_table()) *sub = InlineCopy(*sub);
  }
  return copy;
}

std::string PhaseLabel(const Campaign& c, const CampaignPoint& p) {
  std::string label;
  for (std::size_t a = 0; a < c.axes.size(); ++a) {
    label += (a ? ", " : "") + c.axes[a].key + " = " + p.values[a];
  }
  return label;
}

/// The `channel` event of phase `k`: the effective channel.delay and channel.loss of its
/// point's scenario, on every link, for its window.
toml::table PhaseEvent(const toml::table& tree, double start, double end, bool last) {
  toml::table e;
  e.insert("at_s", start);
  if (!last) e.insert("until_s", end);
  e.insert("kind", "channel");
  const toml::table* channel = tree["channel"].as_table();
  const toml::table none{{"model", "none"}};
  for (const char* model : {"delay", "loss"}) {
    const toml::table* t = channel ? (*channel)[model].as_table() : nullptr;
    e.insert(model, InlineCopy(t ? *t : none));
  }
  return e;
}

double AtOf(const toml::node& n) {
  const toml::table* t = n.as_table();
  return t ? (*t)["at_s"].value<double>().value_or(0.0) : 0.0;
}

/// The `event` value: the base scenario's events and the phases', ordered by at_s (an
/// event of the base at a phase's start comes first, as it was written first).
std::string TimelineValue(const toml::table& base_tree, std::vector<toml::table> phase_events) {
  toml::array events;
  if (const toml::array* own = base_tree["event"].as_array()) {
    for (const toml::node& n : *own) {
      if (const toml::table* t = n.as_table()) events.push_back(InlineCopy(*t));
    }
  }
  for (toml::table& e : phase_events) events.push_back(std::move(e));
  std::vector<toml::table> sorted;
  for (toml::node& n : events) sorted.push_back(*n.as_table());
  std::stable_sort(sorted.begin(), sorted.end(), [](const toml::table& a, const toml::table& b) {
    return AtOf(a) < AtOf(b);
  });
  toml::array ordered;
  for (toml::table& t : sorted) ordered.push_back(std::move(t));
  std::ostringstream out;
  out << toml::toml_formatter{ordered, toml::format_flags::none};
  return out.str();
}

/// Where an event of the effective scenario was written: an override that sets the
/// timeline (a campaign's `set`, `--set event=...`) by its origin, else the scenario file's
/// line of the same event (overrides rewrite the text, so the line is read from the file's).
std::string WhereEventIs(const Campaign& c, const std::string& scenario_text,
                         const std::vector<ScenarioOverride>& base, std::size_t index) {
  // The timeline's own override, or one of this event's keys (event[k].kind, ...); a key
  // may be written quoted ("event", 'event').
  const std::string element = "event[" + std::to_string(index) + "]";
  for (auto it = base.rbegin(); it != base.rend(); ++it) {
    std::string key = it->key;
    key.erase(std::remove_if(key.begin(), key.end(), [](char ch) { return ch == '"' || ch == '\''; }),
              key.end());
    if (key == "event" || key == element || key.rfind(element + ".", 0) == 0) {
      return it->origin.empty() ? "--set " + it->key : it->origin;
    }
  }
  try {
    const toml::table own = toml::parse(scenario_text, c.scenario);
    if (const toml::array* events = own["event"].as_array(); events && index < events->size()) {
      const auto line = events->get(index)->source().begin.line;
      if (line > 0) return c.scenario + ":" + std::to_string(line);
    }
  } catch (const toml::parse_error&) {
    // The effective text parsed; the file's own errors are the loader's to name.
  }
  return c.scenario;
}

/// A soak's phases each change the channel of every link, and one of them is in force at
/// every moment of the run: a channel event of the scenario's own would overlap one. It is
/// refused here where it was written, before the merged timeline's loader names it by its
/// position among the phases.
void CheckNoChannelEvents(const Campaign& c, const std::string& scenario_text,
                          const std::vector<ScenarioOverride>& base, const toml::table& tree) {
  const toml::array* own = tree["event"].as_array();
  if (own == nullptr) return;
  for (std::size_t k = 0; k < own->size(); ++k) {
    const toml::table* t = own->get(k)->as_table();
    if (t == nullptr || (*t)["kind"].value<std::string>().value_or("") != "channel") continue;
    std::ostringstream at;
    at << (*t)["at_s"].value<double>().value_or(0.0);
    throw CampaignError(WhereEventIs(c, scenario_text, base, k) + ": a channel event (at_s = " +
                        at.str() + "): a soak's phases set the channel of every link for the "
                        "whole run, so its scenario may hold no channel event of its own; "
                        "remove it (the other kinds of event are kept), or run that scenario "
                        "with shoal sweep");
  }
}

}  // namespace

SoakPlan PlanSoak(const Campaign& c, const std::string& scenario_text,
                  const std::vector<ScenarioOverride>& base) {
  CheckSoakable(c);
  const std::vector<CampaignPoint> points = MakePoints(c);
  if (points.size() > kMaxEvents) {
    Fail(c, c.axes.front().line,
         "a soak of " + std::to_string(points.size()) + " phases is beyond the timeline's " +
             std::to_string(kMaxEvents) + " events; use fewer axis values");
  }
  // Each phase's scenario as a sweep point would run it: a bad value is named by its axis'
  // line, not by the event it becomes.
  PlanPoints(c, scenario_text, base, points);
  toml::table base_tree = EffectiveTree(c, scenario_text, base);
  CheckNoChannelEvents(c, scenario_text, base, base_tree);
  SoakPlan plan;
  const double phase_s = c.soak.phase_s;
  std::vector<toml::table> events;
  for (std::size_t k = 0; k < points.size(); ++k) {
    SoakPlanPhase phase;
    phase.start_s = phase_s * static_cast<double>(k);
    phase.end_s = phase_s * static_cast<double>(k + 1);
    phase.label = PhaseLabel(c, points[k]);
    for (std::size_t a = 0; a < c.axes.size(); ++a) {
      phase.values[c.axes[a].key] = points[k].json[a];
    }
    const std::vector<ScenarioOverride> own = PointOverrides(c, base, points[k]);
    events.push_back(PhaseEvent(EffectiveTree(c, scenario_text, own), phase.start_s,
                                phase.end_s, k + 1 == points.size()));
    plan.phases.push_back(std::move(phase));
  }
  plan.duration_s = phase_s * static_cast<double>(points.size());
  plan.overrides = base;
  plan.overrides.push_back({"event",
                            TimelineValue(base_tree, std::move(events)),
                            c.path + ": the soak's phases (" + std::to_string(points.size()) +
                                " channel events)"});
  // The timeline reaches every process of the run as one --set argument, and Linux caps
  // one argument at 128 KiB (MAX_ARG_STRLEN).
  constexpr std::size_t kMaxArgumentBytes = 120 * 1024;
  if (plan.overrides.back().value.size() > kMaxArgumentBytes) {
    Fail(c, c.axes.front().line,
         "the soak's " + std::to_string(points.size()) + " phases make a timeline of " +
             std::to_string(plan.overrides.back().value.size() / 1024) +
             " KiB, more than one process argument may hold (120 KiB); use fewer phases");
  }
  try {
    plan.scenario = ParseScenario(scenario_text, c.scenario, plan.overrides);
  } catch (const ScenarioError& e) {
    throw CampaignError(e.what());
  }
  return plan;
}

}  // namespace shoal
