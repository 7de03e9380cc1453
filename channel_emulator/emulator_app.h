// The channel emulator process: the only path between vehicles. For every directed link
// it applies the scenario's delay and loss models (core Channel) and delivers each
// message, unchanged, on SHOAL_RX_<receiver>; every decision is published on
// SHOAL_CHANNEL. In lockstep it is also the clock master.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/channel_model.h"
#include "core/scenario.h"
#include "runtime/clock.h"
#include "runtime/lcm_bus.h"
#include "runtime/messages.h"
#include "runtime/process.h"
#include "runtime/recorder_gate.h"

namespace shoal {

struct EmulatorCounters {
  std::int64_t states_accepted = 0;
  std::int64_t states_invalid = 0;  // undecodable, wrong id for the channel, NaN/Inf
  std::int64_t states_old = 0;      // duplicate / replayed / out-of-order seq, wrong tick
  std::int64_t delivered = 0;
  std::int64_t dropped = 0;
};

class EmulatorApp {
 public:
  /// `vehicle_buses[id]` is where vehicle id receives (its SHOAL_RX and, in lockstep, the
  /// clock); entries may all be `bus`.
  /// `max_lookahead_ticks` (lockstep): how many ticks the clock master may release before
  /// it waits for the states; the channel's minimum delivery lag bounds it (see Run).
  EmulatorApp(const Scenario& s, Mode mode, std::int64_t t0_ns, double duration_s, Bus* bus,
              std::vector<Bus*> vehicle_buses, std::int64_t max_lookahead_ticks = 50);
  void Init();
  /// 0: ran to the end with every process; 4: ran to the end, some process stopped
  /// answering (named on stderr and in SHOAL_STATUS); 1: interrupted; 3: start-up failed.
  int Run();
  const EmulatorCounters& counters() const { return counters_; }
  /// Lockstep: before each window, wait (at most 20 ms) until this process -- the run's
  /// lcm-logger -- has handled what it was sent (runtime/recorder_gate.h).
  void SetRecorder(pid_t pid) { recorder_ = std::make_unique<RecorderGate>(pid); }
  /// Ticks released per round trip in lockstep (1 = wait for the states after every tick).
  std::int64_t lookahead_ticks() const { return lookahead_; }

 private:
  using Bytes = std::vector<unsigned char>;
  /// A state in transit: its encoded bytes (forwarded unchanged) and its identity, which
  /// a lockstep clock tick lists for the receiver.
  struct Datagram {
    std::int32_t sender = 0;
    std::int32_t seq = 0;
    std::int64_t digest = 0;  // Digest64(raw)
    Bytes raw;
  };
  void OnState(const std::string& channel, const void* data, int size);
  void OnStatus(const void* data, int size);
  void Submit(int id, const Bytes& raw, std::int32_t seq, Micros utime);
  void ReleaseWindow();
  void PublishEvents();  // the decisions not yet published, on SHOAL_CHANNEL
  clock_tick_t WindowClock() const;  // ticks [win_first_, win_last_], no deliveries listed
  void PublishHealth(Micros utime);
  void PublishStatus(const std::string& state, const std::string& message);
  int RunLockstep();
  int RunRealtime();

  const Scenario& s_;
  Mode mode_;
  std::int64_t t0_ns_;
  Micros period_us_;
  std::int64_t final_tick_;
  Bus* bus_;
  std::vector<Bus*> vbus_;
  Channel<Datagram> channel_;
  std::vector<ChannelDecision> decisions_;
  std::vector<std::string> rx_channels_;
  int n_;  // followers
  // Lockstep: the distinct vehicle buses, each with the vehicles that receive on it, and
  // whether the shared bus is one of them (else the logger gets clock ticks of its own).
  std::vector<std::vector<int>> bus_groups_;
  bool shared_has_vehicles_ = false;
  struct Outgoing {
    std::int64_t tick;
    Datagram d;
  };
  std::vector<std::vector<Outgoing>> outbox_;  // lockstep window, per receiving vehicle
  ChannelEventBatch events_;  // decided, not yet published
  std::int64_t events_since_ns_ = 0;  // real time: when the oldest unpublished one was added

  // Per sender: newest accepted seq, and (lockstep) the states received for the ticks of
  // the current window [win_first_, win_last_], at slot (tick - win_first_) * (n + 1) + id.
  std::vector<std::int32_t> last_seq_;
  std::vector<bool> have_seq_;
  std::int64_t lookahead_ = 1;
  std::int64_t win_first_ = 0, win_last_ = -1;
  std::vector<bool> got_tick_;
  std::vector<Bytes> tick_state_;
  std::vector<std::int32_t> tick_seq_;
  std::vector<bool> alive_;
  std::vector<bool> ready_;
  std::int64_t tick_ = -1;  // lockstep: current tick
  std::int32_t clock_seq_ = 0, health_seq_ = 0, status_seq_ = 0;
  EmulatorCounters counters_;
  LatenessStats release_error_;  // realtime: release time - due time
  std::unique_ptr<RecorderGate> recorder_;
};

int EmulatorMain(int argc, char** argv);

}  // namespace shoal
