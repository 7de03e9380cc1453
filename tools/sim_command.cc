#include "tools/sim_command.h"

#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <memory>
#include <sstream>

#include "core/swarm.h"
#include "runtime/channels.h"
#include "runtime/log_writer.h"
#include "runtime/messages.h"
#include "scenario/loader.h"
#include "tools/json.h"

namespace shoal {
namespace {

volatile bool g_stop = false;
extern "C" void OnSignal(int) { g_stop = true; }

/// Writes everything the swarm publishes into an LCM log, on the SIL channels.
class LogObserver : public SwarmObserver {
 public:
  explicit LogObserver(LogWriter* log) : log_(log) {
    for (int id = 0; id < 256; ++id) {
      state_ch_.push_back(channels::State(id));
      rx_ch_.push_back(channels::Rx(id));
      health_ch_.push_back(channels::Health(id));
    }
  }
  void OnTick(std::int64_t tick, Micros utime, bool final_tick) override {
    FlushChannel();  // the previous tick's decisions
    clock_window_t c;
    c.utime = utime;
    c.vehicle_id = kEmulatorId;
    c.seq = static_cast<std::int32_t>(tick);
    c.tick = tick;
    c.n_ticks = 1;
    c.period_us = period_us;
    c.final_tick = final_tick ? 1 : 0;
    c.n_deliveries = 0;  // shoal sim's deliveries are in SHOAL_CHANNEL
    log_->Write(channels::Clock(), utime, c);
    now_ = utime;
  }
  void OnDeliver(int receiver, const StateMsg& m) override {
    log_->Write(Name(rx_ch_, receiver, channels::Rx), now_, ToLcm(m));
  }
  void OnState(const StateMsg& m) override {
    log_->Write(Name(state_ch_, m.vehicle_id, channels::State), m.utime, ToLcm(m));
  }
  void OnChannel(const ChannelDecision& d) override { channel_.Add(d); }
  /// Writes the decisions not yet written: one SHOAL_CHANNEL message per tick, as the
  /// lockstep emulator publishes them per window.
  void FlushChannel() {
    channel_.Flush([&](const channel_events_t& b) { log_->Write(channels::ChannelEvents(), now_, b); });
  }
  void OnHealth(Micros utime, const Follower& f) override {
    log_->Write(Name(health_ch_, f.id(), channels::Health), utime,
                ToLcmHealth(utime, f, health_seq_[f.id() % 256]++));
  }

  Micros period_us = 0;

 private:
  static const std::string& Name(std::vector<std::string>& cache, int id,
                                 std::string (*make)(int)) {
    if (id >= 0 && id < static_cast<int>(cache.size())) return cache[id];
    static thread_local std::string tmp;
    tmp = make(id);
    return tmp;
  }
  LogWriter* log_;
  Micros now_ = 0;
  ChannelEventBatch channel_;
  std::int32_t health_seq_[256] = {};
  std::vector<std::string> state_ch_, rx_ch_, health_ch_;
};

/// Observer that forwards to the log (if any) and shows progress on a terminal.
class ProgressObserver : public SwarmObserver {
 public:
  ProgressObserver(SwarmObserver* inner, const Swarm* swarm, bool show)
      : inner_(inner), swarm_(swarm), show_(show), start_(Clock::now()), last_(start_) {}
  void OnTick(std::int64_t tick, Micros utime, bool final_tick) override {
    if (inner_) inner_->OnTick(tick, utime, final_tick);
    if (show_ && (tick & 1023) == 0) {
      const auto now = Clock::now();
      if (now - last_ > std::chrono::milliseconds(250)) {
        last_ = now;
        const double wall = std::chrono::duration<double>(now - start_).count();
        std::fprintf(stderr, "\r  t = %8.1f / %.1f s  (%.0fx real time)  worst position error %.2f m   ",
                     ToSeconds(utime), ToSeconds(swarm_->final_tick() * swarm_->period_us()),
                     ToSeconds(utime) / wall, swarm_->metrics().current_worst_position_m());
        shown_ = true;
      }
    }
  }
  void OnDeliver(int r, const StateMsg& m) override { if (inner_) inner_->OnDeliver(r, m); }
  void OnState(const StateMsg& m) override { if (inner_) inner_->OnState(m); }
  void OnChannel(const ChannelDecision& d) override { if (inner_) inner_->OnChannel(d); }
  void OnHealth(Micros t, const Follower& f) override { if (inner_) inner_->OnHealth(t, f); }
  bool shows() const { return show_; }
  void Finish() {
    if (shown_) std::fprintf(stderr, "\r%100s\r", "");
  }

