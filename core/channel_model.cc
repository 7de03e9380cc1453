#include "core/channel_model.h"

#include <cmath>

namespace shoal {

std::vector<Link> BuildLinks(const Scenario& s, const Topology& topo) {
  const std::vector<std::pair<int, int>> pairs = topo.Links();
  std::vector<Link> links;
  links.reserve(pairs.size());  // a dense swarm has 10^5 links: no copies while it grows
  for (const auto& [from, to] : pairs) {
    Link l;
    l.from = from;
    l.to = to;
    l.delay = s.delay;
    l.loss = s.loss;
    for (const LinkOverride& o : s.links) {
      if (o.from == from && o.to == to) {
        if (o.delay) l.delay = *o.delay;
        if (o.loss) l.loss = *o.loss;
      }
    }
    l.rng = Rng(s.seed, 0x11A4ULL + static_cast<std::uint64_t>(from),
                static_cast<std::uint64_t>(to));
    l.loss_rng = Rng(s.seed, 0x6E11ULL + static_cast<std::uint64_t>(from),
                     static_cast<std::uint64_t>(to));
    links.push_back(l);
  }
  return links;
}

std::vector<Link> BuildAllLinks(const Scenario& s) { return BuildLinks(s, UnionTopology(s)); }

std::vector<Micros> ModemIntervals(const Scenario& s) {
  const auto us = [](double seconds) { return static_cast<Micros>(std::llround(seconds * 1e6)); };
  std::vector<Micros> interval(static_cast<std::size_t>(s.followers + 1),
                               us(s.modem_min_interval_s));
  for (const ModemConfig& m : s.modems) {
    if (m.id >= 0 && m.id <= s.followers) interval[static_cast<std::size_t>(m.id)] = us(m.min_interval_s);
  }
  return interval;
}

}  // namespace shoal
