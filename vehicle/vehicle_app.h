// The follower process (ids 1..n): protocol (10) on the core's Follower, fed with what the
// channel emulator delivers on SHOAL_RX_<id>. In lockstep a delivery is held until the
// clock window lists it for a tick, and applied at that tick (runtime/clocked_node.h).
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "core/follower.h"
#include "runtime/clocked_node.h"

namespace shoal {

struct VehicleRxCounters {
  std::int64_t bad_rx = 0;       // undecodable / wrong fingerprint / truncated on SHOAL_RX
  std::int64_t unlisted_rx = 0;  // lockstep: held messages no tick listed (not replays)
};

class VehicleApp : public ClockedNode {
 public:
  /// `id` in 1..followers; buses as ClockedNode.
  VehicleApp(const Scenario& s, int id, Mode mode, std::int64_t t0_ns, double duration_s, Bus* bus,
             Bus* rx_bus);

  const VehicleRxCounters& rx_counters() const { return rx_counters_; }
  const Follower& follower() const { return follower_; }

 private:
  static constexpr int kRxKind = kFirstInputKind;
  // What of a held delivery its tick uses: Follower::Receive takes only these (every
  // number of the message was checked finite when it was held). Half a StateMsg, so a
  // window's held deliveries fill half the cache lines.
  struct Held {
    std::int32_t sender = 0;
    std::int32_t seq = 0;
    Micros utime = 0;
    std::int64_t digest = 0;  // DeliveryDigest of the bytes received
    Vec5 eta = Vec5::Zero();
    Vec5 eta_dot = Vec5::Zero();
  };
  static StateMsg Unheld(const Held& h);

  void SubscribeInputs() override;
  bool OnInput(int kind, const unsigned char* data, int size) override;
  const Delivery* ApplyListed(const std::vector<Delivery>& listed) override;
  void AfterLockstepStep(std::int64_t tick) override;
  const StateMsg& StepAt(Micros now) override { return follower_.Tick(now); }
  health_t Health(Micros utime) const override;
  void SaveCheckpoint(CheckpointPayload* out) const override;
  bool RestoreCheckpoint(std::int64_t tick, CheckpointPayload* in) override;
  /// Lockstep: drops held message k, which no tick listed, counting it.
  void DropHeld(std::size_t k);

  Follower follower_;
  std::vector<Held> held_;              // lockstep: received, not yet listed, in arrival order
  std::vector<std::size_t> listed_at_;  // ApplyListed's scratch: held_ index per listed one
  Micros listable_us_ = 0;  // lockstep: a delivery is listed within this of its send time
  VehicleRxCounters rx_counters_;
};

/// The whole main() of shoal_vehicle: parse flags, load, run.
int VehicleMain(int argc, char** argv);

}  // namespace shoal
