#include "launcher/run_report.h"

#include <unistd.h>

#include <cmath>

#include "analysis/analysis_json.h"
#include "analysis/run_data.h"
#include "analysis/verdict.h"
#include "runtime/process.h"

namespace shoal {

RunReport MakeRunReport(const Scenario& s, LaunchResult launch) {
  RunReport r;
  r.scenario = s.name;
  r.followers = s.followers;
  r.control_rate_hz = s.control_rate_hz;
  r.launch = std::move(launch);
  r.problems = r.launch.problems;
  // lcm-logger drops messages when it cannot keep up (LCM's 30-message subscription
  // queue); the expected count says how complete the log is.
  r.log_states_expected = (s.final_tick(r.launch.duration_s) + 1) * (s.followers + 1);
  // The summary is read back from the run's log (the single source of truth), with the
  // same code as shoal analyze.
  r.log_readable = access(r.launch.log.c_str(), R_OK) == 0;
  if (!r.log_readable) {
    r.problems.push_back("the log " + r.launch.log + " cannot be read");
    return r;
  }
  RunData run;
  LoadOptions lo;
  lo.scenario = &s;
  std::string error;
  if (!LoadRunLog(r.launch.log, lo, &run, &error)) return r;  // no Shoal data: all zero
  const RunAnalysis a = AnalyseRun(run);
  r.summary = a.summary;
  r.diverged_follower = a.diverged_follower;
  r.converged = FormationConverged(a);
  return r;
}

nlohmann::ordered_json RunReportJson(const RunReport& r) {
  const RunSummary& sum = r.summary;
  const LaunchResult& l = r.launch;
  const bool realtime = l.mode == ModeName(Mode::kRealtime);
  nlohmann::ordered_json j;
  j["scenario"] = r.scenario;
  j["mode"] = l.mode;
  AddFormationKeys(r.converged, sum.convergence_time_s, sum.final_worst, &j);
  AddTimingKeys(sum.sim_time_s, l.wall_time_s, &j);
  j["diverged_follower"] = r.diverged_follower;
  j["channel"] = {{"delivered", sum.delivered},
                  {"dropped", sum.dropped},
                  {"delay_error_p99_s", realtime ? sum.release_error_p99_s : 0.0}};
  j["loop"] = {{"lateness_p99_s", sum.lateness_p99_s}, {"overruns", sum.overruns}};
  j["all_processes_ok"] = r.all_processes_ok();
  j["problems"] = r.problems;
  j["interrupted"] = l.interrupted;
  j["log"] = l.log;
  j["process_output_dir"] = l.process_output_dir;
  j["log_states"] = sum.states;
  j["log_states_expected"] = r.log_states_expected;
  j["lcm_url"] = l.lcm_url;
  j["cpu_latency_request"] = l.cpu_latency_request;
  return j;
}

void PrintRunReport(const RunReport& r, std::FILE* out) {
  const RunSummary& sum = r.summary;
  const LaunchResult& l = r.launch;
  const bool realtime = l.mode == ModeName(Mode::kRealtime);
  std::fprintf(out, "shoal run: %s (%s, %d followers, %.0f Hz)\n", r.scenario.c_str(),
               l.mode.c_str(), r.followers, r.control_rate_hz);
  std::fprintf(out, "  simulated %.1f s in %.2f s wall (%.1fx real time)%s\n", sum.sim_time_s,
               l.wall_time_s, l.wall_time_s > 0 ? sum.sim_time_s / l.wall_time_s : 0.0,
               l.interrupted ? "  -- interrupted" : "");
  std::fprintf(out, "  %s\n", l.cpu_latency_note.c_str());
  if (r.diverged_follower) std::fprintf(out, "  DIVERGED: follower %d\n", r.diverged_follower);
  if (r.converged) {
    std::fprintf(out, "  converged: yes, at %.2f s\n", sum.convergence_time_s);
  } else {
    std::fprintf(out, "  converged: NO\n");
  }
  std::fprintf(out,
               "  final errors, worst follower: position %.4f m, velocity %.4f m/s, "
               "attitude %.4f rad\n",
               sum.final_worst.position_m, sum.final_worst.velocity_mps,
               sum.final_worst.attitude_rad);
  std::fprintf(out, "  channel (as recorded in the log): %lld delivered, %lld dropped",
               static_cast<long long>(sum.delivered), static_cast<long long>(sum.dropped));
  if (realtime) std::fprintf(out, ", release error p99 %.3f ms", sum.release_error_p99_s * 1e3);
  std::fprintf(out, "\n");
  if (realtime) {
    std::fprintf(out, "  loops: lateness p99 %.3f ms, %lld overruns\n",
                 sum.lateness_p99_s * 1e3, static_cast<long long>(sum.overruns));
  }
  for (const std::string& p : r.problems) std::fprintf(out, "  PROBLEM: %s\n", p.c_str());
  std::fprintf(out, "  log: %s (URL %s), %lld of %lld vehicle states recorded\n", l.log.c_str(),
               l.lcm_url.c_str(), static_cast<long long>(sum.states),
               static_cast<long long>(r.log_states_expected));
  std::fprintf(out, "  output of each process: %s/\n", l.process_output_dir.c_str());
}

int RunExitStatus(const RunReport& r) {
  if (r.launch.interrupted) return kExitInterrupted;
  return r.all_processes_ok() && r.converged ? kExitOk : kExitFailed;
}

}  // namespace shoal
