#include "design/formation_delay.h"

#include <algorithm>
#include <vector>

#include "core/channel_model.h"
#include "core/timeline.h"

namespace shoal {
namespace design {
namespace {

double FormationRange(const Scenario& s, int from, int to) {
  auto offset = [&](int id) -> Vec3 {
    return id >= 1 && id <= static_cast<int>(s.offsets_m.size())
               ? s.offsets_m[static_cast<std::size_t>(id - 1)]
               : Vec3(Vec3::Zero());
  };
  return (offset(to) - offset(from)).norm();
}

bool Lists(const ScenarioEvent& e, int from, int to) {
  if (e.links.empty()) return true;
  return std::find(e.links.begin(), e.links.end(), std::make_pair(from, to)) != e.links.end();
}

void AddLink(const Scenario& s, int from, int to, const DelayConfig& c, FormationDelay* f) {
  if (c.kind != DelayKind::kAcoustic) return;
  f->applicable = true;
  ++f->acoustic_links;
  const double range = FormationRange(s, from, to);
  const bool beyond = c.max_range_m > 0.0 && range > c.max_range_m;
  if (beyond) ++f->beyond_range_links;
  const double counted = beyond ? c.max_range_m : range;
  const double delay = counted / c.sound_speed_mps + c.processing_s + c.jitter_s;
  if (f->from < 0 || delay > f->in_formation_s) {
    f->in_formation_s = delay;
    f->from = from;
    f->to = to;
    f->range_m = range;
  }
  f->model_bound_s = std::max(f->model_bound_s, MaxDelaySeconds(c));
}

}  // namespace

FormationDelay FormationAcousticDelay(const Scenario& s) {
  FormationDelay f;
  for (const Link& l : BuildLinks(s, UnionTopology(s))) {
    AddLink(s, l.from, l.to, l.delay, &f);
    for (const ScenarioEvent& e : s.events) {
      if (e.kind == EventKind::kChannel && e.delay && Lists(e, l.from, l.to)) {
        AddLink(s, l.from, l.to, *e.delay, &f);
      }
    }
  }
  return f;
}

}  // namespace design
}  // namespace shoal
