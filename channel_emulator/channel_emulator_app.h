// The channel emulator process: the only path between vehicles. For every directed link
// it applies the scenario's delay and loss models (core Channel) and delivers each
// message, unchanged, on SHOAL_RX_<receiver>; every decision is published on
// SHOAL_CHANNEL. In lockstep it is also the clock master.
//
// LCM handlers copy the message into an inbox and return; HandleBus() then applies the
// inbox in arrival order (the channel's decisions are taken there, outside any handler).
// A lockstep state is the exception: its handler checks it and keeps it for its window,
// straight from where it was received, as nothing is decided until the window is whole.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/channel_model.h"
#include "core/scenario.h"
#include "runtime/clock.h"
#include "runtime/lcm_bus.h"
#include "runtime/overrun_note.h"
#include "runtime/udpm_sender.h"
#include "runtime/lcm_queue_shim.h"
#include "runtime/messages.h"
#include "runtime/process.h"
#include "channel_emulator/recorder_gate.h"

namespace shoal {

/// LCM's subscription queue (messages), what lcm-logger has unless shoal run widens it.
constexpr std::int64_t kLcmDefaultQueue = SHOAL_LCM_DEFAULT_QUEUE_CAPACITY;

struct EmulatorCounters {
  std::int64_t states_accepted = 0;
  std::int64_t states_invalid = 0;  // undecodable, wrong id for the channel, NaN/Inf
  std::int64_t states_old = 0;      // duplicate / replayed / out-of-order seq, wrong tick
  std::int64_t delivered = 0;
  std::int64_t dropped = 0;
};

class ChannelEmulatorApp {
 public:
  /// `vehicle_buses[id]` is where vehicle id receives (its SHOAL_RX and, in lockstep, the
  /// clock); entries may all be `bus`.
  /// `max_lookahead_ticks` (lockstep): how many ticks the clock master may release before
  /// it waits for the states; the channel's delivery lag at the window's ticks bounds it
  /// (LagBound, see RunLockstep), and so does the logger: one window sends the logger's bus at most two thirds of
  /// `recorder_queue` messages (states, deliveries it carries, clock, channel batch), the
  /// queue of lcm-logger's subscription (LCM's default 30; shoal run preloads
  /// runtime/lcm_queue_shim.c into it for SHOAL_LOGGER_QUEUE_CAPACITY).
  ChannelEmulatorApp(const Scenario& s, Mode mode, std::int64_t t0_ns, double duration_s,
                     Bus* bus, std::vector<Bus*> vehicle_buses,
                     std::int64_t max_lookahead_ticks = 50,
                     std::int64_t recorder_queue = kLcmDefaultQueue);
  void Init();
  /// 0: ran to the end with every process; 4: ran to the end, some process stopped
  /// answering (named on stderr and in SHOAL_STATUS); 1: interrupted; 3: start-up failed.
  int Run();
  const EmulatorCounters& counters() const { return counters_; }
  /// Lockstep: before each window, wait (at most 100 ms) until this process -- the run's
  /// lcm-logger -- has handled what it was sent (channel_emulator/recorder_gate.h).
  /// With an uplink, and the recorder counting what it has handled (RecorderProgress),
  /// the wait is instead until it has handled everything sent before the window's release
  /// and is at most a third of its queue behind: it records a window while the vehicles
  /// step the next.
  void SetRecorder(pid_t pid) {
    recorder_ = std::make_unique<RecorderGate>(pid);
    progress_ = std::make_unique<RecorderProgress>(pid);
  }
  /// Most ticks released per round trip in lockstep (1 = wait for the states after every
  /// tick): the cap; each window is as long as the channel's lag at its ticks allows.
  std::int64_t max_window_ticks() const { return max_window_; }
  /// The fewest ticks a window of the run has (the last one aside): the channel's
  /// smallest lag, or the cap.
  std::int64_t min_window_ticks() const { return min_window_; }
  /// The processes publish on `uplink`, where only this process listens (before Init):
  /// their messages are received there, and each that verified is passed on, unchanged,
  /// to the run's bus for the recorder, packed as recordable bundles (runtime/lcm_bus.h)
  /// per batch received in lockstep (before the window it completes is released), per
  /// control period in real time; so the recorder is woken by a few datagrams a window or
  /// period instead of one per process. Not with restarts: what is in flight to a dead
  /// emulator is never passed on.
  void SetUplink(Bus* uplink) { uplink_ = uplink; }
  /// The run's bus is not authenticated (--insecure): every status says so.
  void SetInsecure() { insecure_ = true; }
  /// This emulator replaces one that died (shoal run --restart on-failure); `note` says
  /// why and when, in its "restarted" status. Lockstep: it goes on from the tick the
  /// processes need, which they tell it (docs/reliability.md); the deliveries its
  /// predecessor held are lost.
  void SetRestarted(const std::string& note) {
    restarted_ = true;
    restart_note_ = note;
  }

