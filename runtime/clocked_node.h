// What the leader and vehicle processes share: a life of construct (no I/O) -> Init
// (subscribe) -> Run -> exit code, following the lockstep clock master (one step per
// tick of a SHOAL_CLOCK window, held until the tick's listed deliveries are here, with an
// exit when the master is gone) or a fixed-rate loop on absolute deadlines (realtime),
// and publishing the process's state, health and status. What a tick computes is the
// derived app's (vehicle/vehicle_app.h, leader/leader_app.h).
//
// LCM handlers copy the message into an inbox and return; HandleBus() then decodes and
// applies the inbox in arrival order, stepping whatever became due after each message,
// outside any handler. A lockstep input (a delivery; not in runs with restarts) is the
// exception: its handler decodes it where it was received and holds it for the tick that
// lists it, and what it completes is stepped after the handlers. That saves a copy of
// every delivery in each vehicle's window, whose every line is fetched again each turn
// once many processes share a CPU.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <shoal/clock_window_t.hpp>
#include <shoal/health_t.hpp>
#include <string>
#include <vector>

#include "core/channel_model.h"
#include "core/scenario.h"
#include "core/state_msg.h"
#include "runtime/checkpoint.h"
#include "runtime/clock.h"
#include "runtime/lcm_bus.h"
#include "runtime/process.h"

namespace shoal {

struct ClockCounters {
  std::int64_t bad_clock = 0;  // undecodable, duplicate, out-of-order or foreign clock windows
  std::int64_t overruns = 0;   // realtime: ticks whose work outlasted their period
  // realtime: inputs that reached the host after the time of the tick that read them and
  // were kept for a later tick, counted at each tick that kept them
  std::int64_t held_to_next_tick = 0;
};

class ClockedNode {
 public:
  /// `bus` is the shared bus (state, health, status), `rx_bus` the one this process
  /// receives on (may be the same object).
  ClockedNode(const Scenario& s, int id, Mode mode, std::int64_t t0_ns, double duration_s, Bus* bus,
              Bus* rx_bus);
  virtual ~ClockedNode() = default;
  ClockedNode(const ClockedNode&) = delete;
  ClockedNode& operator=(const ClockedNode&) = delete;

  /// Subscribes the app's inputs, then (lockstep) the clock.
  void Init();
  /// Runs to the end of the scenario or until StopRequested(). Returns the exit code:
  /// 0 finished, 1 stopped early, 3 no clock came or it stopped coming (lockstep).
  int Run();
  /// Dispatches what the receive bus has (waiting at most timeout_ms for the first
  /// message), then applies it in arrival order, stepping (lockstep) what became due after
  /// each message; lockstep deliveries, held by their handlers, count as arrived before
  /// the first message applied (a tick's step does not depend on when its deliveries
  /// came), and what they complete is stepped at the end. An input that reached the host after `arrived_by_ns` (CLOCK_MONOTONIC;
  /// known when the bus records arrivals) is not applied but kept, in order, for the next
  /// call. Returns the number of messages handled, -1 on a bus error.
  static constexpr std::int64_t kAnyArrival = INT64_MAX;
  /// Real time: a delivery due at a tick's very time (a delay of whole periods) leaves the
  /// emulator at that time and reaches the host just after it; what arrives within this
  /// much of the tick's time counts as arrived by it. The emulator's release-error target.
  static constexpr std::int64_t kArrivalSlackNs = 1000000;
  int HandleBus(int timeout_ms, std::int64_t arrived_by_ns = kAnyArrival);

  const ClockCounters& counters() const { return counters_; }
  int id() const { return id_; }

