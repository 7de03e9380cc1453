// The largest acoustic delay the formation itself produces: in formation follower i sits
// at the leader's position plus its offset d_i ([control] offsets_m), so a link from j to
// i spans |d_i - d_j| (from the leader: |d_i|) and its acoustic delay is at most
// range / sound_speed + processing + jitter (docs/theory.md, "Switching topologies and
// acoustic delays").
#pragma once

#include "core/scenario.h"

namespace shoal {
namespace design {

struct FormationDelay {
  bool applicable = false;  ///< some link of some topology (or a channel event) is acoustic
  int acoustic_links = 0;   ///< (link, model) pairs considered
  /// max over them of min(range, max_range_m) / sound_speed + processing_s + jitter_s.
  double in_formation_s = 0.0;
  int from = -1, to = -1;   ///< the link that gives it (0: the leader)
  double range_m = 0.0;     ///< that link's length in formation
  /// Links longer than their model's max_range_m in formation: their messages are lost
  /// while the formation holds (the delay above counts them at max_range_m).
  int beyond_range_links = 0;
  /// max over the same models of MaxDelaySeconds (the delay at max_range_m): the bound
  /// for any geometry, which is the scenario's h.
  double model_bound_s = 0.0;
};

/// Over every link of every topology the timeline produces (UnionTopology), each with its
/// [channel.delay] default or [[channel.link]] override, and every channel event's delay
/// on the links it lists.
FormationDelay FormationAcousticDelay(const Scenario& s);

}  // namespace design
}  // namespace shoal
