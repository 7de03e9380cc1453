#include "runtime/clocked_node.h"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <shoal/run_status_t.hpp>
#include <utility>

#include "core/channel_model.h"
#include "core/timeline.h"
#include "core/topology.h"
#include "runtime/channels.h"
#include "runtime/messages.h"
#include "runtime/overrun_note.h"

namespace shoal {

namespace {
constexpr std::int64_t kWaitWarningNs = 5000000000LL;
constexpr std::int64_t kIdleExitNs = 30000000000LL;
constexpr std::int64_t kReadyEveryNs = 100000000LL;
constexpr std::int64_t kNoClockExitNs = 60000000000LL;

// The channel's smallest delivery lag (its MinLagTicks): channel events included.
std::int64_t LockstepTicksAhead(const Scenario& s) {
  const Timeline timeline(s);
  return MinLagTicks(BuildAllLinks(s), &timeline, s.period_us());
}

// The channel's delivery lag at each tick, which bounds the clock master's windows.
LagBound LockstepLags(const Scenario& s) {
  const Timeline timeline(s);
  return LagBound(BuildAllLinks(s), &timeline, s.period_us());
}

// More ticks than any window a clock master releases (its --max-lookahead is far less):
// bounds the work a clock message can ask of the check below.
constexpr std::int64_t kMaxWindowTicks = 100000;
}  // namespace

Micros ClockedNode::StaggerPhaseUs(const Scenario& s, int id) {
  if (id <= 0 || LockstepTicksAhead(s) < 2) return 0;
  return static_cast<Micros>(id) * (s.period_us() / 2) / (s.followers + 1);
}

ClockedNode::ClockedNode(const Scenario& s, int id, Mode mode, std::int64_t t0_ns,
                         double duration_s, Bus* bus, Bus* rx_bus)
    : s_(s),
      id_(id),
      mode_(mode),
      t0_ns_(t0_ns),
      period_us_(s.period_us()),
      final_tick_(s.final_tick(duration_s)),
      bus_(bus),
      rx_bus_(rx_bus),
      lags_(LockstepLags(s)),
      state_channel_(channels::State(id)),
      health_channel_(channels::Health(id)) {}

void ClockedNode::Init() {
  // A real-time tick reads what reached the host by its time, wherever in its period the
  // loop runs (a phase, a late wake-up): what came later waits for the next tick, as it
  // would for a loop that ran at the tick's very instant.
  if (mode_ == Mode::kRealtime && !rx_bus_->RecordArrivals()) {
    std::cerr << "process " << id_ << ": the bus gives no arrival times; each tick reads "
              << "what has come when its loop runs\n";
  }
  SubscribeInputs();
  if (mode_ == Mode::kLockstep) SubscribeInput(channels::Clock(), kClockKind);
  if (mode_ == Mode::kLockstep && checkpoint_) SubscribeInput(channels::Status(), kStatusKind);
}

void ClockedNode::SubscribeInput(const std::string& channel, int kind) {
  if (kind >= kFirstInputKind && mode_ == Mode::kLockstep && !checkpoint_) {
    // Held by the app where it lies; what it completes is stepped after the handlers. Not
    // with restarts: there the emulator's statuses come through the inbox, and a "ready"
    // must name the tick after those the deliveries before it completed, as in arrival
    // order.
    rx_bus_->Subscribe(channel, [this, kind](const std::string&, const void* d, int n) {
      const bool may_complete = OnInput(kind, n > 0 ? static_cast<const unsigned char*>(d) : nullptr,
                                        n > 0 ? n : 0);
      input_held_ = input_held_ || may_complete;
    });
    return;
  }
  rx_bus_->Subscribe(
      channel, [this, kind](const std::string&, const void* d, int n) { Enqueue(kind, d, n); });
}

void ClockedNode::Enqueue(int kind, const void* data, int size) {
  if (inbox_size_ == inbox_.size()) inbox_.emplace_back();
  Inbound& in = inbox_[inbox_size_++];
  in.kind = kind;
  in.arrival_ns = rx_bus_->ArrivalNs();
  const auto* p = static_cast<const unsigned char*>(data);
  in.bytes.assign(p, p + (size > 0 && p != nullptr ? size : 0));
}

int ClockedNode::HandleBus(int timeout_ms, std::int64_t arrived_by_ns) {
  const int handled = rx_bus_->Handle(timeout_ms);
  // What the inbox's ticks publish goes out together after it (BundlePublishes).
  const bool bundle = bundle_publishes_ && mode_ == Mode::kLockstep && !checkpoint_ &&
                      (inbox_size_ > 0 || input_held_);
  if (bundle) bus_->BeginBundle(/*recordable=*/true);
  // Applied in arrival order, each as its handler would have done it: entries stay in
  // place (their buffers are reused); what arrived too late moves to the front, in order,
  // and is all that is left at the end.
  std::size_t kept = 0;
  for (std::size_t k = 0; k < inbox_size_; ++k) {
    if (inbox_[k].kind >= kFirstInputKind && inbox_[k].arrival_ns > arrived_by_ns) {
      if (kept != k) std::swap(inbox_[kept], inbox_[k]);
      ++kept;
      continue;
    }
    const Inbound& in = inbox_[k];
    const auto* data = in.bytes.empty() ? nullptr : in.bytes.data();
    const int size = static_cast<int>(in.bytes.size());
    if (in.kind == kClockKind) {
      OnClock(data, size);
    } else if (in.kind == kStatusKind) {
      OnStatus(data, size);
    } else if (OnInput(in.kind, data, size) && mode_ == Mode::kLockstep) {
      StepWhatIsDue();
    }
  }
  // Inputs held by their handlers: the clock may have come first (its ticks then wait for
  // them), or in this very batch, before or after them.
  if (input_held_) {
    input_held_ = false;
    StepWhatIsDue();
  }
  counters_.held_to_next_tick += static_cast<std::int64_t>(kept);
  inbox_size_ = kept;
  if (bundle) bus_->EndBundle();  // a failed publish is not fatal here, as in Step
  return handled;
}

bool ClockedNode::OnInput(int /*kind*/, const unsigned char* /*data*/, int /*size*/) {
  return false;
}

const ClockedNode::Delivery* ClockedNode::ApplyListed(const std::vector<Delivery>& listed) {
  return listed.empty() ? nullptr : &listed.front();  // nothing is ever delivered here
}

bool ClockedNode::AcceptableWindow(const clock_window_t& c) const {
  // All its ticks must be ticks this process can be given now (none stepped or announced
  // yet, none past the run's end, and none that a state this process has yet to send
  // could be delivered at: from the next tick to step to the window's last, the channel's
  // lag at each tick reaches beyond it), and every delivery it lists must be for one of
  // them. The ranges are checked before any arithmetic on the fields (a forged tick or
  // count must not overflow).
  bool ok = c.vehicle_id == kEmulatorId && c.n_ticks >= 1 && c.n_ticks <= kMaxWindowTicks &&
            c.tick >= next_tick_ && c.tick <= final_tick_ && c.period_us == period_us_;
  const std::int64_t last = ok ? c.tick + c.n_ticks - 1 : 0;
  const std::int64_t span = last - next_tick_ + 1;
  ok = ok && last <= final_tick_ && span <= kMaxWindowTicks &&
       lags_.Window(next_tick_, span) == span && c.utime == c.tick * period_us_;
  for (std::int64_t j = c.tick; ok && j <= last; ++j) ok = !Announced(j);
  for (std::int32_t k = 0; ok && k < c.n_deliveries; ++k) {
    ok = c.delivery_tick[k] >= c.tick && c.delivery_tick[k] <= last;
  }
  return ok;
}

ClockedNode::DueTick* ClockedNode::DueAt(std::int64_t tick) {
  return Announced(tick) ? &due_[static_cast<std::size_t>(tick) & (due_.size() - 1)] : nullptr;
}

bool ClockedNode::Announced(std::int64_t tick) const {
  return !due_.empty() && tick >= 0 &&
         due_[static_cast<std::size_t>(tick) & (due_.size() - 1)].tick == tick;
}

void ClockedNode::ReserveDue(std::int64_t last) {
  const auto needed = static_cast<std::size_t>(last - next_tick_ + 1);
  if (needed <= due_.size()) return;
  std::size_t size = due_.empty() ? 16 : due_.size();
  while (size < needed) size *= 2;
  std::vector<DueTick> ring(size);
  for (DueTick& d : due_) {
    if (d.tick >= 0) std::swap(ring[static_cast<std::size_t>(d.tick) & (size - 1)], d);
  }
  due_.swap(ring);
}

ClockedNode::DueTick& ClockedNode::Announce(std::int64_t tick) {
  DueTick& d = due_[static_cast<std::size_t>(tick) & (due_.size() - 1)];
  d.tick = tick;
  d.final_tick = false;
  d.deliveries.clear();
  ++due_count_;
  return d;
}

void ClockedNode::OnClock(const unsigned char* data, int size) {
  clock_window_t& c = window_;
  if (!Decode(data, size, &c) || !AcceptableWindow(c)) {
    ++counters_.bad_clock;
    return;
  }
  const std::int64_t last = c.tick + c.n_ticks - 1;
  ReserveDue(last);
  for (std::int64_t j = c.tick; j <= last; ++j) {
    Announce(j).final_tick = j == last && c.final_tick != 0;
  }
  for (std::int32_t k = 0; k < c.n_deliveries; ++k) {
    if (c.delivery_receiver[k] == id_) {
      DueAt(c.delivery_tick[k])
          ->deliveries.push_back({c.delivery_sender[k], c.delivery_seq[k], c.delivery_digest[k]});
    }
  }
  StepWhatIsDue();
}

void ClockedNode::OnStatus(const unsigned char* data, int size) {
  run_status_t st;
  if (Decode(data, size, &st) && st.vehicle_id == kEmulatorId &&
      ParseRunState(st.state) == RunState::kRestarted) {
    PublishStatus(RunStateName(RunState::kReady));
  }
}

void ClockedNode::StepWhatIsDue() {
  for (DueTick* due = DueAt(next_tick_); due != nullptr; due = DueAt(next_tick_)) {
    const Delivery* missing = ApplyListed(due->deliveries);
    if (missing != nullptr) {
      NoteWaiting(*missing);
      return;
    }
    const bool final_tick = due->final_tick;
    const std::int64_t tick = due->tick;
    due->tick = -1;  // the slot is free again; its list keeps its capacity
    --due_count_;
    waiting_since_ns_ = 0;
    warned_waiting_ = false;
    Step(tick);
    AfterLockstepStep(tick);
    if (final_tick || tick >= final_tick_) {
      done_ = true;
      return;
    }
  }
}

void ClockedNode::NoteWaiting(const Delivery& missing) {
  if (waiting_since_ns_ == 0) waiting_since_ns_ = MonotonicNs();
  if (!warned_waiting_ && MonotonicNs() - waiting_since_ns_ > kWaitWarningNs) {
    std::fprintf(stderr,
                 "vehicle %d: tick %lld still waits for the delivery of %d's "
                 "state seq %d (a datagram lost on the bus?)\n",
                 id_, static_cast<long long>(next_tick_), missing.sender, missing.seq);
    warned_waiting_ = true;
  }
}

void ClockedNode::Step(std::int64_t tick) {
  const Micros now = tick * period_us_;
  bus_->Publish(state_channel_, ToLcm(StepAt(now)));
  next_tick_ = tick + 1;
  stepped_ = true;
  if (checkpoint_) WriteCheckpoint(tick);
  if (now % 1000000 < period_us_ || tick == final_tick_) PublishHealth(now);
  if (checkpoint_ && std::binary_search(stop_before_.begin(), stop_before_.end(), tick + 1)) {
    // Published and checkpointed: shoal run kills this process here and starts another
    // from the checkpoint, whose controller then resets at tick + 1 as shoal sim's does.
    raise(SIGSTOP);
  }
}

std::vector<std::int64_t> ClockedNode::ResetTicks(const Scenario& s, int id,
                                                  std::int64_t final_tick) {
  std::vector<std::int64_t> ticks;
  const Micros period = s.period_us();
  for (const ScenarioEvent& e : s.events) {
    if (e.kind != EventKind::kControllerReset) continue;
    if (std::find(e.vehicles.begin(), e.vehicles.end(), id) == e.vehicles.end()) continue;
    const Micros at = TimelineMicros(e.at_s);
    const std::int64_t k = at <= 0 ? 0 : (at + period - 1) / period;  // first tick at or after
    if (k >= 1 && k <= final_tick) ticks.push_back(k);
  }
  std::sort(ticks.begin(), ticks.end());
  ticks.erase(std::unique(ticks.begin(), ticks.end()), ticks.end());
  return ticks;
}

void ClockedNode::StopBeforeResets() {
  if (id_ >= 1) stop_before_ = ResetTicks(s_, id_, final_tick_);
}

void ClockedNode::PublishHealth(Micros utime) {
  health_t h = Health(utime);
  h.seq = health_seq_++;
  h.msgs_dropped_invalid += rx_bus_->rejected();  // forged, or another run's
  h.lateness_p50_s = lateness_.Quantile(0.5);
  h.lateness_p99_s = lateness_.Quantile(0.99);
  h.lateness_max_s = lateness_.max();
  h.overruns = counters_.overruns;
  bus_->Publish(health_channel_, ToLcmHealth2(h, lateness_.TakeWindow()));
}

void ClockedNode::PublishStatus(const std::string& state, const std::string& message) {
  run_status_t st;
  st.utime = next_tick_ * period_us_;
  st.vehicle_id = id_;
  st.seq = status_seq_++;
  st.state = state;
  st.scenario_name = s_.name;
  st.scenario_toml = "";
  st.seed = static_cast<std::int64_t>(s_.seed);
  st.followers = s_.followers;
  st.message = message;
  bus_->Publish(channels::Status(), st);
}

int ClockedNode::Run() { return mode_ == Mode::kLockstep ? RunLockstep() : RunRealtime(); }

bool ClockedNode::AnnounceReady(std::int64_t start_ns, std::int64_t* last_ready_ns) {
  const std::int64_t now = MonotonicNs();
  if (now - *last_ready_ns > kReadyEveryNs) {
    // A restarted process says so, with the tick it needs next (the status's time): the
    // clock master sends it the windows it missed (docs/reliability.md).
    if (resumed_) {
      PublishStatus(RunStateName(RunState::kRestarted), RestartMessage(0, 0));
    } else {
      PublishStatus(RunStateName(RunState::kReady));
    }
    *last_ready_ns = now;
  }
  if (now - start_ns > kNoClockExitNs) {
    std::cerr << "vehicle " << id_ << ": no clock tick within 60 s; exiting\n";
    return false;
  }
  return true;
}

int ClockedNode::RunLockstep() {
  // Announce readiness until the clock master starts the run.
  std::int64_t last_ready = 0;
  const std::int64_t start = MonotonicNs();
  if (next_tick_ > final_tick_) {  // resumed after its last tick: nothing left to step
    PublishStatus(RunStateName(RunState::kRestarted), RestartMessage(0, 0));
    done_ = true;
  }
  while (!done_ && !StopRequested()) {
    if (!stepped_ && !AnnounceReady(start, &last_ready)) return 3;
    const std::int64_t stepped_before = next_tick_;
    const int handled = HandleBus(50);
    if (handled < 0) return 1;
    if (handled == 0 && due_count_ > 0) StepWhatIsDue();  // to say what it waits for
    if (next_tick_ != stepped_before) last_step_ns_ = MonotonicNs();
    if (stepped_ && MonotonicNs() - last_step_ns_ > kIdleExitNs) {
      std::cerr << "vehicle " << id_ << ": no tick could be stepped for "
                << kIdleExitNs / 1000000000LL << " s after tick " << next_tick_ - 1
                << " (the clock master is gone, or declared this vehicle lost); exiting\n";
      return 3;
    }
  }
  if (done_) PublishStatus(RunStateName(RunState::kFinished));
  return done_ ? 0 : 1;
}

int ClockedNode::RunRealtime() {
  const std::int64_t period_ns = period_us_ * 1000;
  const std::int64_t first = resumed_ ? CatchUp() : 0;
  for (std::int64_t k = first; k <= final_tick_ && !StopRequested(); ++k) {
    const std::int64_t deadline = t0_ns_ + k * period_ns + phase_ns_;
    SleepUntilNs(deadline);
    if (StopRequested()) break;
    const std::int64_t woke = MonotonicNs();
    lateness_.Add(static_cast<double>(woke - deadline) * 1e-9);
    HandleBus(0, deadline - phase_ns_ + kArrivalSlackNs);  // what arrived by the tick's time
    Step(k);
    const std::int64_t done = MonotonicNs();
    if (done > deadline + period_ns) NoteOverrun(k, deadline, woke, done);
  }
  LeaveRealtimeScheduling();
  const bool finished = next_tick_ > final_tick_;
  std::fprintf(stderr,
               "vehicle %d: %lld ticks, lateness p50 %.3f ms p99 %.3f ms max %.3f ms, "
               "%lld overruns\n",
               id_, static_cast<long long>(next_tick_), lateness_.Quantile(0.5) * 1e3,
               lateness_.Quantile(0.99) * 1e3, lateness_.max() * 1e3,
               static_cast<long long>(counters_.overruns));
  PublishStatus(RunStateName(finished ? RunState::kFinished : RunState::kInterrupted));
  return finished ? 0 : 1;
}

void ClockedNode::NoteOverrun(std::int64_t k, std::int64_t deadline, std::int64_t woke,
                              std::int64_t done) {
  ++counters_.overruns;
  // Written once the tick is already late: the write delays nothing that was on time.
  if (counters_.overruns > kOverrunNotes + 1) return;
  const std::string line =
      counters_.overruns > kOverrunNotes
          ? std::string(kOverrunNotesEnd)
          : FormatOverrunNote({k, deadline, (deadline - t0_ns_) * 1e-9,
                               (woke - deadline) * 1e-9, (done - deadline) * 1e-9});
  std::fprintf(stderr, "%s\n", line.c_str());
}

bool ClockedNode::RestoreCheckpoint(std::int64_t tick, CheckpointPayload* /*in*/) {
  for (std::int64_t k = 0; k <= tick && k <= final_tick_; ++k) StepAt(k * period_us_);
  return true;
}

bool ClockedNode::EnableCheckpoints(const std::string& path, std::string* error) {
  checkpoint_ = std::make_unique<CheckpointFile>();
  if (checkpoint_->Open(path, next_generation_, error)) return true;
  checkpoint_.reset();
  return false;
}

void ClockedNode::Resume(const std::string& path, const std::string& note) {
  resumed_ = true;
  restart_note_ = note;
  CheckpointRecord r;
  std::string error;
  if (!ReadCheckpoint(path, id_, &r, &error) || r.tick < 0 || r.tick > final_tick_) {
    std::cerr << "vehicle " << id_ << ": " << (error.empty() ? "checkpoint out of range" : error)
              << "; starting again from tick 0\n";
    return;
  }
  if (!RestoreCheckpoint(r.tick, &r.payload)) {
    std::cerr << "vehicle " << id_ << ": " << path
              << ": not a checkpoint of this process; starting again from tick 0\n";
    return;
  }
  next_tick_ = r.tick + 1;
  resumed_tick_ = r.tick;
  next_generation_ = r.generation + 1;
}

void ClockedNode::WriteCheckpoint(std::int64_t tick) {
  checkpoint_payload_.Clear();
  SaveCheckpoint(&checkpoint_payload_);
  if (!checkpoint_->Write(id_, tick, checkpoint_payload_)) {
    std::cerr << "vehicle " << id_ << ": cannot write its checkpoint; it can no longer be "
              << "resumed after a restart\n";
    checkpoint_.reset();
  }
}

std::string ClockedNode::RestartMessage(std::int64_t from, std::int64_t skipped) const {
  char text[256];
  if (resumed_tick_ >= 0) {
    std::snprintf(text, sizeof(text), "; resumed from its state of t = %.3f s (tick %lld)",
                  ToSeconds(resumed_tick_ * period_us_), static_cast<long long>(resumed_tick_));
  } else {
    std::snprintf(text, sizeof(text), "; no checkpoint: started again from tick 0");
  }
  std::string m = restart_note_ + text;
  if (skipped > 0) {
    std::snprintf(text, sizeof(text),
                  "; ticks %lld..%lld (%lld) stepped without neighbour data and not published",
                  static_cast<long long>(from), static_cast<long long>(from + skipped - 1),
                  static_cast<long long>(skipped));
    m += text;
  }
  return m;
}

std::int64_t ClockedNode::CatchUp() {
  // The first tick to publish is the one after the current period's end: the ticks before
  // it are stepped now, well within that period (microseconds each), so that it starts on
  // time.
  const std::int64_t period_ns = period_us_ * 1000;
  const std::int64_t elapsed = MonotonicNs() - t0_ns_;
  const std::int64_t first = std::max(next_tick_, elapsed < 0 ? 0 : elapsed / period_ns + 2);
  const std::int64_t from = next_tick_;
  const std::int64_t skipped = std::max<std::int64_t>(0, std::min(first, final_tick_ + 1) - from);
  for (std::int64_t k = from; k < first && k <= final_tick_; ++k) StepAt(k * period_us_);
  next_tick_ = first;
  PublishStatus(RunStateName(RunState::kRestarted), RestartMessage(from, skipped));
  return first;
}

int ClockedNodeMain(CLI::App* app, int argc, char** argv, const std::string& name,
                    const std::function<bool(const Scenario&)>& valid,
                    const std::function<std::unique_ptr<ClockedNode>(const NodeContext&)>& make) {
  ProcessOptions opt;
  AddProcessOptions(app, &opt);
  std::string checkpoint, resume, restart_note;
  app->add_option("--checkpoint", checkpoint,
                  "After every published state write a checkpoint to this file (shoal run "
                  "--restart on-failure)");
  app->add_option("--resume", resume,
                  "Replace a process that died: go on from the checkpoint in this file");
  app->add_option("--restart-note", restart_note,
                  "With --resume: why and when the process before it ended (for the log)");
  bool stop_before_resets = false;
  app->add_flag("--stop-before-resets", stop_before_resets,
                "With --checkpoint: stop (SIGSTOP) after the tick before each controller "
                "reset of this vehicle, for shoal run to restart the process there");
  Micros phase_us = 0;
  app->add_option("--phase-us", phase_us,
                  "Real time: run each tick this many us after its period begins (below "
                  "the period; it reads only what reached the host by the tick's time; "
                  "shoal run spreads the vehicles' phases so their loops do not wake at once)")
      ->check(CLI::NonNegativeNumber);
  bool bundle_publishes = false;
  app->add_flag("--bundle-publishes", bundle_publishes,
                "Lockstep: publish a window's states and health on the shared bus as one "
                "recordable bundle (every receiver of that bus must unpack it: shoal run "
                "gives it when lcm-logger has runtime/lcm_queue_shim.c preloaded)");
  Scenario s;
  const int started = StartProcess(app, argc, argv, name, &opt, &s);
  if (started >= 0) return started;
  if (!valid(s)) return 2;
  if (phase_us >= s.period_us()) {
    std::cerr << name << ": --phase-us " << phase_us << " is not within the control period ("
              << s.period_us() << " us)\n";
    return 2;
  }
  bus_auth::Setting auth;
  if (!bus_auth::SettingOrReport(opt.insecure, name, &auth)) return 2;
  // Before LCM starts its receive thread, so that the thread inherits the policy.
  if (!EnterScheduling(name, opt, kNodeFifoPriority, /*clock_master=*/false)) return 2;
  try {
    LcmBus bus(opt.lcm_url, auth.key);
    std::unique_ptr<LcmBus> rx;
    if (!opt.rx_url.empty() && opt.rx_url != opt.lcm_url) {
      rx = std::make_unique<LcmBus>(opt.rx_url, auth.key);
    }
    const NodeContext c{s,         opt.parsed_mode(),
                        opt.t0_ns, opt.duration_s,
                        &bus,      rx ? static_cast<Bus*>(rx.get()) : &bus};
    std::unique_ptr<ClockedNode> node = make(c);
    if (!resume.empty()) node->Resume(resume, restart_note);
    std::string error;
    if (!checkpoint.empty() && !node->EnableCheckpoints(checkpoint, &error)) {
      std::cerr << name << ": " << error << "\n";
      return 2;
    }
    if (stop_before_resets) node->StopBeforeResets();
    if (bundle_publishes) node->BundlePublishes();
    node->SetPhase(phase_us);
    node->Init();
    const int status = node->Run();
    // A lockstep run that stalls on a lost datagram says where it was lost. Before the
    // authentication line, which shoal run reads as the last.
    const std::int64_t overflowed = (rx ? rx.get() : &bus)->overflowed();
    if (overflowed > 0) {
      std::cerr << name << ": the kernel dropped " << overflowed
                << " datagram(s) sent to this process: its receive buffer was full\n";
    }
    std::cerr << name << ": " << bus_auth::ExitNote(auth, c.rx_bus->rejected()) << "\n";
    return status;
  } catch (const std::exception& e) {
    std::cerr << name << ": " << e.what() << "\n";
    return 2;
  }
}

}  // namespace shoal