 private:
  using Bytes = std::vector<unsigned char>;
  /// A state in transit: its encoded bytes (forwarded unchanged) and its identity, which
  /// a lockstep clock tick lists for the receiver.
  struct Datagram {
    std::int32_t sender = 0;
    std::int32_t seq = 0;
    std::int64_t digest = 0;  // DeliveryDigest(raw)
    Bytes raw;
  };
  /// A message as its handler copied it: SHOAL_STATUS, or a state on `channel`.
  struct Inbound {
    bool status = false;
    std::string channel;
    Bytes bytes;
  };
  void Enqueue(bool status, const std::string& channel, const void* data, int size);
  /// Dispatches what the shared bus has (waiting at most timeout_ms for the first
  /// message), then applies the inbox in arrival order (lockstep states were kept by their
  /// handlers, during the dispatch). Returns bus_->Handle's result.
  int HandleBus(int timeout_ms);
  void OnState(const std::string& channel, const unsigned char* data, int size);
  void OnStatus(const unsigned char* data, int size);
  /// Lockstep: process `id`, restarted, needs tick `next` next: it is alive again, the
  /// window's answer time starts anew, and it gets again the clock windows (with its
  /// deliveries) it missed while it was down (docs/reliability.md).
  void OnRestarted(int id, std::int64_t next);
  /// Lockstep: sends process `id` alone the clock of ticks [first, last] (at most one
  /// lookahead) with its deliveries of the current window among them.
  void ResendClock(int id, std::int64_t first, std::int64_t last);
  /// `position`: the state's (eta x, y, z), which the acoustic model's range needs: the
  /// emulator knows every vehicle's position from the states it forwards.
  /// `digest`: DeliveryDigest of the bytes (lockstep; 0 in real time, where no clock lists it).
  void Submit(int id, Bytes* raw, std::int64_t digest, std::int32_t seq, Micros utime,
              const Vec3& position);
  void ReleaseWindow();
  void PublishEvents();  // the decisions not yet published, on SHOAL_CHANNEL
  clock_window_t WindowClock() const;  // ticks [win_first_, win_last_], no deliveries listed
  void SetWindowClock(clock_window_t* c) const;  // the same into *c, its vectors kept
  void PublishHealth(Micros utime);
  /// On the shared bus; `to_vehicles`: also on every vehicle bus (the processes hear it).
  void PublishStatus(RunState state, const std::string& message, bool to_vehicles = false);
  int RunLockstep();
  /// Lockstep: waits until every process has announced itself. Returns -1 then, else the
  /// exit code: 1 stopped, 3 (reported) nobody came within 60 s.
  int WaitForReady();
  /// Lockstep, restarted: asks every process for the tick it needs next, sends each the
  /// clock up to the newest of them (the windows its predecessor released to some and
  /// not to others), and returns -1 with start_tick_ set; else the exit code (1 stopped).
  int Rejoin();
  enum class WindowWait { kComplete, kStopped, kTimedOut };
  /// Lockstep: waits for the state of every live process for every tick of the window.
  WindowWait WaitForWindow();
  /// Lockstep: marks every live process that sent no state for some tick of the window
  /// as lost, saying so on stderr and on SHOAL_STATUS.
  void DeclareSilentLost();
  /// Lockstep: the window's states enter the channel (tick by tick, in id order).
  void SubmitWindow();
  int RunRealtime();
  /// Real time: the smallest and the largest delay the scenario's channel can give (its
  /// default, its links' and its events' delay models), seconds.
  std::pair<double, double> DelayBounds() const;
  /// Real time: waits for what comes next, until at most `wake_ns`. With `drain_ns` > 0
  /// the states wait in the socket and are read every drain_ns (one wake-up for many
  /// senders); otherwise the emulator wakes for each arrival.
  void AwaitRealtime(std::int64_t wake_ns, Micros due, std::int64_t drain_ns,
                     std::int64_t* drained_ns);
  /// Real time: releases every message due at `due` (mission time, us).
  void ReleaseDue(Micros due);

  const Scenario& s_;
  Mode mode_;
  std::int64_t t0_ns_;
  Micros period_us_;
  std::int64_t final_tick_;
  /// Where the processes' messages come in: the uplink, or else the run's bus.
  Bus* rx_bus() const { return uplink_ != nullptr ? uplink_ : bus_; }

