#include "analysis/sim_report.h"

#include <chrono>
#include <cmath>
#include <memory>
#include <sstream>
#include <stdexcept>

#include "analysis/analysis_json.h"
#include "analysis/verdict.h"
#include "core/swarm.h"
#include "runtime/channels.h"
#include "runtime/log_writer.h"
#include "runtime/messages.h"

namespace shoal {
namespace {

/// Writes everything the swarm publishes into an LCM log, on the SIL channels.
class LogObserver : public SwarmObserver {
 public:
  LogObserver(LogWriter* log, Micros period_us) : log_(log), period_us_(period_us) {
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
    c.period_us = period_us_;
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
    channel_.Flush(
        [&](const channel_events_t& b) { log_->Write(channels::ChannelEvents(), now_, b); });
  }
  void OnHealth(Micros utime, const Follower& f) override {
    log_->Write(Name(health_ch_, f.id(), channels::Health), utime,
                ToLcmHealth2(ToLcmHealth(utime, f, HealthSeq(f.id())++),
                             LatenessWindow()));
  }

 private:
  static const std::string& Name(std::vector<std::string>& cache, int id,
                                 std::string (*make)(int)) {
    if (id >= 0 && id < static_cast<int>(cache.size())) return cache[id];
    static thread_local std::string tmp;
    tmp = make(id);
    return tmp;
  }
  LogWriter* log_;
  Micros period_us_;
  Micros now_ = 0;
  ChannelEventBatch channel_;
  /// Each follower's own count of health messages, as each process of shoal run keeps.
  std::int32_t& HealthSeq(int id) {
    const auto i = static_cast<std::size_t>(id);
    if (i >= health_seq_.size()) health_seq_.resize(i + 1, 0);
    return health_seq_[i];
  }
  std::vector<std::int32_t> health_seq_;
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
        std::fprintf(stderr,
                     "\r  t = %8.1f / %.1f s  (%.0fx real time)  "
                     "worst position error %.2f m   ",
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

std::string DivergedDetail(const Swarm& swarm) {
  if (!swarm.diverged_id()) return "";
  std::ostringstream detail;
  detail << "follower " << swarm.diverged_id() << " diverged at t = " << swarm.sim_time_s()
         << " s";
  return detail.str();
}

/// The outcome of a finished (or interrupted) swarm run.
void FillReport(const Scenario& s, const Swarm& swarm, SimReport* r) {
  const FormationMetrics& m = swarm.metrics();
  r->scenario = s.name;
  r->followers = s.followers;
  r->control_rate_hz = s.control_rate_hz;
  r->seed = s.seed;
  r->position_tol_m = s.metrics.position_tol_m;
  r->velocity_tol_mps = s.metrics.velocity_tol_mps;
  r->diverged_follower = swarm.diverged_id();
  r->converged = FormationConverged(m.converged(), swarm.diverged_id());
  r->convergence_time_s = m.convergence_time_s();
  r->final_worst = m.final_worst();
  r->max_position_error_m = m.max_position_error_m();
  r->sim_time_s = swarm.sim_time_s();
  r->ticks = swarm.next_tick();
  r->delivered = swarm.delivered();
  r->dropped = swarm.dropped();
  r->per_follower.clear();
  for (std::size_t i = 0; i < swarm.followers().size(); ++i) {
    const Follower& f = *swarm.followers()[i];
    const auto& c = f.counters();
    SimFollowerReport fr;
    fr.id = f.id();
    fr.final_errors = m.final_errors()[i];
    fr.saturation_fraction = c.ticks ? double(c.saturated_ticks) / c.ticks : 0.0;
    fr.neighbour_timeouts = c.neighbour_timeouts;
    fr.msgs_received = c.msgs_received;
    r->per_follower.push_back(fr);
  }
}

std::string SecondsText(double t) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.3f", t);
  return text;
}

/// Opens the log and writes its first event through to the file, so that an unwritable
/// path or a full disk refuses the run before it starts. False with *error.
bool OpenLog(const Scenario& s, const std::string& path, std::unique_ptr<LogWriter>* log,
             std::string* error) {
  try {
    *log = std::make_unique<LogWriter>(path);
    (*log)->Write(channels::Status(), 0,
                  Status(s, 0, 0, RunStateName(RunState::kRunning), "shoal sim", true));
    (*log)->Flush();
    return true;
  } catch (const std::runtime_error& e) {
    *error = e.what();
    log->reset();
    return false;
  }
}

/// Writes the log's last events and closes it; a failure goes to report->log_error.
void FinishLog(const Scenario& s, const Swarm& swarm, bool interrupted, LogObserver* obs,
               LogWriter* log, SimReport* report) {
  if (report->log_error.empty()) {
    try {
      const Micros end = swarm.sim_time_us();
      const std::string state = RunStateName(
          interrupted ? RunState::kInterrupted
                      : (swarm.diverged_id() ? RunState::kFailed : RunState::kFinished));
      obs->FlushChannel();
      log->Write(channels::Status(), end, Status(s, end, 1, state, DivergedDetail(swarm), false));
      log->Close();
    } catch (const std::runtime_error& e) {
      report->log_error = e.what();
    }
  }
  report->log_events = log->events();
  if (!report->log_error.empty()) {
    report->log_error += "; the log is incomplete: at most " +
                         std::to_string(report->log_events) + " events, up to t = " +
                         SecondsText(swarm.sim_time_s()) + " s";
  }
}

}  // namespace

bool RunSimulation(const Scenario& s, const SimRunOptions& opt, SimReport* report,
                   std::string* error) {
  std::unique_ptr<Swarm> swarm_ptr;
  try {
    swarm_ptr = std::make_unique<Swarm>(s, opt.duration_s);
  } catch (const std::exception& e) {  // std::bad_alloc, std::length_error
    *error = std::string("this run does not fit in memory (") + e.what() + "; estimated " +
             EstimateRun(s, opt.duration_s).Describe(s.followers) + ")";
    return false;
  }
  Swarm& swarm = *swarm_ptr;
  std::unique_ptr<LogWriter> log;
  if (!opt.out.empty() && !OpenLog(s, opt.out, &log, error)) return false;
  std::unique_ptr<LogObserver> log_obs;
  if (log) log_obs = std::make_unique<LogObserver>(log.get(), swarm.period_us());
  ProgressObserver progress(log_obs.get(), &swarm, opt.show_progress);
  // Nothing to log or show: no observer at all (its calls are ~30 per tick).
  SwarmObserver* obs = log_obs || progress.shows() ? &progress : nullptr;
  const auto t0 = std::chrono::steady_clock::now();
  bool interrupted = false;
  std::string log_error;
  try {
    while (!(interrupted = opt.stop_requested && opt.stop_requested()) && swarm.Step(obs)) {
    }
  } catch (const std::runtime_error& e) {  // only the log's writes throw
    log_error = e.what();
  }
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  progress.Finish();

  *report = SimReport();
  FillReport(s, swarm, report);
  report->interrupted = interrupted;
  report->wall_time_s = wall_s;
  report->log_error = log_error;
  if (log) {
    report->log = opt.out;
    FinishLog(s, swarm, interrupted, log_obs.get(), log.get(), report);
  }
  return true;
}

nlohmann::ordered_json SimReportJson(const SimReport& r) {
  nlohmann::ordered_json j;
  j["scenario"] = r.scenario;
  AddFormationKeys(r.converged, r.convergence_time_s, r.final_worst, &j);
  j["max_position_error_m"] = r.max_position_error_m;
  AddTimingKeys(r.sim_time_s, r.wall_time_s, &j);
  j["ticks"] = r.ticks;
  j["channel_delivered"] = r.delivered;
  j["channel_dropped"] = r.dropped;
  j["interrupted"] = r.interrupted;
  j["diverged_follower"] = r.diverged_follower;
  nlohmann::ordered_json per = nlohmann::ordered_json::array();
  for (const SimFollowerReport& f : r.per_follower) {
    per.push_back({{"id", f.id},
                   {"final_position_error_m", f.final_errors.position_m},
                   {"final_velocity_error_mps", f.final_errors.velocity_mps},
                   {"final_attitude_error_rad", f.final_errors.attitude_rad},
                   {"saturation_fraction", f.saturation_fraction},
                   {"neighbour_timeouts", f.neighbour_timeouts},
                   {"msgs_received", f.msgs_received}});
  }
  j["followers"] = per;
  if (!r.log.empty()) {
    j["log"] = r.log;
    j["log_events"] = r.log_events;
  }
  if (!r.log_error.empty()) j["log_error"] = r.log_error;
  return j;
}

void PrintSimReport(const SimReport& r, std::FILE* out) {
  std::fprintf(out, "shoal sim: %s (%d followers, %.0f Hz control, seed %llu)\n",
               r.scenario.c_str(), r.followers, r.control_rate_hz,
               static_cast<unsigned long long>(r.seed));
  std::fprintf(out, "  simulated %.1f s in %.3f s wall (%.0fx real time)%s\n", r.sim_time_s,
               r.wall_time_s, r.wall_time_s > 0 ? r.sim_time_s / r.wall_time_s : 0.0,
               r.interrupted ? "  -- interrupted" : "");
  if (r.diverged_follower) {
    std::ostringstream t;  // as in the log's status message
    t << r.sim_time_s;
    std::fprintf(out, "  DIVERGED: follower %d diverged at t = %s s\n", r.diverged_follower,
                 t.str().c_str());
  }
  if (r.converged) {
    std::fprintf(out, "  converged: yes, at %.2f s (position tol %.3g m, velocity tol %.3g m/s)\n",
                 r.convergence_time_s, r.position_tol_m, r.velocity_tol_mps);
  } else {
    std::fprintf(out, "  converged: NO (position tol %.3g m, velocity tol %.3g m/s)\n",
                 r.position_tol_m, r.velocity_tol_mps);
  }
  std::fprintf(out,
               "  final errors, worst follower: position %.4f m, velocity %.4f m/s, "
               "attitude %.4f rad\n",
               r.final_worst.position_m, r.final_worst.velocity_mps, r.final_worst.attitude_rad);
  std::fprintf(out, "  %-9s %12s %14s %14s %11s %9s\n", "follower", "position[m]",
               "velocity[m/s]", "attitude[rad]", "saturated", "timeouts");
  for (const SimFollowerReport& f : r.per_follower) {
    std::fprintf(out, "  %-9d %12.4f %14.4f %14.4f %10.1f%% %9lld\n", f.id,
                 f.final_errors.position_m, f.final_errors.velocity_mps,
                 f.final_errors.attitude_rad, 100.0 * f.saturation_fraction,
                 static_cast<long long>(f.neighbour_timeouts));
  }
  std::fprintf(out, "  channel: %lld delivered, %lld dropped\n",
               static_cast<long long>(r.delivered), static_cast<long long>(r.dropped));
  if (!r.log.empty()) {
    std::fprintf(out, "  log: %s (%lld events)\n", r.log.c_str(),
                 static_cast<long long>(r.log_events));
  }
}

int SimExitStatus(const SimReport& r) {
  if (!r.log_error.empty()) return kExitFailed;
  if (r.interrupted) return kExitInterrupted;
  return r.converged ? kExitOk : kExitFailed;
}

}  // namespace shoal
