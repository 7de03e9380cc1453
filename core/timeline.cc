#include "core/timeline.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace shoal {

namespace {
constexpr Micros kNever = std::numeric_limits<Micros>::max();
constexpr Micros kAlways = std::numeric_limits<Micros>::min();

}  // namespace

Micros TimelineMicros(double seconds) {
  if (!(seconds * 1e6 < 9.2e18)) return kNever;  // infinity, or beyond Micros
  if (!(seconds * 1e6 > -9.2e18)) return kAlways;
  return static_cast<Micros>(std::llround(seconds * 1e6));
}

Topology UnionTopology(const Scenario& s) {
  std::vector<std::pair<int, int>> edges = s.edges;
  std::vector<int> leader_links = s.leader_links;
  for (const ScenarioEvent& e : s.events) {
    if (e.kind != EventKind::kTopology) continue;
    edges.insert(edges.end(), e.edges.begin(), e.edges.end());
    leader_links.insert(leader_links.end(), e.leader_links.begin(), e.leader_links.end());
  }
  return Topology::Build(s.followers, edges, leader_links);
}

Timeline::Timeline(const Scenario& s) : events_(s.events), ids_(s.followers + 1) {
  if (events_.empty()) return;
  links_ = UnionTopology(s).Links();
  for (std::size_t k = 0; k < links_.size(); ++k) {
    link_index_.push_back({links_[k], static_cast<int>(k)});
  }
  std::sort(link_index_.begin(), link_index_.end());

  topologies_.push_back(Topology::Build(s.followers, s.edges, s.leader_links));
  std::vector<Micros> change = {kAlways};
  for (const ScenarioEvent& e : events_) {
    at_us_.push_back(TimelineMicros(e.at_s));
    end_us_.push_back(TimelineMicros(e.end_s()));
    topology_of_.push_back(-1);
    if (e.kind == EventKind::kTopology) {
      topology_of_.back() = static_cast<int>(topologies_.size());
      topologies_.push_back(Topology::Build(s.followers, e.edges, e.leader_links));
    }
    resets_ = resets_ || e.kind == EventKind::kControllerReset;
  }
  // A topology holds until its until_s or the next topology event's start, whichever
  // comes first.
  std::vector<Micros> topo_end = end_us_;
  for (std::size_t a = 0; a < events_.size(); ++a) {
    if (topology_of_[a] < 0) continue;
    for (std::size_t b = 0; b < events_.size(); ++b) {
      if (b != a && topology_of_[b] >= 0 && at_us_[b] > at_us_[a]) {
        topo_end[a] = std::min(topo_end[a], at_us_[b]);
      }
    }
  }
  for (std::size_t a = 0; a < events_.size(); ++a) {
    change.push_back(at_us_[a]);
    const Micros end = topology_of_[a] >= 0 ? topo_end[a] : end_us_[a];
    if (end != kNever) change.push_back(end);
  }
  std::sort(change.begin(), change.end());
  change.erase(std::unique(change.begin(), change.end()), change.end());
  for (Micros start : change) {
    Segment seg;
    seg.start = start;
    Tabulate(&seg, topo_end);
    segments_.push_back(std::move(seg));
  }
}

