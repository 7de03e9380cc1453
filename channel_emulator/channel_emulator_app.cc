#include "channel_emulator/channel_emulator_app.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>

#include "runtime/channels.h"
#include "runtime/messages.h"
#include "runtime/overrun_note.h"
#include "scenario/loader.h"

namespace shoal {

namespace {
constexpr std::int64_t kAnswerTimeoutNs = 5000000000LL;  // lockstep: a process is gone
// Lockstep: most wait for the recorder per window. Only a logger starved of the CPU takes
// long; giving up then loses states, so the wait is generous (20 ms gave up a few times per
// 120 s run on a loaded machine).
constexpr std::int64_t kRecorderWaitNs = 100000000LL;
// lcm-logger hands messages from LCM's receive thread to its writer through a queue
// (`recorder_queue` messages: LCM's 30, or what runtime/lcm_queue_shim.c gives it) and
// drops beyond that. The recorder gate lets at most one window's messages pile up, so a
// window may send the logger at most two thirds of the queue (20 of 30): the clock
// master's own messages (clock and channel batch) included, with room left for the
// once-a-second health and status messages of every process that can fall into the same
// window.
constexpr std::int64_t kMasterMessagesPerWindow = 2;  // SHOAL_CLOCK + SHOAL_CHANNEL

/// A recordable bundle on `bus` (none when null) from construction to destruction: every
/// way out of a window sends what it holds.
class WindowRecord {
 public:
  explicit WindowRecord(Bus* bus) : bus_(bus) {
    if (bus_ != nullptr) bus_->BeginBundle(/*recordable=*/true);
  }
  ~WindowRecord() {
    if (bus_ != nullptr) bus_->EndBundle();
  }
  WindowRecord(const WindowRecord&) = delete;
  WindowRecord& operator=(const WindowRecord&) = delete;

