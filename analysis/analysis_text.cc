#include "analysis/analysis_text.h"

#include <cmath>

#include "analysis/live.h"
#include "analysis/verdict.h"

namespace shoal {
namespace {

/// Whether the log's messages were checked against the run's key, and what failed.
void PrintAuthentication(std::FILE* out, const RunData& run) {
  if (run.key_used) {
    std::fprintf(out, "  authentication: %lld events verified, %lld did not (dropped)%s\n",
                 static_cast<long long>(run.verified),
                 static_cast<long long>(run.unauthenticated),
                 run.key_file.empty() ? "" : (" -- key " + run.key_file).c_str());
    for (const auto& [channel, n] : run.unauthenticated_by_channel) {
      std::fprintf(out, "    unauthenticated on %s: %lld\n", channel.c_str(),
                   static_cast<long long>(n));
    }
  } else if (run.unverified > 0) {
    std::fprintf(out, "  authentication: NOT VERIFIED (%lld events carry a trailer; no key)\n",
                 static_cast<long long>(run.unverified));
  }
  if (run.insecure_run) std::fprintf(out, "  bus not authenticated (--insecure)\n");
}

/// "1.23 s", or "-" for NaN.
std::string Seconds(double t) {
  if (!std::isfinite(t)) return "-";
  char b[32];
  std::snprintf(b, sizeof(b), "%.2f s", t);
  return b;
}

/// Per [[event]]: its window, what it affects, the formation's excursion and
/// re-convergence, and the channel decisions in its window by status.
void PrintEvents(std::FILE* out, const RunAnalysis& a) {
  std::fprintf(out, "  events: %zu\n", a.events.size());
  for (const EventAnalysis& e : a.events) {
    std::fprintf(out, "  event %d %s at %.2f s until %s%s: %s\n", e.index + 1,
                 EventKindName(e.kind), e.at_s, Seconds(e.end_s).c_str(),
                 e.ends_in_run ? "" : " (run end)", e.affects.c_str());
    if (std::isfinite(e.max_position_error_m)) {
      std::fprintf(out,
                   "    excursion: position %.4f m (follower %d at %.2f s), velocity %.4f m/s\n",
                   e.max_position_error_m, e.max_position_follower, e.max_position_time_s,
                   e.max_velocity_error_mps);
    }
    if (e.reconverged) {
      std::fprintf(out, "    re-converged %.2f s after %s (at %.2f s)\n", e.time_to_reconverge_s,
                   e.ends_in_run ? "its end" : "its start", e.reconverged_at_s);
    } else {
      std::fprintf(out, "    did not re-converge (before %.2f s)\n", e.horizon_s);
    }
    std::string d;
    for (int st = 0; st < kChannelStatuses; ++st) {
      if (e.decisions[st] == 0) continue;
      d += (d.empty() ? "" : ", ") + std::to_string(e.decisions[st]) + " " +
           ChannelStatusKey(st);
    }
    std::fprintf(out, "    channel decisions in its window: %s\n", d.empty() ? "none" : d.c_str());
  }
}

}  // namespace

namespace {

/// --live: whether the stream held the whole run, said before any figure. A retimed log:
/// which log it was made from.
void PrintStream(std::FILE* out, const RunData& run, const RunAnalysis& a) {
  if (run.retimed_from.retimed) {
    std::fprintf(out, "  RETIMED log (event times in mission time) of %s; the wall time is the "
                 "original recording's\n", run.retimed_from.source.c_str());
  }
  if (!run.stream.live) return;
  const LiveCompleteness c = JudgeLiveStream(run, a);
  if (c.complete) {
    std::fprintf(out, "  stream complete: every expected state arrived, and the run's end status\n");
    return;
  }
  std::fprintf(out, "  INCOMPLETE STREAM: %lld states missed; the figures below are of the part "
               "received, not of the whole run\n", static_cast<long long>(c.states_missed));
  for (const std::string& r : c.reasons) std::fprintf(out, "    %s\n", r.c_str());
}

/// The run, its states (and those at impossible times) and its length.
void PrintHeader(std::FILE* out, const RunData& run, const RunAnalysis& a,
                 const AnalysisSource& source) {
  const RunSummary& s = a.summary;
  std::fprintf(out, "shoal analyze: %s (%s, %d followers, mode %s)\n",
              run.scenario_name.empty() ? "unnamed run" : run.scenario_name.c_str(),
              source.live ? run.source.c_str() : source.log.c_str(), run.followers, a.mode.c_str());
  std::fprintf(out, "  %lld events, %lld vehicle states (of %lld expected), simulated %.2f s",
              static_cast<long long>(run.events), static_cast<long long>(s.states),
              static_cast<long long>(a.states_expected), s.sim_time_s);
  if (a.wall_time_s > 0) std::fprintf(out, ", recorded over %.2f s wall", a.wall_time_s);
  std::fprintf(out, "\n");
  PrintStream(out, run, a);
  if (a.states_damaged > 0) {
    std::fprintf(out,
                 "  DAMAGED: %lld vehicle states at impossible times (%lld negative, %lld after "
                 "the run's end at %.2f s), left out of the metrics\n",
                 static_cast<long long>(a.states_damaged),
                 static_cast<long long>(a.states_negative_time),
                 static_cast<long long>(a.states_after_end), a.end_s);
  }
  const ChannelAnalysis& c = a.channel;
  if (c.events_damaged > 0) {
    // Without an end to judge by (no scenario, no state) only the sign and order count.
    char sent_end[40] = "", deliver_end[40] = "";
    if (a.bounds.limit_us >= 0) {
      std::snprintf(sent_end, sizeof(sent_end), " or after %.2f s", a.end_s);
      std::snprintf(deliver_end, sizeof(deliver_end), " or after %.2f s",
                    ToSeconds(a.bounds.deliver_limit_us));
    }
    std::fprintf(out,
                 "  DAMAGED: %lld channel events at impossible times (%lld sent at a negative "
                 "time%s, %lld delivered before sent%s), left out of the metrics\n",
                 static_cast<long long>(c.events_damaged),
                 static_cast<long long>(c.events_sent_impossible), sent_end,
                 static_cast<long long>(c.events_delivered_impossible), deliver_end);
  }
}

/// Each restarted process (shoal run --restart on-failure) and the states it left missing.
void PrintRestarts(std::FILE* out, const RunAnalysis& a) {
  for (const RestartAnalysis& r : a.restarts) {
    const std::string who = r.id == -1  ? "channel emulator"
                            : r.id == 0 ? "leader"
                                        : "vehicle " + std::to_string(r.id);
    std::fprintf(out, "  RESTARTED: %s at t = %.2f s, %lld state(s) missing while it was down: %s\n",
                 who.c_str(), ToSeconds(r.utime), static_cast<long long>(r.states_missing),
                 r.message.c_str());
  }
}

/// The channel's lines: counts, delays, message age, model check.
void PrintChannel(std::FILE* out, const RunAnalysis& a) {
  const ChannelAnalysis& c = a.channel;
  std::fprintf(out, "  channel: %lld sent, %lld delivered, %lld dropped (loss %lld, queue %lld, invalid %lld)\n",
              static_cast<long long>(c.sent), static_cast<long long>(c.delivered),
              static_cast<long long>(c.dropped), static_cast<long long>(c.dropped_loss),
              static_cast<long long>(c.dropped_queue), static_cast<long long>(c.dropped_invalid));
  if (c.dropped_range > 0 || c.skipped_busy > 0) {
    std::fprintf(out, "  acoustic: %lld dropped out of range (in the dropped above), %lld not sent: modem busy\n",
                static_cast<long long>(c.dropped_range), static_cast<long long>(c.skipped_busy));
  }
  if (c.skipped_silent > 0 || c.dropped_link_down > 0 || c.dropped_deaf > 0) {
    std::fprintf(out, "  timeline: %lld dropped: link down, %lld dropped: receiver deaf (in the dropped above), %lld not sent: sender silent\n",
                static_cast<long long>(c.dropped_link_down), static_cast<long long>(c.dropped_deaf),
                static_cast<long long>(c.skipped_silent));
  }
  if (c.delay_error_s.count > 0) {
    std::fprintf(out, "  realised delay - configured tau: p50 %.3f ms, p99 %.3f ms, max %.3f ms (%s)\n",
                c.delay_error_s.p50 * 1e3, c.delay_error_s.p99 * 1e3, c.delay_error_s.max * 1e3,
                a.mode == "realtime" ? "scheduled release times; the release error is below"
                                     : "tick quantisation: delivery at the first tick at or after send + tau");
  }
  if (c.age_at_use_s.count > 0) {
    std::fprintf(out, "  message age at use: p50 %.3f s, p99 %.3f s, max %.3f s\n", c.age_at_use_s.p50,
                c.age_at_use_s.p99, c.age_at_use_s.max);
  }
  if (c.model_mismatches > 0) {
    std::fprintf(out, "  WARNING: %lld channel decisions drew a delay other than the scenario's tau(t)\n",
                static_cast<long long>(c.model_mismatches));
  }
  if (a.mode == "realtime") {
    std::fprintf(out, "  emulator release error p99 %.3f ms\n", c.release_error_p99_s * 1e3);
  }
}

}  // namespace

void PrintAnalysisText(std::FILE* out, const RunData& run, const RunAnalysis& a,
                       const AnalysisSource& source) {
  const RunSummary& s = a.summary;
  PrintHeader(out, run, a, source);
  if (!a.has_formation) {
    std::fprintf(out, "  formation: not computed (%s)\n",
                !run.has_scenario
                    ? (run.scenario_text.empty() ? "no scenario in the log; give --scenario FILE"
                                                 : "the log's scenario does not load; give --scenario FILE")
                : static_cast<int>(run.scenario.offsets_m.size()) != run.followers
                    ? "the scenario's followers are not the log's"
                    : "no leader states in the log");
  } else {
    if (a.complete_samples == 0) {
      std::fprintf(out, "  swarm errors: unknown (no tick has a valid state of every vehicle, "
                        "the leader's too)\n");
    } else if (FormationConverged(a)) {
      std::fprintf(out, "  converged: yes, at %.2f s (position tol %.3g m, velocity tol %.3g m/s)\n",
                  s.convergence_time_s, run.scenario.metrics.position_tol_m,
                  run.scenario.metrics.velocity_tol_mps);
    } else {
      std::fprintf(out, "  converged: NO (position tol %.3g m, velocity tol %.3g m/s)\n",
                  run.scenario.metrics.position_tol_m, run.scenario.metrics.velocity_tol_mps);
    }
    if (a.diverged_follower) std::fprintf(out, "  DIVERGED: follower %d\n", a.diverged_follower);
    if (a.complete_samples > 0) {
      std::fprintf(out, "  final errors, worst follower: position %.4f m, velocity %.4f m/s, attitude %.4f rad\n",
                  s.final_worst.position_m, s.final_worst.velocity_mps, s.final_worst.attitude_rad);
    }
    std::fprintf(out, "  %-9s %12s %14s %14s %12s %10s %9s\n", "follower", "position[m]",
                "velocity[m/s]", "attitude[rad]", "converged[s]", "saturated", "stale");
    for (std::size_t i = 0; i < a.followers.size(); ++i) {
      const FollowerAnalysis& f = a.followers[i];
      const FormationErrors e = i < a.final_errors.size() ? a.final_errors[i] : f.final_errors;
      char conv[32] = "no";
      if (f.converged) std::snprintf(conv, sizeof(conv), "%.2f", f.convergence_time_s);
      std::fprintf(out, "  %-9d %12.4f %14.4f %14.4f %12s %9.1f%% %9lld\n", f.id, e.position_m,
                  e.velocity_mps, e.attitude_rad, conv, 100.0 * f.saturation_fraction,
                  static_cast<long long>(f.stale_events));
    }
  }
  PrintChannel(out, a);
  if (!a.processes.empty()) {
    std::fprintf(out, "  %-9s %10s %10s %10s %9s %10s %9s\n", "process", "late p50", "late p99",
                "late max", "overruns", "saturated", "timeouts");
    for (const ProcessAnalysis& p : a.processes) {
      const HealthRecord& h = p.last;
      std::fprintf(out, "  %-9s %8.3fms %8.3fms %8.3fms %9lld %9.1f%% %9lld\n",
                  p.id == -1 ? "emulator" : std::to_string(p.id).c_str(), h.lateness_p50_s * 1e3,
                  h.lateness_p99_s * 1e3, h.lateness_max_s * 1e3,
                  static_cast<long long>(h.overruns), 100.0 * h.saturation_fraction,
                  static_cast<long long>(h.neighbour_timeouts));
    }
  }
  if (!a.events.empty()) PrintEvents(out, a);
  if (a.interrupted) std::fprintf(out, "  the run was interrupted\n");
  for (const std::string& p : a.problems) std::fprintf(out, "  PROBLEM: %s\n", p.c_str());
  PrintRestarts(out, a);
  PrintAuthentication(out, run);
}


}  // namespace shoal
