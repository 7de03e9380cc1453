#include "campaign/plan.h"

#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>

#include <algorithm>
#include <map>
#include <optional>
#include <set>

#include "core/swarm.h"
#include "scenario/loader.h"
#include "scenario/regular_file.h"

namespace shoal {

std::string ReadScenarioText(const std::string& path) {
  constexpr std::int64_t kMaxScenarioBytes = 16 << 20;  // as the scenario loader's limit
  std::string error;
  const int fd = OpenRegularFile(path, "scenario file", kMaxScenarioBytes, &error);
  if (fd < 0) throw CampaignError(error);
  std::string text;
  char buffer[1 << 16];
  for (;;) {
    const ssize_t n = read(fd, buffer, sizeof(buffer));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      close(fd);
      if (n < 0) throw CampaignError(path + ": cannot read scenario file");
      return text;
    }
    text.append(buffer, static_cast<std::size_t>(n));
    if (text.size() > static_cast<std::size_t>(kMaxScenarioBytes)) {
      close(fd);
      throw CampaignError(path + ": scenario file grew beyond 16 MiB while being read");
    }
  }
}

std::vector<ScenarioOverride> BaseOverrides(const Campaign& c,
                                            const std::vector<std::string>& cli_set) {
  std::vector<ScenarioOverride> out;
  for (const CampaignSet& s : c.set) {
    try {
      ScenarioOverride o = ParseSetFlag(s.text);
      o.origin = c.path + ":" + std::to_string(s.line) + ": set " + s.text;
      out.push_back(std::move(o));
    } catch (const ScenarioError& e) {
      throw CampaignError(c.path + ":" + std::to_string(s.line) + ": campaign.set: " + e.what());
    }
  }
  for (const std::string& text : cli_set) {
    try {
      out.push_back(ParseSetFlag(text));
    } catch (const ScenarioError& e) {
      throw CampaignError(e.what());
    }
  }
  return out;
}

std::vector<ScenarioOverride> PointOverrides(const Campaign& c,
                                             const std::vector<ScenarioOverride>& base,
                                             const CampaignPoint& p) {
  std::vector<ScenarioOverride> out = base;
  for (std::size_t a = 0; a < c.axes.size(); ++a) {
    const CampaignAxis& axis = c.axes[a];
    out.push_back({axis.key, p.values[a],
                   c.path + ":" + std::to_string(axis.line) + ": axis " + axis.key});
  }
  return out;
}

std::vector<PointPlan> PlanPoints(const Campaign& c, const std::string& scenario_text,
                                  const std::vector<ScenarioOverride>& base,
                                  const std::vector<CampaignPoint>& points, bool refuse_large) {
  const RunPace pace = c.engine == CampaignEngine::kSim        ? RunPace::kSim
                       : c.engine == CampaignEngine::kLockstep ? RunPace::kLockstep
                                                               : RunPace::kRealtime;
  std::vector<PointPlan> plans;
  plans.reserve(points.size());
  // The file is parsed once, not once a point: a campaign of a million points is checked
  // in minutes rather than hours.
  std::optional<ScenarioTemplate> scenario;
  for (const CampaignPoint& p : points) {
    PointPlan plan;
    Scenario s;
    try {
      if (!scenario) scenario.emplace(scenario_text, c.scenario);
      s = scenario->Read(PointOverrides(c, base, p));
    } catch (const ScenarioError& e) {
      throw CampaignError(std::string(e.what()) + " (point " + std::to_string(p.index) + ")");
    }
    plan.duration_s = c.duration_s > 0 ? c.duration_s : s.duration_s;
    // What shoal sim and shoal run would refuse for every point, refused once, before any
    // runs (the scenario's own duration_s was checked as it loaded).
    if (c.duration_s > 0) {
      char what[160] = "";
      if (c.duration_s * 1e6 < static_cast<double>(s.period_us())) {
        std::snprintf(what, sizeof what, "is shorter than one control period (%g s at %g Hz)",
                      static_cast<double>(s.period_us()) * 1e-6, s.control_rate_hz);
      } else if (const std::string ticks = s.TickLimitRefusal(c.duration_s); !ticks.empty()) {
        std::snprintf(what, sizeof what, "is too long: %s", ticks.c_str());
      }
      if (what[0] != '\0') {
        char got[64];
        std::snprintf(got, sizeof got, " (got %g)", c.duration_s);
        throw CampaignError(c.path + ": campaign.duration_s: " + what + got + " (point " +
                            std::to_string(p.index) + ")");
      }
    }
    if (refuse_large) {
      const std::string large = LargeRunRefusal(s, plan.duration_s, pace,
                                                "campaign.duration_s (or run.duration_s)",
                                                "shoal sweep --allow-large (it passes it on)");
      if (!large.empty()) {
        throw CampaignError(c.path + ": point " + std::to_string(p.index) + ": " + large);
      }
    }
    plans.push_back(std::move(plan));
  }
  return plans;
}

double PointTimeout(const Campaign& c, const PointPlan& plan) {
  if (c.timeout_s > 0) return c.timeout_s;
  const double speed = c.engine == CampaignEngine::kRealtime   ? 1.0
                       : c.engine == CampaignEngine::kLockstep ? 10.0
                                                               : 100.0;
  // Capped at a year: beyond that the deadline would overflow the clock, and a point
  // that long is a mistake the scenario's own size limits let through.
  return std::min(60.0 + 10.0 * plan.duration_s / speed, 365.0 * 86400.0);
}

}  // namespace shoal
