#include "tools/analyze_command.h"

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>

#include "analysis/analysis.h"
#include "analysis/analysis_json.h"
#include "analysis/csv.h"
#include "analysis/run_data.h"
#include "analysis/verdict.h"
#include "runtime/channels.h"
#include "runtime/lcm_bus.h"
#include "runtime/messages.h"
#include "scenario/loader.h"
#include "runtime/stop_signals.h"
#include "tools/json_text.h"

namespace shoal {
namespace {

std::int64_t WallMicros() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

/// A run-level end: shoal sim / the launcher (-2) or the channel emulator (-1) says the run
/// is over. Vehicles' own "finished" statuses do not end it.
bool RunEnded(const StatusRecord& st) {
  const std::optional<RunState> s = ParseRunState(st.state);
  return st.vehicle_id < 0 && s &&
         (*s == RunState::kFinished || *s == RunState::kFailed || *s == RunState::kInterrupted);
}

/// Subscribes to every Shoal channel on `url` until SIGINT, a run-level end status (plus a
/// short drain for the last messages in flight), or `duration_s` wall seconds.
bool ReadLive(const AnalyzeOptions& opt, const LoadOptions& lo, RunData* run, std::string* error) {
  std::unique_ptr<LcmBus> bus;
  try {
    bus = std::make_unique<LcmBus>(opt.lcm_url);
  } catch (const std::exception& e) {
    *error = e.what();
    return false;
  }
  *run = RunData();
  run->source = opt.lcm_url.empty() ? "LCM default URL" : opt.lcm_url;
  RunDataBuilder b(run, lo);
  bool ended = false;
  std::size_t statuses_seen = 0;
  bus->Subscribe(channels::kAllPattern, [&](const std::string& ch, const void* d, int n) {
    b.Add(ch, static_cast<const std::uint8_t*>(d), n, WallMicros());
    for (; statuses_seen < run->statuses.size(); ++statuses_seen) {
      ended = ended || RunEnded(run->statuses[statuses_seen]);
    }
  });

  const StopSignals signals;  // Ctrl-C ends the listening, not the analysis
  const bool show = !opt.quiet && !opt.json && isatty(2);
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  auto last_show = t0;
  Clock::time_point end_at = Clock::time_point::max();
  while (!StopSignals::Requested()) {
    if (bus->Handle(50) < 0) {
      if (StopSignals::Requested() || errno == EINTR) continue;  // Ctrl-C interrupts the wait: not an error
      *error = "LCM receive error on " + run->source + " (" + std::strerror(errno) + ")";
      break;
    }
    const auto now = Clock::now();
    if (ended && end_at == Clock::time_point::max()) {
      end_at = now + std::chrono::milliseconds(500);  // the processes' last messages
    }
    if (now >= end_at) break;
    if (opt.duration_s > 0 && now - t0 >= std::chrono::duration<double>(opt.duration_s)) break;
    if (show && now - last_show > std::chrono::milliseconds(500)) {
      last_show = now;
      Micros t = 0;
      for (const VehicleTrack& v : run->vehicles) {
        if (!v.samples.empty()) t = std::max(t, v.samples.back().utime);
      }
      std::fprintf(stderr, "\r  listening on %s: %lld messages, t = %.1f s   ",
                   run->source.c_str(), static_cast<long long>(run->events), ToSeconds(t));
    }
  }
  if (show) std::fprintf(stderr, "\r%100s\r", "");
  b.Finish();
  if (!error->empty()) return false;
  const bool any = run->state_messages() > 0 || !run->channel_events.empty() ||
                   !run->health.empty() || !run->statuses.empty() || !run->clock.empty();
  if (!any) {
    *error = "nothing from a Shoal run received on " + run->source +
             " (is shoal run, shoal sim's log in lcm-logplayer, or a swarm publishing there? "
             "for udpm on one host, multicast must be routed to lo)";
    return false;
  }
  return true;
}

void PrintText(const AnalyzeOptions& opt, const RunData& run, const RunAnalysis& a) {
  const RunSummary& s = a.summary;
  std::printf("shoal analyze: %s (%s, %d followers, mode %s)\n",
              run.scenario_name.empty() ? "unnamed run" : run.scenario_name.c_str(),
              opt.live ? run.source.c_str() : opt.log.c_str(), run.followers, a.mode.c_str());
  std::printf("  %lld events, %lld vehicle states (of %lld expected), simulated %.2f s",
              static_cast<long long>(run.events), static_cast<long long>(s.states),
              static_cast<long long>(a.states_expected), s.sim_time_s);
  if (a.wall_time_s > 0) std::printf(", recorded over %.2f s wall", a.wall_time_s);
  std::printf("\n");
  if (!a.has_formation) {
    std::printf("  formation: not computed (%s)\n",
                run.has_scenario ? "no leader states in the log"
                                 : "no scenario in the log; give --scenario FILE");
  } else {
    if (FormationConverged(a)) {
      std::printf("  converged: yes, at %.2f s (position tol %.3g m, velocity tol %.3g m/s)\n",
                  s.convergence_time_s, run.scenario.metrics.position_tol_m,
                  run.scenario.metrics.velocity_tol_mps);
    } else {
      std::printf("  converged: NO (position tol %.3g m, velocity tol %.3g m/s)\n",
                  run.scenario.metrics.position_tol_m, run.scenario.metrics.velocity_tol_mps);
    }
    if (a.diverged_follower) std::printf("  DIVERGED: follower %d\n", a.diverged_follower);
    std::printf("  final errors, worst follower: position %.4f m, velocity %.4f m/s, attitude %.4f rad\n",
                s.final_worst.position_m, s.final_worst.velocity_mps, s.final_worst.attitude_rad);
    std::printf("  %-9s %12s %14s %14s %12s %10s %9s\n", "follower", "position[m]",
                "velocity[m/s]", "attitude[rad]", "converged[s]", "saturated", "stale");
    for (std::size_t i = 0; i < a.followers.size(); ++i) {
      const FollowerAnalysis& f = a.followers[i];
      const FormationErrors e = i < a.final_errors.size() ? a.final_errors[i] : f.final_errors;
      char conv[32] = "no";
      if (f.converged) std::snprintf(conv, sizeof(conv), "%.2f", f.convergence_time_s);
      std::printf("  %-9d %12.4f %14.4f %14.4f %12s %9.1f%% %9lld\n", f.id, e.position_m,
                  e.velocity_mps, e.attitude_rad, conv, 100.0 * f.saturation_fraction,
                  static_cast<long long>(f.stale_events));
    }
  }
  const ChannelAnalysis& c = a.channel;
  std::printf("  channel: %lld sent, %lld delivered, %lld dropped (loss %lld, queue %lld, invalid %lld)\n",
              static_cast<long long>(c.sent), static_cast<long long>(c.delivered),
              static_cast<long long>(c.dropped), static_cast<long long>(c.dropped_loss),
              static_cast<long long>(c.dropped_queue), static_cast<long long>(c.dropped_invalid));
  if (c.delay_error_s.count > 0) {
    std::printf("  realised delay - configured tau: p50 %.3f ms, p99 %.3f ms, max %.3f ms (%s)\n",
                c.delay_error_s.p50 * 1e3, c.delay_error_s.p99 * 1e3, c.delay_error_s.max * 1e3,
                a.mode == "realtime" ? "scheduled release times; the release error is below"
                                     : "tick quantisation: delivery at the first tick at or after send + tau");
  }
  if (c.age_at_use_s.count > 0) {
    std::printf("  message age at use: p50 %.3f s, p99 %.3f s, max %.3f s\n", c.age_at_use_s.p50,
                c.age_at_use_s.p99, c.age_at_use_s.max);
  }
  if (c.model_mismatches > 0) {
    std::printf("  WARNING: %lld channel decisions drew a delay other than the scenario's tau(t)\n",
                static_cast<long long>(c.model_mismatches));
  }
  if (a.mode == "realtime") {
    std::printf("  emulator release error p99 %.3f ms\n", c.release_error_p99_s * 1e3);
  }
  if (!a.processes.empty()) {
    std::printf("  %-9s %10s %10s %10s %9s %10s %9s\n", "process", "late p50", "late p99",
                "late max", "overruns", "saturated", "timeouts");
    for (const ProcessAnalysis& p : a.processes) {
      const HealthRecord& h = p.last;
      std::printf("  %-9s %8.3fms %8.3fms %8.3fms %9lld %9.1f%% %9lld\n",
                  p.id == -1 ? "emulator" : std::to_string(p.id).c_str(), h.lateness_p50_s * 1e3,
                  h.lateness_p99_s * 1e3, h.lateness_max_s * 1e3,
                  static_cast<long long>(h.overruns), 100.0 * h.saturation_fraction,
                  static_cast<long long>(h.neighbour_timeouts));
    }
  }
  if (a.interrupted) std::printf("  the run was interrupted\n");
  for (const std::string& p : a.problems) std::printf("  PROBLEM: %s\n", p.c_str());
}

}  // namespace

int RunAnalyze(const AnalyzeOptions& opt) {
  const char* who = "shoal analyze: ";
  if (opt.live == !opt.log.empty()) {
    std::cerr << who
              << (opt.live ? "give either a LOG or --live, not both"
                           : "give a LOG to analyse, or --live to listen on an LCM URL")
              << "\n";
    return kExitBadInput;
  }
  if (!opt.live && (!std::isnan(opt.duration_s) || !opt.lcm_url.empty())) {
    std::cerr << who << "--duration and --lcm-url go with --live\n";
    return kExitBadInput;
  }
  if (opt.live && !std::isnan(opt.duration_s) && !(opt.duration_s > 0 && std::isfinite(opt.duration_s))) {
    std::cerr << who << "--duration must be a positive number of seconds (got " << opt.duration_s
              << ")\n";
    return kExitBadInput;
  }
  if (!opt.csv_dir.empty()) {  // before listening for a long time, not after it
    struct stat st {};
    if (mkdir(opt.csv_dir.c_str(), 0755) != 0 && errno != EEXIST) {
      std::cerr << who << opt.csv_dir << ": cannot create the CSV directory ("
                << std::strerror(errno) << ")\n";
      return kExitBadInput;
    }
    if (stat(opt.csv_dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) {
      std::cerr << who << opt.csv_dir << ": exists and is not a directory; give --csv a directory\n";
      return kExitBadInput;
    }
  }
  Scenario scenario;
  LoadOptions lo;
  if (!opt.scenario.empty()) {
    if (!LoadScenarioOrReport("shoal analyze", opt.scenario, &scenario)) return kExitBadInput;
    lo.scenario = &scenario;
  }

  RunData run;
  std::string error;
  const bool ok = opt.live ? ReadLive(opt, lo, &run, &error) : LoadRunLog(opt.log, lo, &run, &error);
  if (!ok) {
    std::cerr << who << error << "\n";
    return kExitBadInput;
  }
  for (const std::string& w : run.warnings) std::cerr << who << "warning: " << w << "\n";
  if (!run.has_scenario) {
    std::cerr << who << "warning: no scenario text in "
              << (opt.live ? "the received statuses" : "the log")
              << "; formation errors and configured delays "
                 "need --scenario FILE\n";
  }
  const RunAnalysis a = AnalyseRun(run);
  if (!opt.csv_dir.empty()) {
    std::vector<std::string> files;
    if (!WriteRunCsv(run, a, opt.csv_dir, &files, &error)) {
      std::cerr << who << error << "\n";
      return kExitBadInput;
    }
    if (!opt.json) std::fprintf(stderr, "shoal analyze: wrote %zu CSV files to %s\n", files.size(),
                                opt.csv_dir.c_str());
  }
  if (opt.json) {
    AnalysisSource source;
    source.live = opt.live;
    source.log = opt.log;
    std::cout << JsonText(AnalysisJson(run, a, source)) << "\n";
  } else {
    PrintText(opt, run, a);
  }
  return kExitOk;
}

}  // namespace shoal