 private:
  using Clock = std::chrono::steady_clock;
  SwarmObserver* inner_;
  const Swarm* swarm_;
  bool show_;
  bool shown_ = false;
  Clock::time_point start_, last_;
};

run_status_t Status(const Scenario& s, Micros utime, std::int32_t seq, const std::string& state,
                    const std::string& message, bool with_text) {
  run_status_t st;
  st.utime = utime;
  st.vehicle_id = kLauncherId;
  st.seq = seq;
  st.state = state;
  st.scenario_name = s.name;
  st.scenario_toml = with_text ? s.source_text : "";
  st.seed = static_cast<std::int64_t>(s.seed);
  st.followers = s.followers;
  st.message = message;
  return st;
}

}  // namespace

int RunSim(const SimOptions& opt) {
  Scenario s;
  if (!LoadScenarioOrReport("shoal sim", opt.scenario, &s)) return 2;
  if (opt.duration_s == 0 || (opt.duration_s < 0 && opt.duration_s != -1)) {
    std::cerr << "shoal sim: --duration must be a positive number of seconds (got "
              << opt.duration_s << ")\n";
    return 2;
  }

  std::unique_ptr<LogWriter> log;
  if (!opt.out.empty()) {
    try {
      log = std::make_unique<LogWriter>(opt.out);
    } catch (const std::exception& e) {
      std::cerr << "shoal sim: " << e.what() << "\n";
      return 2;
    }
  }

  Swarm swarm(s, opt.duration_s);
  std::unique_ptr<LogObserver> log_obs;
  if (log) {
    log_obs = std::make_unique<LogObserver>(log.get());
    log_obs->period_us = swarm.period_us();
    log->Write(channels::Status(), 0, Status(s, 0, 0, "running", "shoal sim", true));
  }
  ProgressObserver progress(log_obs.get(), &swarm, !opt.quiet && !opt.json && isatty(2));

  g_stop = false;
  struct sigaction sa = {};
  sa.sa_handler = OnSignal;
  sigemptyset(&sa.sa_mask);
  struct sigaction old_int, old_term;
  sigaction(SIGINT, &sa, &old_int);
  sigaction(SIGTERM, &sa, &old_term);

  const auto t0 = std::chrono::steady_clock::now();
  // Nothing to log or show: no observer at all (its calls are ~30 per tick).
  swarm.Run(log_obs || progress.shows() ? &progress : nullptr, &g_stop);
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  progress.Finish();
  sigaction(SIGINT, &old_int, nullptr);
  sigaction(SIGTERM, &old_term, nullptr);

  const FormationMetrics& m = swarm.metrics();
  const bool interrupted = g_stop;
  const bool converged = m.converged() && swarm.diverged_id() == 0;
  const double sim_s = swarm.sim_time_s();
  std::string state = interrupted ? "interrupted" : (swarm.diverged_id() ? "failed" : "finished");
  std::ostringstream detail;
  if (swarm.diverged_id()) {
    detail << "follower " << swarm.diverged_id() << " diverged at t = " << sim_s << " s";
  }
  if (log) {
    log_obs->FlushChannel();
    log->Write(channels::Status(), static_cast<Micros>(sim_s * 1e6),
               Status(s, static_cast<Micros>(sim_s * 1e6), 1, state, detail.str(), false));
    log->Close();
  }

  if (opt.json) {
    JsonWriter j;
    j.Str("scenario", s.name)
        .Bool("converged", converged)
        .Num("convergence_time_s", converged ? m.convergence_time_s() : NAN)
        .Num("final_position_error_m", m.final_worst().position_m)
        .Num("final_velocity_error_mps", m.final_worst().velocity_mps)
        .Num("final_attitude_error_rad", m.final_worst().attitude_rad)
        .Num("max_position_error_m", m.max_position_error_m())
        .Num("sim_time_s", sim_s)
        .Num("wall_time_s", wall_s)
        .Num("realtime_factor", wall_s > 0 ? sim_s / wall_s : NAN)
        .Int("ticks", swarm.next_tick())
        .Int("channel_delivered", swarm.delivered())
        .Int("channel_dropped", swarm.dropped())
        .Bool("interrupted", interrupted)
        .Int("diverged_follower", swarm.diverged_id());
    std::string per = "[";
    for (std::size_t i = 0; i < swarm.followers().size(); ++i) {
      const Follower& f = *swarm.followers()[i];
      const FormationErrors& e = m.final_errors()[i];
      JsonWriter fj;
      fj.Int("id", f.id())
          .Num("final_position_error_m", e.position_m)
          .Num("final_velocity_error_mps", e.velocity_mps)
          .Num("final_attitude_error_rad", e.attitude_rad)
          .Num("saturation_fraction",
               f.counters().ticks ? double(f.counters().saturated_ticks) / f.counters().ticks : 0)
          .Int("neighbour_timeouts", f.counters().neighbour_timeouts)
          .Int("msgs_received", f.counters().msgs_received);
      per += (i ? "," : "") + fj.Done();
    }
    j.Raw("followers", per + "]");
    if (log) j.Str("log", opt.out).Int("log_events", log->events());
    std::cout << j.Done() << "\n";
  } else {
    std::printf("shoal sim: %s (%d followers, %.0f Hz control, seed %llu)\n", s.name.c_str(),
                s.followers, s.control_rate_hz, static_cast<unsigned long long>(s.seed));
    std::printf("  simulated %.1f s in %.3f s wall (%.0fx real time)%s\n", sim_s, wall_s,
                wall_s > 0 ? sim_s / wall_s : 0.0, interrupted ? "  -- interrupted" : "");
    if (swarm.diverged_id()) std::printf("  DIVERGED: %s\n", detail.str().c_str());
    if (converged) {
      std::printf("  converged: yes, at %.2f s (position tol %.3g m, velocity tol %.3g m/s)\n",
                  m.convergence_time_s(), s.metrics.position_tol_m, s.metrics.velocity_tol_mps);
    } else {
      std::printf("  converged: NO (position tol %.3g m, velocity tol %.3g m/s)\n",
                  s.metrics.position_tol_m, s.metrics.velocity_tol_mps);
    }
    std::printf("  final errors, worst follower: position %.4f m, velocity %.4f m/s, attitude %.4f rad\n",
                m.final_worst().position_m, m.final_worst().velocity_mps,
                m.final_worst().attitude_rad);
    std::printf("  %-9s %12s %14s %14s %11s %9s\n", "follower", "position[m]", "velocity[m/s]",
                "attitude[rad]", "saturated", "timeouts");
    for (std::size_t i = 0; i < swarm.followers().size(); ++i) {
      const Follower& f = *swarm.followers()[i];
      const FormationErrors& e = m.final_errors()[i];
      const auto& c = f.counters();
      std::printf("  %-9d %12.4f %14.4f %14.4f %10.1f%% %9lld\n", f.id(), e.position_m,
                  e.velocity_mps, e.attitude_rad,
                  c.ticks ? 100.0 * c.saturated_ticks / c.ticks : 0.0,
                  static_cast<long long>(c.neighbour_timeouts));
    }
    std::printf("  channel: %lld delivered, %lld dropped\n",
                static_cast<long long>(swarm.delivered()), static_cast<long long>(swarm.dropped()));
    if (log) {
      std::printf("  log: %s (%lld events)\n", opt.out.c_str(),
                  static_cast<long long>(log->events()));
    }
  }
  if (interrupted) return 130;
  return converged ? 0 : 1;
}

}  // namespace shoal