  /// Restart (shoal run --restart on-failure, docs/reliability.md). After Run's every
  /// published state, the process's checkpoint goes to `path`. False with *error if the
  /// file cannot be opened. Call after Resume, if any.
  bool EnableCheckpoints(const std::string& path, std::string* error);
  /// This process replaces one that died: it goes on from the newest valid checkpoint in
  /// `path` (from tick 0 if there is none, saying so on stderr), and says on SHOAL_STATUS
  /// that it was restarted, with `note` (why, from shoal run). Before Init.
  void Resume(const std::string& path, const std::string& note);
  /// A controller_reset of this vehicle in a SIL run (docs/run.md): after publishing
  /// (and checkpointing) the tick before each reset window of the scenario, the process
  /// stops itself (SIGSTOP) for shoal run to kill it and start it again from that
  /// checkpoint. With a checkpoint only (EnableCheckpoints).
  void StopBeforeResets();
  /// Lockstep: what the process publishes while it applies what one HandleBus call took
  /// (a window's ticks: their states, and health) goes out on the shared bus as one
  /// recordable bundle (Bus::BeginBundle): one datagram, one wake-up of the clock master and
  /// of lcm-logger, per window instead of per message. Only when every receiver of the
  /// shared bus is an LcmBus or lcm-logger with runtime/lcm_queue_shim.c (shoal run says so
  /// with --bundle-publishes). Not with checkpoints: a checkpoint must follow its state's
  /// publication.
  void BundlePublishes() { bundle_publishes_ = true; }
  /// Real time: run each tick `phase_us` after its period begins instead of at its start
  /// (0 <= phase_us < the control period). The state is still that of the tick's time:
  /// the loop samples later in the period, as a vehicle with a clock of its own would.
  void SetPhase(Micros phase_us) { phase_ns_ = phase_us * 1000; }
  /// shoal run --stagger: the phase of process `id` (0 the leader, 1..n the followers),
  /// spread evenly over half the control period so that the run's loops do not all wake
  /// at one instant. 0 for every process when the channel's smallest delay is not more
  /// than a period: a state must go out before the earliest moment it can be due.
  static Micros StaggerPhaseUs(const Scenario& s, int id);
  /// The ticks at which the scenario resets follower `id`'s controller and a process can
  /// stop before (1..final_tick: a reset at tick 0 has no tick before it).
  static std::vector<std::int64_t> ResetTicks(const Scenario& s, int id, std::int64_t final_tick);

 protected:
  /// One delivery a clock window lists for this process at a tick.
  struct Delivery {
    std::int32_t sender;
    std::int32_t seq;
    std::int64_t digest;  // DeliveryDigest of the delivered bytes
  };
  /// Inbox kinds: the clock, and the derived app's own (from kFirstInputKind on).
  static constexpr int kClockKind = 0;
  static constexpr int kStatusKind = -1;  // lockstep with restarts: the emulator's statuses
  static constexpr int kFirstInputKind = 1;

  /// Subscribes `channel` on the receive bus; its messages reach OnInput as `kind`.
  void SubscribeInput(const std::string& channel, int kind);

  /// The app's own subscriptions (SubscribeInput), made by Init before the clock's.
  virtual void SubscribeInputs() {}
  /// Applies one input (kind >= kFirstInputKind): in real time (and with restarts) from the
  /// inbox, outside any handler; in lockstep from its handler, with the bytes as received,
  /// so it must only decode and hold it (publish nothing). Returns whether it may have completed a
  /// lockstep tick (then due ticks are stepped, after the handlers).
  virtual bool OnInput(int kind, const unsigned char* data, int size);
  /// Lockstep: applies exactly `listed`, in order, if every one of them is here, and
  /// returns nullptr; else applies nothing and returns the first one missing.
  virtual const Delivery* ApplyListed(const std::vector<Delivery>& listed);
  /// Lockstep: after tick `tick` was stepped (drops what no later tick can list).
  virtual void AfterLockstepStep(std::int64_t /*tick*/) {}
  /// The control step at time `now`: the state to publish.
  virtual const StateMsg& StepAt(Micros now) = 0;
  /// The app's part of its health report at `utime` (seq, lateness and overruns are set
  /// by the caller).
  virtual health_t Health(Micros utime) const = 0;
  /// The app's part of the checkpoint after tick `tick` was stepped and published.
  virtual void SaveCheckpoint(CheckpointPayload* /*out*/) const {}
  /// Restores the app to just after tick `tick`, from what SaveCheckpoint wrote; false
  /// (nothing changed) if `in` is not such a record. By default the ticks are stepped
  /// again up to `tick`, without publishing: right for an app whose state is a function
  /// of time and of the ticks stepped (the leader).
  virtual bool RestoreCheckpoint(std::int64_t tick, CheckpointPayload* in);

  Micros period_us() const { return period_us_; }
  std::int64_t next_tick() const { return next_tick_; }
  Mode mode() const { return mode_; }

