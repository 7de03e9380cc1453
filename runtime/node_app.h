// A vehicle process's life (follower or leader): construct (no I/O) -> Init (subscribe)
// -> Run (lockstep: one Tick per SHOAL_CLOCK tick; realtime: fixed-rate loop on absolute
// deadlines) -> exit code. The maths is the core's Follower / Leader, unchanged.
#pragma once

#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/follower.h"
#include "core/leader.h"
#include "runtime/clock.h"
#include "runtime/lcm_bus.h"
#include "runtime/process.h"

namespace shoal {

struct NodeCounters {
  std::int64_t bad_rx = 0;     // undecodable / wrong fingerprint / truncated on SHOAL_RX
  std::int64_t bad_clock = 0;  // undecodable, duplicate, out-of-order or foreign clock ticks
  std::int64_t unlisted_rx = 0;  // lockstep: held messages no tick listed (not replays)
  std::int64_t overruns = 0;
};

class NodeApp {
 public:
  /// id 0 runs the leader, 1..n a follower. `bus` is the shared bus, `rx_bus` the one this
  /// node receives on (may be the same object).
  NodeApp(const Scenario& s, int id, Mode mode, std::int64_t t0_ns, double duration_s,
          Bus* bus, Bus* rx_bus);

  void Init();
  /// Runs to the end of the scenario or until StopRequested(). Returns the exit code:
  /// 0 finished, 1 stopped early, 3 no clock came (lockstep).
  int Run();

  const NodeCounters& counters() const { return counters_; }
  const Follower* follower() const { return follower_.get(); }

 private:
  void OnRx(const void* data, int size);
  void OnClock(const void* data, int size);
  void Step(std::int64_t tick);
  /// Lockstep: steps every tick whose clock tick and listed deliveries are all here.
  void StepWhatIsDue();
  /// Lockstep: drops held message k, which no tick listed, counting it.
  void DropHeld(std::size_t k);
  void PublishHealth(Micros utime);
  void PublishStatus(const std::string& state, const std::string& message);
  int RunLockstep();
  int RunRealtime();

  const Scenario& s_;
  int id_;
  Mode mode_;
  std::int64_t t0_ns_;
  Micros period_us_;
  std::int64_t final_tick_;
  Bus* bus_;
  Bus* rx_bus_;
  std::unique_ptr<Follower> follower_;
  std::unique_ptr<Leader> leader_;
  std::string state_channel_, health_channel_;
  std::int64_t next_tick_ = 0;  // lockstep: the clock tick expected next
  // Lockstep: clock ticks received, by tick, with the deliveries (sender, seq, digest) each lists
  // for this vehicle; and the deliveries received and not yet applied, in arrival order.
  struct DueTick {
    bool final_tick = false;
    struct Delivery {
      std::int32_t sender;
      std::int32_t seq;
      std::int64_t digest;
    };
    std::vector<Delivery> deliveries;
  };
  std::map<std::int64_t, DueTick> due_;
  struct Held {
    StateMsg msg;
    std::int64_t digest = 0;  // Digest64 of the bytes received
  };
  std::vector<Held> held_;
  std::int64_t max_ticks_ahead_ = 1;  // clock ticks accepted: [next_tick_, + this)
  Micros listable_us_ = 0;            // a delivery is listed within this of its send time
  std::int64_t waiting_since_ns_ = 0;  // when the tick expected next started to wait
  bool warned_waiting_ = false;
  std::int64_t last_step_ns_ = 0;  // lockstep: when a tick was last stepped
  bool done_ = false;
  std::int32_t health_seq_ = 0, status_seq_ = 0;
  NodeCounters counters_;
  LatenessStats lateness_;
};

/// The whole main() of shoal_vehicle / shoal_leader: parse flags, load, run.
int NodeMain(int argc, char** argv, bool leader);

}  // namespace shoal
