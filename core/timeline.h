// The scenario's [[event]] timeline, resolved once for every engine (shoal sim, the channel
// emulator, the vehicle processes), so that a lockstep run stays equal to shoal sim with
// events. The state it describes is piecewise constant between the events' start and end
// times; each piece (a segment) is tabulated when the timeline is built, so a query is a
// binary search over the change times and a table lookup.
#pragma once

#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "core/scenario.h"
#include "core/topology.h"
#include "core/types.h"

namespace shoal {

/// A time of the timeline in whole microseconds (rounded); infinity and beyond-range
/// times saturate at the largest Micros.
Micros TimelineMicros(double seconds);

/// The graph with every edge and leader link of every topology the timeline produces:
/// the links the channel serves and the neighbours a follower keeps slots for.
Topology UnionTopology(const Scenario& s);

class Timeline {
 public:
  /// No events: nothing ever changes.
  Timeline() = default;
  /// The timeline of a validated scenario.
  explicit Timeline(const Scenario& s);

  bool empty() const { return events_.empty(); }
  const std::vector<ScenarioEvent>& events() const { return events_; }

  /// Every link of every topology, in UnionTopology(s).Links() order: the channel's links
  /// in the same order, so link index k means the same link everywhere.
  const std::vector<std::pair<int, int>>& links() const { return links_; }
  /// Index of the link (from, to) in links(), -1 if there is none.
  int LinkIndex(int from, int to) const;

  /// The topologies: [0] the scenario's [swarm] one, then one per topology event, in the
  /// order of the file.
  const std::vector<Topology>& topologies() const { return topologies_; }
  /// Index in topologies() of the topology in force at t.
  int TopologyAt(Micros t) const;

  /// Link k (of links()) belongs to the topology in force at t.
  bool LinkActive(std::size_t k, Micros t) const { return Link(k, t) & kActive; }
  /// Link k is down (a link_down event) at t.
  bool LinkDown(std::size_t k, Micros t) const { return Link(k, t) & kDown; }
  /// The channel event whose models link k takes at t, or nullptr.
  const ScenarioEvent* ChannelChange(std::size_t k, Micros t) const;
  /// Vehicle id (0: the leader) does not send at t.
  bool Silent(int id, Micros t) const { return Vehicle(id, t) & kSilent; }
  /// Vehicle id receives nothing due at t.
  bool Deaf(int id, Micros t) const { return Vehicle(id, t) & kDeaf; }
  /// Follower id's controller is reset (no memory, zero force) at t.
  bool InReset(int id, Micros t) const { return Vehicle(id, t) & kReset; }
  /// Start of follower id's reset window in force at t, kNoReset if none (two windows
  /// that touch are two resets).
  static constexpr Micros kNoReset = std::numeric_limits<Micros>::min();
  Micros ResetStart(int id, Micros t) const;

  /// True if some event switches the topology (followers then check their links per tick).
  bool switches_topology() const { return topologies_.size() > 1; }
  /// True if some event resets a controller.
  bool resets() const { return resets_; }
  /// Every delay model a channel event gives: the lockstep lookahead and the histories
  /// must allow for them as for the [channel] ones.
  std::vector<DelayConfig> EventDelays() const;

 private:
  enum : std::uint8_t { kActive = 1, kDown = 2 };
  enum : std::uint8_t { kSilent = 1, kDeaf = 2, kReset = 4 };
  struct Segment {
    Micros start = 0;
    int topology = 0;
    std::vector<std::uint8_t> link;      // per link: kActive | kDown
    std::vector<std::int32_t> channel;   // per link: event index or -1 (empty: none)
    std::vector<std::uint8_t> vehicle;   // per id 0..n: kSilent | kDeaf | kReset
    std::vector<Micros> reset_at;        // per id: its reset window's start (if any reset)
  };

  const Segment* SegmentAt(Micros t) const;
  std::uint8_t Link(std::size_t k, Micros t) const;
  std::uint8_t Vehicle(int id, Micros t) const;
  void Tabulate(Segment* seg, const std::vector<Micros>& topo_end) const;

  std::vector<ScenarioEvent> events_;
  std::vector<Micros> at_us_, end_us_;  // per event
  std::vector<int> topology_of_;        // per event: its index in topologies_, or -1
  std::vector<Topology> topologies_;
  std::vector<std::pair<int, int>> links_;
  std::vector<std::pair<std::pair<int, int>, int>> link_index_;  // sorted (link, k)
  std::vector<Segment> segments_;  // by start; segments_[0].start is the smallest Micros
  int ids_ = 0;
  bool resets_ = false;
};

}  // namespace shoal
