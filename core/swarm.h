// The whole swarm in one process with the step semantics every mode shares:
//   tick k at t_k = k * period:
//     1. the channel delivers every message due at or before t_k (SHOAL_RX_<id>);
//     2. the leader and each follower step once and publish their state at t_k;
//     3. each published state enters the channel (usable from tick k+1 at the earliest).
// shoal sim runs this loop as fast as the CPU allows; the SIL processes run the same
// objects (Leader, Follower, Channel) split across processes.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/channel_model.h"
#include "core/follower.h"
#include "core/leader.h"
#include "core/metrics.h"

namespace shoal {

/// Receives everything the swarm "publishes", in bus order. Default: ignore.
class SwarmObserver {
 public:
  virtual ~SwarmObserver() = default;
  virtual void OnTick(std::int64_t /*tick*/, Micros /*utime*/, bool /*final_tick*/) {}
  virtual void OnDeliver(int /*receiver*/, const StateMsg& /*msg*/) {}
  virtual void OnState(const StateMsg& /*msg*/) {}
  virtual void OnChannel(const ChannelDecision& /*decision*/) {}
  /// Once per simulated second, and at the final tick, for each follower.
  virtual void OnHealth(Micros /*utime*/, const Follower& /*f*/) {}
};

/// What a run will cost, estimated before it starts (a guard against runs of years).
struct RunEstimate {
  std::int64_t ticks = 0;
  std::int64_t links = 0;      // channel links, leader's included
  double memory_bytes = 0.0;   // histories and the channel's pending deliveries
  double wall_seconds = 0.0;   // shoal sim on one core of a current PC
  /// Beyond these a run is refused unless the user allows it (--allow-large).
  static constexpr double kMaxMemoryBytes = 4.0 * (1 << 30);
  static constexpr double kMaxWallSeconds = 3600.0;
  bool large() const { return memory_bytes > kMaxMemoryBytes || wall_seconds > kMaxWallSeconds; }
  /// "3.6e+09 ticks x 4 followers and 7 links: about 2.1 h and 1.2 GiB of memory"
  std::string Describe(int followers) const;
};

/// The estimate of a run of `duration_s` (< 0: the scenario's) of a validated scenario.
RunEstimate EstimateRun(const Scenario& s, double duration_s = -1.0);

/// How a run spends wall time against shoal sim's estimate: a lockstep SIL run is a round
/// of messages between processes every tick (measured on Example 2: about 17x slower
/// than shoal sim), and a real-time run takes its simulated duration.
enum class RunPace { kSim, kLockstep, kRealtime };

/// "" if the run is not large, else why it is refused and how to run it anyway: `shorten`
/// names what sets the duration there, `anyway` the flag and command that run it anyway.
std::string LargeRunRefusal(const Scenario& s, double duration_s = -1.0,
                            RunPace pace = RunPace::kSim,
                            const std::string& shorten = "run.duration_s or --duration",
                            const std::string& anyway = "--allow-large");

class Swarm {
 public:
  /// A validated scenario; `duration_s` < 0 uses the scenario's.
  explicit Swarm(const Scenario& s, double duration_s = -1.0);

  /// Runs tick `next_tick()`; returns false when the run is over (after the final tick).
  bool Step(SwarmObserver* obs);
  /// Runs to the end, or until `*stop` becomes true (checked each tick).
  void Run(SwarmObserver* obs, const volatile bool* stop = nullptr);

  std::int64_t next_tick() const { return tick_; }
  std::int64_t final_tick() const { return final_tick_; }
  Micros period_us() const { return period_us_; }
  double sim_time_s() const { return ToSeconds(last_utime_); }
  /// The last tick's time, exact (sim_time_s() * 1e6 can fall a microsecond short).
  Micros sim_time_us() const { return last_utime_; }
  const FormationMetrics& metrics() const { return metrics_; }
  const std::vector<std::unique_ptr<Follower>>& followers() const { return followers_; }
  /// Id of the first follower that diverged (0 if none); the run stops there.
  int diverged_id() const { return diverged_id_; }
  std::int64_t delivered() const { return delivered_; }
  std::int64_t dropped() const { return dropped_; }

 private:
  Topology topo_;  // every topology's links (UnionTopology)
  std::shared_ptr<const Timeline> timeline_;  // null: no events
  Micros period_us_;
  std::int64_t final_tick_;
  std::int64_t tick_ = 0;
  Micros last_utime_ = 0;
  Leader leader_;
  std::vector<std::unique_ptr<Follower>> followers_;
  Channel<StateMsg> channel_;
  FormationMetrics metrics_;
  std::vector<const StateMsg*> published_;
  std::vector<ForceJob*> forces_;  // the followers' inner loops of the tick
  std::vector<PlantJob> jobs_;     // the followers' integrations of the tick
  bool together_ = false;        // every follower has the same plant: IntegrateMany
  std::vector<ChannelDecision> decisions_;
  int diverged_id_ = 0;
  std::int64_t delivered_ = 0;
  std::int64_t dropped_ = 0;

  // Shared by the followers; warmed once per tick (they all ask for the same time).
  std::shared_ptr<Environment> env_;
  bool warm_env_ = false;
};

}  // namespace shoal