 private:
  Bus* bus_;
};

/// Most ticks per window whose messages to the logger stay within two thirds of its queue:
/// per tick a state of every vehicle and the deliveries the logger's bus carries.
std::int64_t LoggerBoundLookahead(int followers, std::int64_t deliveries_per_tick,
                                  std::int64_t recorder_queue) {
  const std::int64_t window_messages = recorder_queue * 2 / 3;
  const std::int64_t per_tick = followers + 1 + deliveries_per_tick;
  return std::max<std::int64_t>(1, (window_messages - kMasterMessagesPerWindow) / per_tick);
}
}  // namespace

ChannelEmulatorApp::ChannelEmulatorApp(const Scenario& s, Mode mode, std::int64_t t0_ns,
                                       double duration_s, Bus* bus,
                                       std::vector<Bus*> vehicle_buses,
                                       std::int64_t max_lookahead_ticks,
                                       std::int64_t recorder_queue)
    : s_(s),
      mode_(mode),
      t0_ns_(t0_ns),
      period_us_(s.period_us()),
      final_tick_(s.final_tick(duration_s)),
      bus_(bus),
      vbus_(std::move(vehicle_buses)),
      channel_(BuildAllLinks(s), mode == Mode::kLockstep ? s.period_us() : 0,
               std::size_t{1} << 20, ModemIntervals(s),
               s.events.empty() ? nullptr : std::make_shared<const Timeline>(s)),
      lags_(channel_.links(), channel_.timeline(), s.period_us()),
      n_(s.followers),
      last_seq_(s.followers + 1, 0),
      have_seq_(s.followers + 1, false),
      alive_(s.followers + 1, true),
      ready_(s.followers + 1, false),
      ended_(s.followers + 1, false),
      resent_tick_(s.followers + 1, -1),
      resent_ns_(s.followers + 1, 0),
      next_of_(s.followers + 1, -1),
      bundled_(s.followers + 1, 0) {
  recorder_queue_ = recorder_queue;
  // The states in transit are stored once each and reused: made now, at their encoded
  // size (fixed for vehicle_state_t), for the largest delay the run can take.
  channel_.ReservePayloads(
      Datagram{0, 0, 0, Bytes(static_cast<std::size_t>(vehicle_state_t{}.getEncodedSize()))});
  for (int id = 0; id <= n_; ++id) {
    auto group = std::find_if(bus_groups_.begin(), bus_groups_.end(),
                              [&](const std::vector<int>& g) { return vbus_[g[0]] == vbus_[id]; });
    if (group == bus_groups_.end()) {
      bus_groups_.push_back({id});
    } else {
      group->push_back(id);
    }
    shared_has_vehicles_ = shared_has_vehicles_ || vbus_[id] == bus_;
    // What goes to the vehicles' own buses at one instant leaves in one system call.
    if (vbus_[id] != bus_) vbus_[id]->SendThrough(&batch_);
    vbus_[id]->PrepareBundles();
  }
  bus_->PrepareBundles();
  if (mode == Mode::kLockstep) {
    // Every state goes to the logger's bus; so does every delivery to a vehicle that
    // receives there (at most one per link and tick).
    std::int64_t logged_deliveries = 0;
    for (const auto& link : channel_.links()) logged_deliveries += vbus_[link.to] == bus_;
    max_window_ = std::max<std::int64_t>(
        1, std::min(std::max<std::int64_t>(1, max_lookahead_ticks),
                    LoggerBoundLookahead(n_, logged_deliveries, recorder_queue)));
    min_window_ = std::min(channel_.MinLagTicks(), max_window_);
  }
  const auto slots = static_cast<std::size_t>(max_window_ * (n_ + 1));
  got_tick_.assign(slots, false);
  tick_state_.resize(slots);
  tick_seq_.assign(slots, 0);
  tick_digest_.assign(slots, 0);
  tick_pos_.assign(slots, Vec3::Zero());
  for (int id = 0; id <= n_; ++id) rx_channels_.push_back(channels::Rx(id));
  outbox_.resize(static_cast<std::size_t>(n_ + 1));
}

void ChannelEmulatorApp::Init() {
  if (uplink_ != nullptr) {
    // Everything of the run, as it came (the recorder records the run's channels only).
    uplink_->SubscribeAsReceived(channels::kAllPattern,
                                 [this](const std::string& ch, const void* d, int n) {
                                   bus_->PublishAsReceived(ch, d, n);
                                 });
  }
  rx_bus()->Subscribe(channels::kStatePattern, [this](const std::string& ch, const void* d, int n) {
    if (mode_ == Mode::kLockstep) {
      // Only kept for the window's release, which comes after the handlers (and after the
      // uplink's bundle is passed on): taken where it lies, without an inbox copy.
      OnState(ch, n > 0 ? static_cast<const unsigned char*>(d) : nullptr, n > 0 ? n : 0);
    } else {
      Enqueue(false, ch, d, n);
    }
  });
  rx_bus()->Subscribe(channels::Status(), [this](const std::string& ch, const void* d, int n) {
    Enqueue(true, ch, d, n);
  });
}

void ChannelEmulatorApp::Enqueue(bool status, const std::string& channel, const void* data,
                                 int size) {
  if (inbox_size_ == inbox_.size()) inbox_.emplace_back();
  Inbound& in = inbox_[inbox_size_++];
  in.status = status;
  in.channel = channel;
  const auto* p = static_cast<const unsigned char*>(data);
  in.bytes.assign(p, p + (size > 0 && p != nullptr ? size : 0));
}

int ChannelEmulatorApp::HandleBus(int timeout_ms) {
  // What the uplink brings is passed on before any of it is applied: before the window it
  // completes is released and the recorder's gate is waited for. (A lockstep state is kept
  // for its window during the dispatch, after it was passed on: its subscription is the
  // later one.)
  if (uplink_ != nullptr) bus_->BeginBundle(/*recordable=*/true);
  const int handled = rx_bus()->Handle(timeout_ms);
  if (uplink_ != nullptr) bus_->EndBundle();
  for (std::size_t k = 0; k < inbox_size_; ++k) {
    const Inbound& in = inbox_[k];
    const unsigned char* data = in.bytes.empty() ? nullptr : in.bytes.data();
    const int size = static_cast<int>(in.bytes.size());
    if (in.status) {
      OnStatus(data, size);
    } else {
      OnState(in.channel, data, size);
    }
  }
  inbox_size_ = 0;
  return handled;
}

void ChannelEmulatorApp::OnStatus(const unsigned char* data, int size) {
  run_status_t st;
  if (!Decode(data, size, &st)) return;
  if (st.vehicle_id < 0 || st.vehicle_id > n_) return;
  const std::optional<RunState> state = ParseRunState(st.state);
  // A process restarted before the run started is simply ready.
  if (state == RunState::kReady || (state == RunState::kRestarted && !running_)) {
    ready_[st.vehicle_id] = true;
    if (st.utime >= 0 && st.utime % period_us_ == 0) next_of_[st.vehicle_id] = st.utime / period_us_;
  } else if (state == RunState::kRestarted && mode_ == Mode::kLockstep && st.utime >= 0 &&
             st.utime % period_us_ == 0) {
    OnRestarted(st.vehicle_id, st.utime / period_us_);
  } else if (running_ && (state == RunState::kFinished || state == RunState::kFailed ||
                          state == RunState::kInterrupted)) {
    ended_[st.vehicle_id] = true;
  }
}

void ChannelEmulatorApp::OnRestarted(int id, std::int64_t next) {
  const std::int64_t now = MonotonicNs();
  if (!alive_[id]) {
    std::cerr << "shoal_channel_emulator: vehicle " << id << " came back (restarted)\n";
  }
  alive_[id] = true;
  restarted_ns_ = now;
  // Its announcement repeats every 100 ms until a window reaches it: the same request
  // within 200 ms was answered already.
  if (resent_tick_[id] == next && now - resent_ns_[id] < 200000000LL) return;
  resent_tick_[id] = next;
  resent_ns_[id] = now;
  for (std::int64_t first = std::max<std::int64_t>(next, 0); first <= win_last_;) {
    const std::int64_t last = std::min(WindowLast(first), win_last_);
    ResendClock(id, first, last);
    first = last + 1;
  }
}

void ChannelEmulatorApp::ResendClock(int id, std::int64_t first, std::int64_t last) {
  Bus* b = vbus_[id];
  clock_window_t c = WindowClock();
  c.utime = first * period_us_;
  c.tick = first;
  c.n_ticks = static_cast<std::int32_t>(last - first + 1);
  c.final_tick = last == final_tick_ ? 1 : 0;
  // Deliveries exist for the current window only: earlier ticks (at most the one a
  // process re-steps after dying between its publish and its checkpoint) get none.
  for (const Outgoing& o : outbox_[id]) {
    if (o.tick < first || o.tick > last) continue;
    b->PublishRaw(rx_channels_[id], o.d->raw.data(), static_cast<int>(o.d->raw.size()));
    c.delivery_tick.push_back(o.tick);
    c.delivery_receiver.push_back(id);
    c.delivery_sender.push_back(o.d->sender);
    c.delivery_seq.push_back(o.d->seq);
    c.delivery_digest.push_back(o.d->digest);
  }
  c.n_deliveries = static_cast<std::int32_t>(c.delivery_receiver.size());
  b->Publish(channels::Clock(), c);
}

void ChannelEmulatorApp::OnState(const std::string& channel, const unsigned char* data,
                                 int size) {
  vehicle_state_t m{};
  const int id = channels::ParseStateId(channel).value_or(-1);
  if (id < 0 || id > n_ || !Decode(data, size, &m) || m.vehicle_id != id ||
      !FromLcm(m).AllFinite()) {
    ++counters_.states_invalid;
    return;
  }
  if (have_seq_[id] && m.seq <= last_seq_[id]) {  // replayed, duplicate, out of order
    ++counters_.states_old;
    return;
  }
  if (mode_ == Mode::kLockstep) {
    // Only a state for a tick of the current window, once per sender and tick.
    const std::int64_t tick = m.utime / period_us_;
    std::size_t slot = 0;
    const bool in_window = m.utime >= 0 && m.utime % period_us_ == 0 && tick >= win_first_ &&
                           tick <= win_last_;
    if (in_window) slot = static_cast<std::size_t>((tick - win_first_) * (n_ + 1) + id);
    if (!in_window || got_tick_[slot]) {
      ++counters_.states_old;
      return;
    }
    got_tick_[slot] = true;
    tick_state_[slot].assign(data, data + size);
    // Here, while the vehicles still step the window, not when it is complete: the
    // window's submission is the clock master's critical path.
    tick_digest_[slot] = DeliveryDigest(data, size);
    tick_seq_[slot] = m.seq;
    tick_pos_[slot] = FromLcm(m).eta.head<3>();
  } else {
    // Real time: a state must be about now (forged or replayed times are refused).
    const Micros now = (MonotonicNs() - t0_ns_) / 1000;
    if (m.utime > now + 100000 || m.utime < now - 1000000) {
      ++counters_.states_old;
      return;
    }
    Bytes raw(data, data + size);
    Submit(id, &raw, 0, m.seq, m.utime, FromLcm(m).eta.head<3>());
  }
  have_seq_[id] = true;
  last_seq_[id] = m.seq;
  ++counters_.states_accepted;
}

void ChannelEmulatorApp::Submit(int id, Bytes* raw, std::int64_t digest, std::int32_t seq,
                                Micros utime, const Vec3& position) {
  decisions_.clear();
  // The bytes are lent to the channel's copy and taken back: no allocation per state.
  submitted_.sender = id;
  submitted_.seq = seq;
  submitted_.digest = digest;
  submitted_.raw.swap(*raw);
  channel_.Submit(id, seq, utime, submitted_, &decisions_, position);
  submitted_.raw.swap(*raw);
  for (const ChannelDecision& d : decisions_) {
    if (d.status == ChannelDecision::kDelivered) {
      ++counters_.delivered;
    } else if (!NotTransmitted(d.status)) {
      ++counters_.dropped;
    }
    if (mode_ == Mode::kRealtime && events_.empty()) events_since_ns_ = MonotonicNs();
    events_.Add(d);
  }
}

void ChannelEmulatorApp::PublishEvents() {
  events_.Flush([&](const channel_events_t& b) { bus_->Publish(channels::ChannelEvents(), b); });
}

void ChannelEmulatorApp::ReleaseWindow() {
  // The window's deliveries, per receiver, in delivery order.
  for (auto& o : outbox_) o.clear();
  for (std::int64_t j = win_first_; j <= win_last_; ++j) {
    channel_.DeliverDue(j * period_us_, [&](int receiver, const Datagram& d) {
      outbox_[receiver].push_back(Outgoing{j, &d});
    });
  }
  // Bus by bus, the whole window in one burst: the deliveries due to the bus's vehicles,
  // tick by tick, then one clock message that covers the window's ticks and lists them.
  // Vehicles apply what the clock lists, whatever order the datagrams arrive in, so this
  // order only matters for speed. On a bus of its own (not the logger's, which records
  // each message) the burst goes out as one bundle: one datagram, and one wake-up of the
  // vehicle, per window rather than one per message.
  // The positions and the clock message are members, reused: a window allocates nothing
  // (with 64 followers, fresh ones cost about a thousand allocations a window in the
  // process every vehicle waits for).
  std::vector<std::size_t>& next = next_delivery_;
  next.resize(static_cast<std::size_t>(n_ + 1));
  batch_.Begin();
  for (const std::vector<int>& group : bus_groups_) {
    Bus* b = vbus_[group[0]];
    if (b != bus_) b->BeginBundle();
    for (int id : group) next[id] = 0;
    clock_window_t& c = window_clock_;
    SetWindowClock(&c);
    for (std::int64_t j = win_first_; j <= win_last_; ++j) {
      for (int id : group) {
        const std::vector<Outgoing>& out = outbox_[id];
        for (; next[id] < out.size() && out[next[id]].tick == j; ++next[id]) {
          const Datagram& d = *out[next[id]].d;
          b->PublishRaw(rx_channels_[id], d.raw.data(), static_cast<int>(d.raw.size()));
          c.delivery_tick.push_back(j);
          c.delivery_receiver.push_back(id);
          c.delivery_sender.push_back(d.sender);
          c.delivery_seq.push_back(d.seq);
          c.delivery_digest.push_back(d.digest);
        }
      }
    }
    c.n_deliveries = static_cast<std::int32_t>(c.delivery_receiver.size());
    b->Publish(channels::Clock(), c);
    if (b != bus_) b->EndBundle();
  }
  batch_.Flush();
  tick_ = win_last_;
}

clock_window_t ChannelEmulatorApp::WindowClock() const {
  clock_window_t c;
  SetWindowClock(&c);
  return c;
}

void ChannelEmulatorApp::SetWindowClock(clock_window_t* c) const {
  c->utime = win_first_ * period_us_;
  c->vehicle_id = kEmulatorId;
  c->seq = clock_seq_;
  c->tick = win_first_;
  c->n_ticks = static_cast<std::int32_t>(win_last_ - win_first_ + 1);
  c->period_us = period_us_;
  c->final_tick = win_last_ == final_tick_ ? 1 : 0;
  c->n_deliveries = 0;
  c->delivery_tick.clear();
  c->delivery_receiver.clear();
  c->delivery_sender.clear();
  c->delivery_seq.clear();
  c->delivery_digest.clear();
}

void ChannelEmulatorApp::PublishHealth(Micros utime) {
  health_t h;
  h.utime = utime;
  h.vehicle_id = kEmulatorId;
  h.seq = health_seq_++;
  h.ticks = tick_ + 1;
  h.lateness_p50_s = release_error_.Quantile(0.5);
  h.lateness_p99_s = release_error_.Quantile(0.99);
  h.lateness_max_s = release_error_.max();
  h.overruns = 0;
  h.msgs_received = counters_.states_accepted;
  h.msgs_dropped_invalid = counters_.states_invalid + rx_bus()->rejected();
  h.msgs_dropped_old = counters_.states_old;
  h.neighbour_timeouts = 0;
  int alive = 0;
  for (bool a : alive_) alive += a;
  h.active_neighbours = alive;
  h.saturated_ticks = 0;
  h.saturation_fraction = 0.0;
  // Its "lateness" is its release error: the window's samples are the deliveries since.
  bus_->Publish(channels::Health(kEmulatorId), ToLcmHealth2(h, release_error_.TakeWindow()));
}

void ChannelEmulatorApp::PublishStatus(RunState state, const std::string& message,
                                       bool to_vehicles) {
  run_status_t st;
  st.utime = std::max<std::int64_t>(tick_, 0) * period_us_;
  st.vehicle_id = kEmulatorId;
  // The first status carries the scenario's text, so that the run's log reproduces it
  // (as shoal sim's does); shoal analyze and shoal render read it from there.
  st.scenario_toml = status_seq_ == 0 ? s_.source_text : "";
  st.seq = status_seq_++;
  st.state = RunStateName(state);
  st.scenario_name = s_.name;
  st.seed = static_cast<std::int64_t>(s_.seed);
  st.followers = n_;
  // An unauthenticated run says so in every status, so that its log does.
  st.message = insecure_ ? (message.empty() ? std::string(bus_auth::kInsecureNote)
                                            : message + "; " + bus_auth::kInsecureNote)
                         : message;
  bus_->Publish(channels::Status(), st);
  if (!to_vehicles) return;
  for (const std::vector<int>& group : bus_groups_) {
    if (vbus_[group[0]] != bus_) vbus_[group[0]]->Publish(channels::Status(), st);
  }
}

int ChannelEmulatorApp::Run() {
  return mode_ == Mode::kLockstep ? RunLockstep() : RunRealtime();
}

int ChannelEmulatorApp::WaitForReady() {
  const std::int64_t start = MonotonicNs();
  for (;;) {
    bool all = true;
    for (bool r : ready_) all = all && r;
    if (all) return -1;
    if (StopRequested()) return 1;
    if (MonotonicNs() - start > 60000000000LL) {
      std::ostringstream missing;
      for (int id = 0; id <= n_; ++id) {
        if (!ready_[id]) missing << " " << id;
      }
      std::cerr << "shoal_channel_emulator: no ready status from vehicle(s)" << missing.str()
                << " within 60 s\n";
      PublishStatus(RunState::kFailed, "not ready:" + missing.str());
      return 3;
    }
    HandleBus(20);
  }
}

int ChannelEmulatorApp::Rejoin() {
  const std::int64_t start = MonotonicNs();
  std::int64_t asked = 0;
  for (;;) {
    bool all = true;
    for (int id = 0; id <= n_; ++id) all = all && ready_[id];
    if (all) break;
    if (StopRequested()) return 1;
    if (MonotonicNs() - start > kAnswerTimeoutNs) {
      for (int id = 0; id <= n_; ++id) {
        if (ready_[id]) continue;
        alive_[id] = false;
        lost_any_ = true;
        std::cerr << "shoal_channel_emulator: vehicle " << id << " did not answer (restart)\n";
        PublishStatus(RunState::kVehicleLost, "vehicle " + std::to_string(id) +
                                                  " did not answer the restarted emulator");
      }
      break;
    }
    if (MonotonicNs() - asked > 100000000LL) {  // until every process has answered
      PublishStatus(RunState::kRestarted, restart_note_, /*to_vehicles=*/true);
      asked = MonotonicNs();
    }
    HandleBus(20);
  }
  std::int64_t next = 0;
  for (int id = 0; id <= n_; ++id) {
    if (alive_[id]) next = std::max(next, next_of_[id]);
  }
  running_ = true;
  win_last_ = std::min(next - 1, final_tick_);
  for (int id = 0; id <= n_; ++id) {
    if (!alive_[id]) continue;
    for (std::int64_t first = std::max<std::int64_t>(next_of_[id], 0); first <= win_last_;) {
      const std::int64_t last = std::min(WindowLast(first), win_last_);
      ResendClock(id, first, last);
      first = last + 1;
    }
  }
  // The logger's copy of the last window before `next`: the emulator that died may have
  // released it to the processes and died before the logger's copy (the log counts a
  // tick it holds twice once).
  if (!shared_has_vehicles_ && next > 0) {
    clock_window_t c = WindowClock();
    c.tick = WindowBefore(next);
    c.utime = c.tick * period_us_;
    c.n_ticks = static_cast<std::int32_t>(next - c.tick);
    c.final_tick = next - 1 == final_tick_ ? 1 : 0;
    bus_->Publish(channels::Clock(), c);
  }
  tick_ = std::max<std::int64_t>(next, 0);
  start_tick_ = next;
  std::cerr << "shoal_channel_emulator: restarted, going on from tick " << next << "\n";
  PublishStatus(RunState::kRunning, "restarted: going on from tick " + std::to_string(next) +
                                        "; the deliveries the emulator before it held are lost");
  tick_ = win_last_;
  return -1;
}

void ChannelEmulatorApp::AwaitRecorder(std::int64_t released, std::uint64_t queued) {
  if (progress_ && uplink_ != nullptr && progress_->Attach()) {
    // Everything of the windows before this one, and room for the next in its queue.
    const std::int64_t target = std::max(released, bus_->sent() - recorder_queue_ / 3);
    progress_->lost(static_cast<std::uint64_t>(bus_->sent()));  // takes back what came after all
    progress_->WaitFor(static_cast<std::uint64_t>(std::max<std::int64_t>(target, 0)),
                       kRecorderWaitNs);
    // And written what its writer had been handed when the window was released: a writer
    // starved of the CPU would otherwise let its queue, and the logger's memory, grow
    // without bound (a soak's memory verdict saw 4 MB more under load).
    progress_->WaitForWrittenUpTo(queued, kRecorderWaitNs);
    return;
  }
  // Without the recorder's count: it first catches up with the window (its states), then
  // the window's decisions go out in one SHOAL_CHANNEL message, then the next window.
  if (recorder_) recorder_->Wait(kRecorderWaitNs);
}

void ChannelEmulatorApp::AwaitEndStatuses() {
  if (uplink_ == nullptr) return;
  const std::int64_t start = MonotonicNs();
  for (;;) {
    bool all = true;
    for (int id = 0; id <= n_; ++id) all = all && (!alive_[id] || ended_[id]);
    if (all || StopRequested() || MonotonicNs() - start > 2000000000LL) return;
    HandleBus(10);
  }
}

void ChannelEmulatorApp::DrainRecorder() {
  if (progress_ && uplink_ != nullptr && progress_->Attach()) {
    progress_->WaitFor(static_cast<std::uint64_t>(bus_->sent()), 50 * kRecorderWaitNs);
    // The last window's record comes in when the window is complete, just before the end:
    // written too, not only handled, before the run's end lets anyone stop the logger.
    if (!progress_->WaitForWritten(50 * kRecorderWaitNs)) {
      std::cerr << "shoal_channel_emulator: the recorder had written " << progress_->written()
                << " of the " << progress_->queued() << " events handed to its writer 5 s "
                << "after the last window\n";
    }
  }
}

void ChannelEmulatorApp::ReportRecorder() const {
  const std::int64_t windows = windows_;
  if (progress_ && progress_->handled() > 0) {
    std::cerr << "shoal_channel_emulator: waited for the recorder's count "
              << progress_->waits() << " time(s) in " << windows << " windows, "
              << progress_->waited_ns() / 1000000 << " ms in all, " << progress_->timeouts()
              << " gave up; it handled " << progress_->handled() << " of the "
              << bus_->sent() << " messages sent it";
    if (const std::uint64_t lost = progress_->lost(static_cast<std::uint64_t>(bus_->sent()))) {
      std::cerr << ", " << lost << " taken as lost on the way (it did nothing for "
                << kRecorderWaitNs / 1000000 << " ms while they were due)";
    }
    std::cerr << "\n";
  } else if (recorder_ && recorder_->active()) {
    std::cerr << "shoal_channel_emulator: waited for the recorder before "
              << recorder_->waits() << " of " << windows << " windows, "
              << recorder_->waited_ns() / 1000000 << " ms in all, " << recorder_->timeouts()
              << " gave up after " << kRecorderWaitNs / 1000000 << " ms\n";
  }
}

int ChannelEmulatorApp::RunLockstep() {
  const int not_started = restarted_ ? Rejoin() : WaitForReady();
  if (not_started >= 0) return not_started;
  if (!restarted_) PublishStatus(RunState::kRunning, "");

  // Conservative lookahead (as in conservative parallel discrete-event simulation): no
  // state sent within the window [k, WindowLast(k)] is delivered within it (LagBound:
  // the channel's lag at each of its ticks), so every delivery due in it comes from
  // states already submitted.
  // The master releases the whole window -- for each tick its deliveries, then its clock
  // tick, in that order on each vehicle's bus -- and waits once for all the window's states.
  // Each vehicle still applies each tick's deliveries (those the tick lists) and steps the
  // ticks one by one in order, so every process computes exactly what it computes with one
  // round trip per tick (and what shoal sim does).
  for (std::int64_t k = start_tick_; k <= final_tick_; k = win_last_ + 1) {
    if (StopRequested()) {
      PublishEvents();
      PublishStatus(RunState::kInterrupted, "");
      return 1;
    }
    win_first_ = k;
    win_last_ = WindowLast(k);
    CountWindow();
    std::fill(got_tick_.begin(), got_tick_.end(), false);
    const std::int64_t released = bus_->sent();
    const std::uint64_t queued = progress_ ? progress_->queued() : 0;
    ReleaseWindow();
    running_ = true;
    // The window's record -- the logger's copy of its clock (when no vehicle shares the
    // logger's bus: the window, without the lists), the states the uplink brings, the
    // health and the channel's decisions -- goes out when the window is complete, in as
    // few datagrams as it fills, in the order it was published: the logger is woken a few
    // times a window, not once per batch of states the emulator received, and it records
    // the window while the vehicles step the next. A bus a vehicle hears is never held.
    WindowRecord record(uplink_ != nullptr && !shared_has_vehicles_ ? bus_ : nullptr);
    if (!shared_has_vehicles_) bus_->Publish(channels::Clock(), WindowClock());
    ++clock_seq_;
    const WindowWait w = WaitForWindow();
    if (w == WindowWait::kStopped) {
      PublishEvents();
      PublishStatus(RunState::kInterrupted, "");
      return 1;
    }
    if (w == WindowWait::kTimedOut) DeclareSilentLost();
    SubmitWindow();
    AwaitRecorder(released, queued);
    PublishEvents();
  }
  AwaitEndStatuses();
  DrainRecorder();
  ReportRecorder();
  if (windows_ > 0) {
    std::cerr << "shoal_channel_emulator: lockstep, " << windows_ << " windows of " << shortest_;
    if (longest_ > shortest_) std::cerr << " to " << longest_;
    std::fprintf(stderr, " tick(s), %.2f on average\n",
                 static_cast<double>(final_tick_ - start_tick_ + 1) / static_cast<double>(windows_));
  }
  // A process declared lost that came back (restarted) is not lost at the end.
  lost_any_ = std::find(alive_.begin(), alive_.end(), false) != alive_.end();
  PublishStatus(RunState::kFinished, lost_any_ ? "some vehicles were lost" : "");
  return lost_any_ ? 4 : 0;
}

std::int64_t ChannelEmulatorApp::WindowLast(std::int64_t first) const {
  return std::min(first + lags_.Window(first, max_window_) - 1, final_tick_);
}

std::int64_t ChannelEmulatorApp::WindowBefore(std::int64_t next) const {
  std::int64_t first = 0;
  for (std::int64_t k = 0; k < next; k = WindowLast(k) + 1) first = k;
  return first;
}

void ChannelEmulatorApp::CountWindow() {
  const std::int64_t len = win_last_ - win_first_ + 1;
  // The last window is cut by the run's end: it does not say what the channel allows.
  if (win_last_ < final_tick_ || windows_ == 0) {
    shortest_ = windows_ == 0 ? len : std::min(shortest_, len);
    longest_ = std::max(longest_, len);
  }
  ++windows_;
}

ChannelEmulatorApp::WindowWait ChannelEmulatorApp::WaitForWindow() {
  const std::int64_t asked = MonotonicNs();
  const std::size_t used = static_cast<std::size_t>((win_last_ - win_first_ + 1) * (n_ + 1));
  for (;;) {
    bool all = true;
    for (std::size_t slot = 0; slot < used && all; ++slot) {
      all = !alive_[slot % (n_ + 1)] || got_tick_[slot];
    }
    if (all) return WindowWait::kComplete;
    if (StopRequested()) return WindowWait::kStopped;
    // A process that restarted meanwhile gets the whole answer time from its restart.
    if (MonotonicNs() - std::max(asked, restarted_ns_) > kAnswerTimeoutNs) {
      return WindowWait::kTimedOut;
    }
    HandleBus(10);
  }
}

void ChannelEmulatorApp::DeclareSilentLost() {
  for (int id = 0; id <= n_; ++id) {
    if (!alive_[id]) continue;
    std::int64_t missing = -1;  // first tick of the window without its state
    for (std::int64_t j = win_first_; j <= win_last_ && missing < 0; ++j) {
      if (!got_tick_[static_cast<std::size_t>((j - win_first_) * (n_ + 1) + id)]) missing = j;
    }
    if (missing < 0) continue;
    alive_[id] = false;
    lost_any_ = true;
    std::ostringstream msg;
    msg << "vehicle " << id << " stopped answering at t = " << ToSeconds(missing * period_us_)
        << " s";
    std::cerr << "shoal_channel_emulator: " << msg.str() << "\n";
    PublishStatus(RunState::kVehicleLost, msg.str());
  }
}

void ChannelEmulatorApp::SubmitWindow() {
  // States enter the channel tick by tick, in id order (leader first), as in shoal sim.
  for (std::int64_t j = win_first_; j <= win_last_; ++j) {
    const Micros now = j * period_us_;
    for (int id = 0; id <= n_; ++id) {
      const auto slot = static_cast<std::size_t>((j - win_first_) * (n_ + 1) + id);
      if (got_tick_[slot]) {
        Submit(id, &tick_state_[slot], tick_digest_[slot], tick_seq_[slot], now, tick_pos_[slot]);
      }
    }
    tick_ = j;
    if (now % 1000000 < period_us_ || j == final_tick_) PublishHealth(now);
  }
}

void ChannelEmulatorApp::ReleaseDue(Micros due) {
  // What is due at one instant goes out bus by bus: on a vehicle's own bus as one bundle
  // (one datagram and one wake-up for the messages of all its in-links that fall due
  // together), all the bundles in one system call; each message's release error is taken
  // when they have gone out.
  const std::int64_t due_ns = t0_ns_ + due * 1000;
  for (int id : released_to_) bundled_[id] = 0;
  released_to_.clear();
  std::int64_t last_sent_ns = -1;  // when the instant's last message went out
  batch_.Begin();
  channel_.DeliverDue(due, [&](int receiver, const Datagram& d) {
    Bus* b = vbus_[receiver];
    if (b == bus_) {
      b->PublishRaw(rx_channels_[receiver], d.raw.data(), static_cast<int>(d.raw.size()));
      last_sent_ns = MonotonicNs();
      release_error_.Add(static_cast<double>(last_sent_ns - due_ns) * 1e-9);
      return;
    }
    if (bundled_[receiver]++ == 0) {
      released_to_.push_back(receiver);
      b->BeginBundle();
    }
    b->PublishRaw(rx_channels_[receiver], d.raw.data(), static_cast<int>(d.raw.size()));
  });
  for (int id : released_to_) vbus_[id]->EndBundle();
  batch_.Flush();
  if (!released_to_.empty()) {
    last_sent_ns = MonotonicNs();
    const double error = static_cast<double>(last_sent_ns - due_ns) * 1e-9;
    for (int id : released_to_) {
      for (int k = 0; k < bundled_[id]; ++k) release_error_.Add(error);
    }
  }
  // Written once the release is already late: the write delays nothing that was on time.
  if (last_sent_ns >= 0) WriteNote(late_releases_.Add(due_ns, ToSeconds(due), last_sent_ns));
}

void ChannelEmulatorApp::WriteNote(const std::string& line) {
  if (!line.empty()) std::fprintf(stderr, "%s\n", line.c_str());
}

std::pair<double, double> ChannelEmulatorApp::DelayBounds() const {
  double lo = MinDelaySeconds(s_.delay), hi = MaxDelaySeconds(s_.delay);
  const auto widen = [&](const DelayConfig& d) {
    lo = std::min(lo, MinDelaySeconds(d));
    hi = std::max(hi, MaxDelaySeconds(d));
  };
  for (const LinkOverride& o : s_.links) {
    if (o.delay) widen(*o.delay);
  }
  for (const ScenarioEvent& e : s_.events) {  // a channel event's delays too
    if (e.delay) widen(*e.delay);
  }
  return {lo, hi};
}

void ChannelEmulatorApp::AwaitRealtime(std::int64_t wake_ns, Micros due, std::int64_t drain_ns,
                                       std::int64_t* drained_ns) {
  if (drain_ns > 0) {
    SleepUntilNs(std::min(wake_ns, *drained_ns + drain_ns));
    while (HandleBus(0) >= Bus::kMaxMessagesPerHandle) {
    }
    *drained_ns = MonotonicNs();
    return;
  }
  // Wait for input until shortly before the next release, then sleep to it exactly.
  const std::int64_t wait_ns = wake_ns - MonotonicNs();
  if (wait_ns > 2000000) {
    HandleBus(static_cast<int>(std::min<std::int64_t>((wait_ns - 1000000) / 1000000, 20)));
  } else if (wait_ns > 0) {
    HandleBus(0);
    if (channel_.NextDue() == due) SleepUntilNs(wake_ns);
  }
}

int ChannelEmulatorApp::RunRealtime() {
  // Restarted: the clock goes on as before; what the emulator that died held is lost.
  if (restarted_) {
    tick_ = std::max<std::int64_t>(0, (MonotonicNs() - t0_ns_) / (period_us_ * 1000));
    PublishStatus(RunState::kRestarted, restart_note_);
  } else {
    PublishStatus(RunState::kRunning, "");
  }
  const auto [min_delay, max_delay] = DelayBounds();
  // A state is due no sooner than min_delay after its tick; a follower sends it within
  // half a period of the tick (--phase-us), so reading the socket every quarter of
  // min(period, min_delay) is in time for its release, in one wake-up for many senders.
  // With a smallest delay of a period or less, every arrival wakes the emulator.
  const std::int64_t drain_ns =
      min_delay * 1e6 > static_cast<double>(period_us_)
          ? std::min<std::int64_t>(period_us_, static_cast<std::int64_t>(min_delay * 1e6)) * 250
          : 0;
  std::int64_t drained_ns = MonotonicNs();
  const std::int64_t end_ns =
      t0_ns_ + (final_tick_ * period_us_ + static_cast<Micros>(max_delay * 1e6) + 100000) * 1000;
  std::int64_t next_health_ns = t0_ns_;
  // What the uplink brings goes on to the recorder once per control period (HandleBus's
  // bundle nests in this one): the states of a period's burst reach it as one or two
  // datagrams, not one per batch the emulator happened to wake for.
  const std::int64_t period_ns = period_us_ * 1000;
  std::int64_t relayed_ns = MonotonicNs();
  if (uplink_ != nullptr) bus_->BeginBundle(/*recordable=*/true);
  while (!StopRequested()) {
    const std::int64_t now_ns = MonotonicNs();
    if (now_ns >= end_ns) break;
    // Release everything due, measuring how late each release is.
    const Micros now_us = (now_ns - t0_ns_) / 1000;
    const Micros due = channel_.NextDue();
    if (due >= 0 && due <= now_us) {
      ReleaseDue(due);
      continue;
    }
    // After the releases due: they are the delays the run is about.
    if (uplink_ != nullptr && now_ns - relayed_ns >= period_ns) {
      bus_->EndBundle();
      bus_->BeginBundle(/*recordable=*/true);
      relayed_ns = now_ns;
    }
    // Decisions go out about once per control period, as one SHOAL_CHANNEL message.
    if (!events_.empty() && now_ns - events_since_ns_ >= period_us_ * 1000) PublishEvents();
    if (now_ns >= next_health_ns) {
      tick_ = (now_ns - t0_ns_) / (period_us_ * 1000);
      PublishHealth(now_us);
      next_health_ns += 1000000000LL;
    }
    std::int64_t wake_ns = std::min(end_ns, next_health_ns);
    if (due >= 0) wake_ns = std::min(wake_ns, t0_ns_ + due * 1000);
    AwaitRealtime(wake_ns, due, drain_ns, &drained_ns);
  }
  if (uplink_ != nullptr) bus_->EndBundle();
  WriteNote(late_releases_.Finish());
  PublishEvents();
  PublishHealth((MonotonicNs() - t0_ns_) / 1000);
  // The status is stamped with the run's clock where it ended (the last tick, or the tick
  // of a stop), which the loop brings up to date only with each health report: a second
  // short, the analysis would expect a second of states too few.
  tick_ = std::min(final_tick_,
                   std::max<std::int64_t>(0, (MonotonicNs() - t0_ns_) / (period_us_ * 1000)));
  PublishStatus(StopRequested() ? RunState::kInterrupted : RunState::kFinished, "");
  return StopRequested() ? 1 : 0;
}

namespace {
struct EmulatorOptions {
  std::vector<std::string> vehicle_urls;
  std::int64_t max_lookahead = 50;
  pid_t recorder_pid = 0;
  std::int64_t recorder_queue = kLcmDefaultQueue;
  std::string restart_note;
  std::string uplink_url;
};

void AddEmulatorOptions(CLI::App* app, EmulatorOptions* o) {
  app->add_option("--max-lookahead", o->max_lookahead,
                  "lockstep: most ticks released per round trip; the channel's delivery "
                  "lag at the window's ticks bounds it, and so does the logger's queue: a window sends "
                  "the logger at most two thirds of --recorder-queue (1 = wait for every "
                  "state after every tick)")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  app->add_option("--recorder-pid", o->recorder_pid,
                  "lockstep: the run's lcm-logger; before each window wait (at most 100 ms) "
                  "until it has handled what it was sent, so that its queue "
                  "never overflows (0 = do not wait)")
      ->check(CLI::NonNegativeNumber);
  app->add_option("--recorder-queue", o->recorder_queue,
                  "lockstep: the messages the recorder's LCM subscription queue holds (LCM's "
                  "default 30; shoal run preloads runtime/lcm_queue_shim.c into lcm-logger "
                  "for 8192)")
      ->check(CLI::Range(3, 1 << 30))
      ->capture_default_str();
  app->add_option("--vehicle-urls", o->vehicle_urls,
                  "LCM URL on which each vehicle 0..n receives (default: all on --lcm-url)")
      ->delimiter(',');
  app->add_option("--uplink-url", o->uplink_url,
                  "receive the processes' messages on this LCM URL (where they publish, and "
                  "nobody else listens), and pass each that verified on to --lcm-url "
                  "unchanged, packed per batch, for the recorder (lcm-logger with "
                  "runtime/lcm_queue_shim.c). shoal run gives it, in both modes, with its per-vehicle "
                  "URLs when that library is there to preload, and not with restarts: what "
                  "is in flight to an emulator that dies is lost with it");
  app->add_option("--restart-note", o->restart_note,
                  "Replace an emulator that died (shoal run --restart on-failure): why and "
                  "when it ended, for the log");
}
}  // namespace

int ChannelEmulatorMain(int argc, char** argv) {
  CLI::App app{"Shoal channel emulator: the only path between vehicles (delay, loss, clock)"};
  ProcessOptions opt;
  AddProcessOptions(&app, &opt);
  EmulatorOptions eo;
  AddEmulatorOptions(&app, &eo);
  const std::vector<std::string>& vehicle_urls = eo.vehicle_urls;
  Scenario s;
  const int started = StartProcess(&app, argc, argv, "shoal_channel_emulator", &opt, &s);
  if (started >= 0) return started;
  bus_auth::Setting auth;
  if (!bus_auth::SettingOrReport(opt.insecure, "shoal_channel_emulator", &auth)) return 2;
  if (!vehicle_urls.empty() && static_cast<int>(vehicle_urls.size()) != s.followers + 1) {
    std::cerr << "shoal_channel_emulator: --vehicle-urls needs " << s.followers + 1
              << " URLs (leader and followers), got " << vehicle_urls.size() << "\n";
    return 2;
  }
  // Before LCM starts its receive threads, so that they inherit the policy; above the
  // vehicles: releases are the delays the run is about.
  if (!EnterScheduling("shoal_channel_emulator", opt, kEmulatorFifoPriority, /*clock_master=*/true)) return 2;
  try {
    auto address = [](const std::string& u) { return u.substr(0, u.find('?')); };
    if (!eo.uplink_url.empty() && address(eo.uplink_url) == address(opt.lcm_url)) {
      std::cerr << "shoal_channel_emulator: --uplink-url must differ from --lcm-url (what it "
                   "passes on would come back to it)\n";
      return 2;
    }
    LcmBus bus(opt.lcm_url, auth.key);
    std::unique_ptr<LcmBus> uplink;
    if (!eo.uplink_url.empty()) uplink = std::make_unique<LcmBus>(eo.uplink_url, auth.key);
    std::vector<std::unique_ptr<LcmBus>> own;
    std::vector<Bus*> vbus;
    // One bus object per distinct URL: vehicles that share a URL share a bus, and get one
    // clock tick listing all their deliveries (two bus objects on one address would each
    // send a tick of their own, with half the list).
    // Keyed on the address (provider://group:port), not the options after '?'.
    std::map<std::string, Bus*> by_url = {{address(opt.lcm_url), &bus}};
    for (int id = 0; id <= s.followers; ++id) {
      const std::string& u = vehicle_urls.empty() ? opt.lcm_url : vehicle_urls[id];
      auto found = by_url.find(address(u));
      if (found == by_url.end()) {
        own.push_back(std::make_unique<LcmBus>(u, auth.key));
        found = by_url.emplace(address(u), own.back().get()).first;
      }
      vbus.push_back(found->second);
    }
    ChannelEmulatorApp app_(s, opt.parsed_mode(), opt.t0_ns, opt.duration_s, &bus, vbus,
                            eo.max_lookahead, eo.recorder_queue);
    if (opt.parsed_mode() == Mode::kLockstep) {
      std::cerr << "shoal_channel_emulator: lockstep, at least " << app_.min_window_ticks()
                << " tick(s) per round trip (the channel's smallest lag), at most "
                << app_.max_window_ticks() << " as its lag at the window's ticks allows\n";
    }
    if (opt.parsed_mode() == Mode::kLockstep && eo.recorder_pid > 0) {
      app_.SetRecorder(eo.recorder_pid);
    }
    if (uplink) app_.SetUplink(uplink.get());
    if (auth.insecure) app_.SetInsecure();
    if (!eo.restart_note.empty()) app_.SetRestarted(eo.restart_note);
    app_.Init();
    // After Init: its subscriptions have started LCM's receive thread and ring.
    std::cerr << "shoal_channel_emulator: " << LockMemory() << "\n";
    const int status = app_.Run();
    const std::int64_t overflowed = bus.overflowed() + (uplink ? uplink->overflowed() : 0);
    if (overflowed > 0) {  // before the authentication line, which shoal run reads as the last
      std::cerr << "shoal_channel_emulator: the kernel dropped " << overflowed
                << " datagram(s) sent to this process: its receive buffer was full\n";
    }
    const std::int64_t rejected = bus.rejected() + (uplink ? uplink->rejected() : 0);
    std::cerr << "shoal_channel_emulator: " << bus_auth::ExitNote(auth, rejected) << "\n";
    return status;
  } catch (const std::exception& e) {
    std::cerr << "shoal_channel_emulator: " << e.what() << "\n";
    return 2;
  }
}

}  // namespace shoal
