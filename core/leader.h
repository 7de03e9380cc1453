// The leader (id 0): publishes its path's state each tick. Used by shoal sim and by the
// leader process.
#pragma once

#include "core/leader_path.h"
#include "core/state_msg.h"

namespace shoal {

class Leader {
 public:
  explicit Leader(const Scenario& s) : path_(s.leader) {
    out_.vehicle_id = 0;
    out_.seq = -1;
    out_.flags = StateMsg::kFlagLeader;
  }

  /// The leader's state at `now` (the message to publish on SHOAL_STATE_0).
  const StateMsg& Tick(Micros now) {
    const LeaderSample s = path_.At(ToSeconds(now), &anchor_);
    out_.seq += 1;
    out_.utime = now;
    out_.eta = s.eta;
    out_.nu = s.nu;
    out_.eta_dot = s.eta_dot;
    return out_;
  }

 private:
  LeaderPath path_;
  LeaderPath::HelixAnchor anchor_;
  StateMsg out_;
};

}  // namespace shoal
