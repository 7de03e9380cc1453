#include "runtime/node_app.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>

#include "core/channel_model.h"
#include "runtime/channels.h"
#include "runtime/messages.h"
#include "scenario/loader.h"

namespace shoal {

NodeApp::NodeApp(const Scenario& s, int id, Mode mode, std::int64_t t0_ns, double duration_s,
                 Bus* bus, Bus* rx_bus)
    : s_(s),
      id_(id),
      mode_(mode),
      t0_ns_(t0_ns),
      period_us_(s.period_us()),
      final_tick_(s.final_tick(duration_s)),
      bus_(bus),
      rx_bus_(rx_bus),
      state_channel_(channels::State(id)),
      health_channel_(channels::Health(id)) {
  const Topology topo = Topology::Build(s.followers, s.edges, s.leader_links);
  if (id == 0) {
    leader_ = std::make_unique<Leader>(s);
  } else {
    follower_ = std::make_unique<Follower>(s, topo, id);
  }
  // Lockstep bounds from the links' delay models: the clock master never releases more
  // ticks ahead than the smallest delivery lag, and a message is delivered (listed) at
  // the latest one period after send time + the largest delay.
  const std::vector<Link> links = BuildLinks(s, topo);
  max_ticks_ahead_ = MinLagTicks(links, period_us_);
  listable_us_ = static_cast<Micros>(std::ceil(MaxDelaySeconds(links) * 1e6)) + 2 * period_us_;
}

void NodeApp::Init() {
  if (follower_) {
    rx_bus_->Subscribe(channels::Rx(id_),
                       [this](const std::string&, const void* d, int n) { OnRx(d, n); });
  }
  if (mode_ == Mode::kLockstep) {
    rx_bus_->Subscribe(channels::Clock(),
                       [this](const std::string&, const void* d, int n) { OnClock(d, n); });
  }
}

namespace {
// Lockstep bounds on what a vehicle holds: far more than a run ever has in flight (a
// window's deliveries and ticks), so that only forged traffic can reach them.
constexpr std::size_t kMaxHeldDeliveries = 4096;
constexpr std::int64_t kWaitWarningNs = 5000000000LL;
constexpr std::int64_t kIdleExitNs = 30000000000LL;
}  // namespace

void NodeApp::OnRx(const void* data, int size) {
  vehicle_state_t m{};
  if (!Decode(data, size, &m)) {
    ++counters_.bad_rx;
    return;
  }
  const StateMsg msg = FromLcm(m);
  if (mode_ != Mode::kLockstep) {
    follower_->Receive(msg);  // validates and counts (NaN/Inf, unknown, old)
    return;
  }
  // Lockstep: hold it until the clock tick that lists it, and apply it there (Receive
  // counts it then, as shoal sim does at that tick -- an old one too: a delay model that
  // lets messages overtake makes the channel deliver it after a newer one). What can never
  // be used (NaN/Inf, unknown sender) is dropped and counted now.
  const RxResult r = follower_->Check(msg);
  if (r == RxResult::kUnknownSender || r == RxResult::kNonFinite) {
    follower_->CountRejected(r);
    return;
  }
  if (held_.size() >= kMaxHeldDeliveries) {
    DropHeld(0);
  }
  held_.push_back(Held{msg, Digest64(data, size)});
  StepWhatIsDue();
}

void NodeApp::OnClock(const void* data, int size) {
  // A clock message covers ticks [tick, last]: all of them must be ticks this vehicle can
  // be given now (none stepped or announced yet, none further ahead than the channel's
  // smallest delivery lag, none past the run's end), and every delivery it lists must be
  // for one of them.
  // The ranges are checked before any arithmetic on the fields (a forged tick or count
  // must not overflow).
  clock_tick_t c;
  bool ok = Decode(data, size, &c) && c.vehicle_id == kEmulatorId && c.n_ticks >= 1 &&
            c.n_ticks <= max_ticks_ahead_ && c.tick >= next_tick_ && c.tick <= final_tick_ &&
            c.period_us == period_us_;
  const std::int64_t last = ok ? c.tick + c.n_ticks - 1 : 0;
  ok = ok && last < next_tick_ + max_ticks_ahead_ && last <= final_tick_ &&
       c.utime == c.tick * period_us_ && due_.lower_bound(c.tick) == due_.upper_bound(last);
  for (std::int32_t k = 0; ok && k < c.n_deliveries; ++k) {
    ok = c.delivery_tick[k] >= c.tick && c.delivery_tick[k] <= last;
  }
  if (!ok) {
    ++counters_.bad_clock;
    return;
  }
  for (std::int64_t j = c.tick; j <= last; ++j) {
    DueTick& d = due_[j];
    d.final_tick = j == last && c.final_tick != 0;
  }
  for (std::int32_t k = 0; k < c.n_deliveries; ++k) {
    if (c.delivery_receiver[k] == id_) {
      due_[c.delivery_tick[k]].deliveries.push_back(
          {c.delivery_sender[k], c.delivery_seq[k], c.delivery_digest[k]});
    }
  }
  StepWhatIsDue();
}

void NodeApp::DropHeld(std::size_t k) {
  // Never listed: old if older than what was applied (a replay), else unlisted.
  if (follower_ && follower_->Check(held_[k].msg) == RxResult::kOld) {
    follower_->CountRejected(RxResult::kOld);
  } else {
    ++counters_.unlisted_rx;
  }
  held_.erase(held_.begin() + static_cast<std::ptrdiff_t>(k));
}

void NodeApp::StepWhatIsDue() {
  for (auto it = due_.find(next_tick_); it != due_.end(); it = due_.find(next_tick_)) {
    // Every listed delivery must be here; apply them in the listed order, as shoal sim.
    std::vector<std::size_t> at;
    at.reserve(it->second.deliveries.size());
    for (const DueTick::Delivery& want : it->second.deliveries) {
      std::size_t k = 0;
      while (k < held_.size() &&
             (held_[k].msg.vehicle_id != want.sender || held_[k].msg.seq != want.seq ||
              held_[k].digest != want.digest || std::find(at.begin(), at.end(), k) != at.end())) {
        ++k;
      }
      if (k == held_.size()) {
        if (waiting_since_ns_ == 0) waiting_since_ns_ = MonotonicNs();
        if (!warned_waiting_ && MonotonicNs() - waiting_since_ns_ > kWaitWarningNs) {
          std::fprintf(stderr, "vehicle %d: tick %lld still waits for the delivery of %d's "
                       "state seq %d (a datagram lost on the bus?)\n", id_,
                       static_cast<long long>(next_tick_), want.sender, want.seq);
          warned_waiting_ = true;
        }
        return;
      }
      at.push_back(k);
    }
    if (follower_) {
      for (std::size_t k : at) follower_->Receive(held_[k].msg);
    }
    std::sort(at.begin(), at.end());
    for (auto k = at.rbegin(); k != at.rend(); ++k) held_.erase(held_.begin() + static_cast<std::ptrdiff_t>(*k));
    const bool final_tick = it->second.final_tick;
    const std::int64_t tick = it->first;
    due_.erase(it);
    waiting_since_ns_ = 0;
    warned_waiting_ = false;
    Step(tick);
    // What no later tick can list any more (sent longer ago than the largest delay, plus
    // a period) is dropped and counted (DropHeld).
    const Micros oldest_listable = tick * period_us_ - listable_us_;
    for (std::size_t k = 0; k < held_.size();) {
      if (held_[k].msg.utime < oldest_listable) {
        DropHeld(k);
      } else {
        ++k;
      }
    }
    if (final_tick || tick >= final_tick_) {
      done_ = true;
      return;
    }
  }
}

void NodeApp::Step(std::int64_t tick) {
  const Micros now = tick * period_us_;
  const StateMsg& m = follower_ ? follower_->Tick(now) : leader_->Tick(now);
  bus_->Publish(state_channel_, ToLcm(m));
  next_tick_ = tick + 1;
  if (now % 1000000 < period_us_ || tick == final_tick_) PublishHealth(now);
}

void NodeApp::PublishHealth(Micros utime) {
  health_t h;
  if (follower_) {
    h = ToLcmHealth(utime, *follower_, health_seq_++);
    h.msgs_dropped_invalid += counters_.bad_rx + counters_.bad_clock + counters_.unlisted_rx;
  } else {
    h = health_t();
    h.utime = utime;
    h.vehicle_id = 0;
    h.seq = health_seq_++;
    h.ticks = next_tick_;
  }
  h.lateness_p50_s = lateness_.Quantile(0.5);
  h.lateness_p99_s = lateness_.Quantile(0.99);
  h.lateness_max_s = lateness_.max();
  h.overruns = counters_.overruns;
  bus_->Publish(health_channel_, h);
}

void NodeApp::PublishStatus(const std::string& state, const std::string& message) {
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

int NodeApp::Run() { return mode_ == Mode::kLockstep ? RunLockstep() : RunRealtime(); }

int NodeApp::RunLockstep() {
  // Announce readiness until the clock master starts the run.
  std::int64_t last_ready = 0;
  const std::int64_t start = MonotonicNs();
  while (!done_ && !StopRequested()) {
    if (next_tick_ == 0) {
      const std::int64_t now = MonotonicNs();
      if (now - last_ready > 100000000LL) {
        PublishStatus("ready", "");
        last_ready = now;
      }
      if (now - start > 60000000000LL) {
        std::cerr << "vehicle " << id_ << ": no clock tick within 60 s; exiting\n";
        return 3;
      }
    }
    const std::int64_t stepped_before = next_tick_;
    const int handled = rx_bus_->Handle(50);
    if (handled < 0) return 1;
    if (handled == 0 && !due_.empty()) StepWhatIsDue();  // to say what it waits for
    if (next_tick_ != stepped_before) last_step_ns_ = MonotonicNs();
    if (next_tick_ > 0 && MonotonicNs() - last_step_ns_ > kIdleExitNs) {
      std::cerr << "vehicle " << id_ << ": no tick could be stepped for "
                << kIdleExitNs / 1000000000LL << " s after tick " << next_tick_ - 1
                << " (the clock master is gone, or declared this vehicle lost); exiting\n";
      return 3;
    }
  }
  if (done_) PublishStatus("finished", "");
  return done_ ? 0 : 1;
}

int NodeApp::RunRealtime() {
  const std::int64_t period_ns = period_us_ * 1000;
  for (std::int64_t k = 0; k <= final_tick_ && !StopRequested(); ++k) {
    const std::int64_t deadline = t0_ns_ + k * period_ns;
    SleepUntilNs(deadline);
    if (StopRequested()) break;
    lateness_.Add(static_cast<double>(MonotonicNs() - deadline) * 1e-9);
    rx_bus_->Handle(0);  // everything delivered so far
    Step(k);
    if (MonotonicNs() > deadline + period_ns) ++counters_.overruns;
  }
  const bool finished = next_tick_ > final_tick_;
  std::fprintf(stderr, "vehicle %d: %lld ticks, lateness p50 %.3f ms p99 %.3f ms max %.3f ms, "
               "%lld overruns\n", id_, static_cast<long long>(next_tick_),
               lateness_.Quantile(0.5) * 1e3, lateness_.Quantile(0.99) * 1e3,
               lateness_.max() * 1e3, static_cast<long long>(counters_.overruns));
  PublishStatus(finished ? "finished" : "interrupted", "");
  return finished ? 0 : 1;
}

int NodeMain(int argc, char** argv, bool leader) {
  const std::string name = leader ? "shoal_leader" : "shoal_vehicle";
  CLI::App app{leader ? "Shoal leader process: publishes the scenario's leader path"
                      : "Shoal vehicle process: one follower UUV running protocol (10)"};
  ProcessOptions opt;
  int id = 0;
  AddProcessOptions(&app, &opt);
  if (!leader) app.add_option("--id", id, "Follower id (1..n)")->required();
  Scenario s;
  const int started = StartProcess(&app, argc, argv, name, opt, &s);
  if (started >= 0) return started;
  if (!leader && (id < 1 || id > s.followers)) {
    std::cerr << name << ": --id must be in 1.." << s.followers << " (got " << id << ")\n";
    return 2;
  }
  // Before LCM starts its receive thread, so that the thread inherits the policy.
  if (opt.parsed_mode() == Mode::kRealtime) {
    std::cerr << name << ": " << EnableRealtimeScheduling(40) << "\n";
  } else {
    std::cerr << name << ": " << EnableBatchScheduling() << "\n";
  }
  try {
    LcmBus bus(opt.lcm_url);
    std::unique_ptr<LcmBus> rx;
    if (!opt.rx_url.empty() && opt.rx_url != opt.lcm_url) rx = std::make_unique<LcmBus>(opt.rx_url);
    NodeApp node(s, id, opt.parsed_mode(), opt.t0_ns, opt.duration_s, &bus,
                 rx ? static_cast<Bus*>(rx.get()) : &bus);
    node.Init();
    return node.Run();
  } catch (const std::exception& e) {
    std::cerr << name << ": " << e.what() << "\n";
    return 2;
  }
}

}  // namespace shoal