 private:
  // Lockstep: an announced tick. The ticks announced and not yet stepped lie within one
  // lag window of the next tick, so a ring indexed by tick holds them without collisions;
  // its slots, and their delivery lists, are reused: a window allocates nothing, which
  // matters when a hundred processes take turns on two CPUs and every line a turn touches
  // is cold again.
  struct DueTick {
    std::int64_t tick = -1;  // -1: a free slot
    bool final_tick = false;
    std::vector<Delivery> deliveries;
  };
  struct Inbound {
    int kind = 0;
    std::int64_t arrival_ns = -1;  // Bus::ArrivalNs
    std::vector<unsigned char> bytes;
  };
  void Enqueue(int kind, const void* data, int size);
  /// A clock window: checked completely, then its ticks and this process's deliveries
  /// become due. Refused (counted) if any part is not a window this process can be given.
  void OnClock(const unsigned char* data, int size);
  bool AcceptableWindow(const clock_window_t& c) const;
  /// Lockstep with restarts: a restarted clock master asks every process for the tick it
  /// needs next; the answer is a "ready" status at that tick.
  void OnStatus(const unsigned char* data, int size);
  /// Lockstep: the slot of announced tick `tick`, or nullptr.
  DueTick* DueAt(std::int64_t tick);
  bool Announced(std::int64_t tick) const;
  /// Lockstep: a cleared slot for tick `tick` (the ring grows to hold up to it).
  DueTick& Announce(std::int64_t tick);
  /// Lockstep: the ring holds every tick from next_tick_ up to `last`.
  void ReserveDue(std::int64_t last);
  /// Lockstep: steps every tick whose clock tick and listed deliveries are all here.
  void StepWhatIsDue();
  /// Lockstep: says (once per tick, after a while) what the tick waits for.
  void NoteWaiting(const Delivery& missing);
  void Step(std::int64_t tick);
  void PublishHealth(Micros utime);
  void PublishStatus(const std::string& state, const std::string& message = "");
  /// Writes the checkpoint of tick `tick`, just published.
  void WriteCheckpoint(std::int64_t tick);
  /// Real time, resumed: steps the ticks the process was down for without publishing them,
  /// up to a tick safely ahead of the clock; says on SHOAL_STATUS that it was restarted.
  /// Returns the first tick to publish.
  std::int64_t CatchUp();
  /// What the "restarted" status says (`skipped` ticks from `from` were stepped, not
  /// published).
  std::string RestartMessage(std::int64_t from, std::int64_t skipped) const;
  int RunLockstep();
  /// Lockstep: announces readiness until the first tick; false once it waited too long.
  bool AnnounceReady(std::int64_t start_ns, std::int64_t* last_ready_ns);
  int RunRealtime();
  /// Counts an overrun of tick k (due at `deadline`, woken at `woke`, its step done at
  /// `done`, CLOCK_MONOTONIC ns) and writes its note (runtime/overrun_note.h).
  void NoteOverrun(std::int64_t k, std::int64_t deadline, std::int64_t woke, std::int64_t done);

  const Scenario& s_;
  const int id_;
  const Mode mode_;
  const std::int64_t t0_ns_;
  const Micros period_us_;
  const std::int64_t final_tick_;
  Bus* const bus_;
  Bus* const rx_bus_;
  // Lockstep: a clock window is accepted only as far ahead of the next tick to step as
  // the channel's lag at those ticks allows (it bounds the clock master's windows).
  const LagBound lags_;
  const std::string state_channel_, health_channel_;
  std::vector<Inbound> inbox_;  // entries [0, inbox_size_) are pending; kept for reuse
  std::size_t inbox_size_ = 0;
  bool input_held_ = false;  // lockstep: an input's handler may have completed a tick
  std::int64_t next_tick_ = 0;           // the tick to step next
  std::vector<DueTick> due_;    // lockstep: ticks announced, not yet stepped (a ring)
  std::size_t due_count_ = 0;   // of them
  clock_window_t window_;       // the clock window being applied (its arrays reused)
  std::int64_t waiting_since_ns_ = 0;    // when the tick expected next started to wait
  bool warned_waiting_ = false;
  std::int64_t last_step_ns_ = 0;  // lockstep: when a tick was last stepped
  bool done_ = false;
  bool stepped_ = false;  // a tick was stepped by this process
  bool bundle_publishes_ = false;  // BundlePublishes()
  std::int64_t phase_ns_ = 0;      // SetPhase()
  // Restart: where checkpoints go, and (resumed) from where and why.
  std::unique_ptr<CheckpointFile> checkpoint_;
  CheckpointPayload checkpoint_payload_;
  std::uint64_t next_generation_ = 0;
  bool resumed_ = false;
  std::int64_t resumed_tick_ = -1;  // the checkpoint's tick; -1 none (started from tick 0)
  std::string restart_note_;
  std::vector<std::int64_t> stop_before_;  // sorted reset ticks to stop before
  std::int32_t health_seq_ = 0, status_seq_ = 0;
  ClockCounters counters_;
  LatenessStats lateness_;
};

/// What a clocked process's app is built from.
struct NodeContext {
  const Scenario& scenario;
  Mode mode;
  std::int64_t t0_ns;
  double duration_s;
  Bus* bus;
  Bus* rx_bus;
};

/// The main() of a clocked process (shoal_leader, shoal_vehicle) after its own options are
/// added to `app`: parses the command line, loads the scenario, checks it with `valid`
/// (which says why on stderr if not: exit 2), sets the scheduling policy, opens the
/// buses, builds the app with `make`, and runs it. Returns the exit code.
int ClockedNodeMain(CLI::App* app, int argc, char** argv, const std::string& name,
                    const std::function<bool(const Scenario&)>& valid,
                    const std::function<std::unique_ptr<ClockedNode>(const NodeContext&)>& make);

}  // namespace shoal
