#include "core/channel_model.h"

namespace shoal {

std::vector<Link> BuildLinks(const Scenario& s, const Topology& topo) {
  std::vector<Link> links;
  for (const auto& [from, to] : topo.Links()) {
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
    links.push_back(l);
  }
  return links;
}

}  // namespace shoal