void Timeline::Tabulate(Segment* seg, const std::vector<Micros>& topo_end) const {
  const Micros t = seg->start;
  auto active = [&](std::size_t a, Micros end) { return at_us_[a] <= t && t < end; };
  // The topology in force: the latest-starting topology event whose window holds t.
  Micros latest = kAlways;
  for (std::size_t a = 0; a < events_.size(); ++a) {
    if (topology_of_[a] >= 0 && active(a, topo_end[a]) && at_us_[a] >= latest) {
      latest = at_us_[a];
      seg->topology = topology_of_[a];
    }
  }
  const Topology& topo = topologies_[static_cast<std::size_t>(seg->topology)];
  seg->link.assign(links_.size(), 0);
  for (std::size_t k = 0; k < links_.size(); ++k) {
    const auto [from, to] = links_[k];
    const bool in = from == 0 ? topo.Pinned(to) : topo.A()(to - 1, from - 1) > 0.0;
    if (in) seg->link[k] |= kActive;
  }
  seg->vehicle.assign(static_cast<std::size_t>(ids_), 0);
  for (std::size_t a = 0; a < events_.size(); ++a) {
    const ScenarioEvent& e = events_[a];
    if (!active(a, end_us_[a])) continue;
    switch (e.kind) {
      case EventKind::kLinkDown:
      case EventKind::kChannel: {
        // Listed links by lookup, not by scanning every link per listed link: a long list
        // on a large swarm stays cheap.
        auto mark = [&](std::size_t k) {
          if (e.kind == EventKind::kLinkDown) {
            seg->link[k] |= kDown;
          } else {
            if (seg->channel.empty()) seg->channel.assign(links_.size(), -1);
            seg->channel[k] = static_cast<std::int32_t>(a);
          }
        };
        if (e.links.empty()) {
          for (std::size_t k = 0; k < links_.size(); ++k) mark(k);
        }
        for (const auto& [from, to] : e.links) {
          const int k = LinkIndex(from, to);
          if (k >= 0) mark(static_cast<std::size_t>(k));
        }
        break;
      }
      case EventKind::kVehicleSilent:
      case EventKind::kVehicleDeaf:
      case EventKind::kControllerReset: {
        const std::uint8_t flag = e.kind == EventKind::kVehicleSilent ? kSilent
                                  : e.kind == EventKind::kVehicleDeaf  ? kDeaf
                                                                       : kReset;
        for (int id : e.vehicles) {
          if (id < 0 || id >= ids_) continue;
          seg->vehicle[static_cast<std::size_t>(id)] |= flag;
          if (flag == kReset) {
            if (seg->reset_at.empty()) seg->reset_at.assign(static_cast<std::size_t>(ids_), kNoReset);
            seg->reset_at[static_cast<std::size_t>(id)] = at_us_[a];
          }
        }
        break;
      }
      case EventKind::kLeaderSilent:
        seg->vehicle[0] |= kSilent;
        break;
      case EventKind::kTopology:
        break;
    }
  }
}

int Timeline::LinkIndex(int from, int to) const {
  const std::pair<int, int> key(from, to);
  auto it = std::lower_bound(link_index_.begin(), link_index_.end(),
                             std::make_pair(key, std::numeric_limits<int>::min()));
  return it != link_index_.end() && it->first == key ? it->second : -1;
}

const Timeline::Segment* Timeline::SegmentAt(Micros t) const {
  if (segments_.empty()) return nullptr;
  // The last segment that starts at or before t (segments_[0] starts before every t).
  auto it = std::upper_bound(segments_.begin(), segments_.end(), t,
                             [](Micros v, const Segment& s) { return v < s.start; });
  return &*(it - 1);
}

int Timeline::TopologyAt(Micros t) const {
  const Segment* s = SegmentAt(t);
  return s ? s->topology : 0;
}

std::uint8_t Timeline::Link(std::size_t k, Micros t) const {
  const Segment* s = SegmentAt(t);
  if (s == nullptr) return kActive;
  return k < s->link.size() ? s->link[k] : 0;
}

std::uint8_t Timeline::Vehicle(int id, Micros t) const {
  const Segment* s = SegmentAt(t);
  if (s == nullptr || id < 0 || id >= static_cast<int>(s->vehicle.size())) return 0;
  return s->vehicle[static_cast<std::size_t>(id)];
}

Micros Timeline::ResetStart(int id, Micros t) const {
  const Segment* s = SegmentAt(t);
  if (s == nullptr || s->reset_at.empty() || id < 0 ||
      id >= static_cast<int>(s->reset_at.size())) {
    return kNoReset;
  }
  return s->reset_at[static_cast<std::size_t>(id)];
}

const ScenarioEvent* Timeline::ChannelChange(std::size_t k, Micros t) const {
  const Segment* s = SegmentAt(t);
  if (s == nullptr || s->channel.empty() || k >= s->channel.size() || s->channel[k] < 0) {
    return nullptr;
  }
  return &events_[static_cast<std::size_t>(s->channel[k])];
}

std::vector<DelayConfig> Timeline::EventDelays() const {
  std::vector<DelayConfig> d;
  for (const ScenarioEvent& e : events_) {
    if (e.kind == EventKind::kChannel && e.delay) d.push_back(*e.delay);
  }
  return d;
}

}  // namespace shoal