  Bus* bus_;
  Bus* uplink_ = nullptr;  // SetUplink
  std::vector<Bus*> vbus_;
  UdpmBatch batch_;  // the vehicles' own buses send through it at a release
  Channel<Datagram> channel_;
  Datagram submitted_;  // Submit's message to the channel, its bytes lent by the caller
  LagBound lags_;  // lockstep: the channel's delivery lag at each tick
  std::vector<ChannelDecision> decisions_;
  std::vector<std::string> rx_channels_;
  int n_;  // followers
  // Lockstep: the distinct vehicle buses, each with the vehicles that receive on it, and
  // whether the shared bus is one of them (else the logger gets clock ticks of its own).
  std::vector<std::vector<int>> bus_groups_;
  bool shared_has_vehicles_ = false;
  // The channel's own copy of the state: the channel overwrites it only in a later Submit,
  // and SubmitWindow runs after the window's deliveries (and any ResendClock, called while
  // the window's states are awaited) are published; no copy of the bytes per delivery.
  struct Outgoing {
    std::int64_t tick;
    const Datagram* d;
  };
  std::vector<std::vector<Outgoing>> outbox_;  // lockstep window, per receiving vehicle
  std::vector<std::size_t> next_delivery_;     // ReleaseWindow: each outbox's next entry
  clock_window_t window_clock_;                // ReleaseWindow: a bus's clock message
  ChannelEventBatch events_;  // decided, not yet published
  std::int64_t events_since_ns_ = 0;  // real time: when the oldest unpublished one was added

  // Per sender: newest accepted seq, and (lockstep) the states received for the ticks of
  // the current window [win_first_, win_last_], at slot (tick - win_first_) * (n + 1) + id.
  std::vector<std::int32_t> last_seq_;
  std::vector<bool> have_seq_;
  // Lockstep windows: each [first, WindowLast(first)], at most max_window_ ticks.
  std::int64_t WindowLast(std::int64_t first) const;
  // The first tick of the window that ends just before `next`, on the run's windows from
  // tick 0 (the window an emulator before a restart released last).
  std::int64_t WindowBefore(std::int64_t next) const;
  void CountWindow();  // the window [win_first_, win_last_] is released
  std::int64_t max_window_ = 1, min_window_ = 1;
  std::int64_t windows_ = 0, shortest_ = 0, longest_ = 0;  // released so far
  std::int64_t win_first_ = 0, win_last_ = -1;
  std::vector<bool> got_tick_;
  std::vector<Bytes> tick_state_;
  std::vector<std::int32_t> tick_seq_;
  std::vector<std::int64_t> tick_digest_;
  std::vector<Vec3> tick_pos_;
  std::vector<bool> alive_;
  std::vector<bool> ready_;
  std::vector<bool> ended_;  // its end-of-run status (finished, failed, interrupted) came
  std::int64_t tick_ = -1;  // lockstep: current tick
  std::int32_t clock_seq_ = 0, health_seq_ = 0, status_seq_ = 0;
  EmulatorCounters counters_;
  LatenessStats release_error_;  // realtime: release time - due time
  /// Real time: the releases later than kLateReleaseNoteS, noted on stderr for the run's
  /// verdict (runtime/overrun_note.h).
  LateReleaseNotes late_releases_;
  void WriteNote(const std::string& line);
  std::unique_ptr<RecorderGate> recorder_;
  std::unique_ptr<RecorderProgress> progress_;
  std::int64_t recorder_queue_ = 0;
  /// Lockstep: waits until the recorder has caught up with the run's bus as SetRecorder
  /// says; `released` is what the bus had sent when the window was released.
  /// `queued`: the events the recorder had handed its writer then; they must be written.
  void AwaitRecorder(std::int64_t released, std::uint64_t queued);
  /// Lockstep, after the last window, when the emulator forwards the uplink to the
  /// recorder: until every live process's end-of-run status has come (at most 2 s). A
  /// process that publishes message by message (with a checkpoint) sends its last health
  /// report and status after the state that completed the last window.
  void AwaitEndStatuses();
  /// After the last window: until the recorder has handled all that was sent (at most 5 s).
  void DrainRecorder();
  void ReportRecorder() const;
  std::vector<Inbound> inbox_;  // entries [0, inbox_size_) are pending; kept for reuse
  std::size_t inbox_size_ = 0;
  bool lost_any_ = false;  // lockstep: some process stopped answering
  bool running_ = false;   // lockstep: the first window was released
  std::int64_t restarted_ns_ = 0;  // lockstep: when a process last said it was restarted
  // Lockstep, per process: the tick its windows were last sent again from, and when (its
  // "restarted" status repeats until a window reaches it).
  std::vector<std::int64_t> resent_tick_;
  std::vector<std::int64_t> resent_ns_;
  std::vector<std::int64_t> next_of_;  // lockstep: the next tick each "ready" status named
  // Real time, per receiver: messages in the bundle being released, and the receivers
  // with one.
  std::vector<int> bundled_;
  std::vector<int> released_to_;
  bool restarted_ = false;
  std::string restart_note_;
  std::int64_t start_tick_ = 0;  // lockstep: the first tick this emulator releases
  bool insecure_ = false;
};

/// The whole main() of shoal_channel_emulator: parse flags, load, open the buses, run.
int ChannelEmulatorMain(int argc, char** argv);

}  // namespace shoal
