#include "launcher/run_report.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>

#include "analysis/analysis_json.h"
#include "analysis/run_data.h"
#include "analysis/verdict.h"
#include "runtime/channels.h"
#include "runtime/overrun_note.h"
#include "runtime/process.h"

namespace shoal {
namespace {

std::string ProcessName(int id) {
  if (id == kEmulatorId) return "channel emulator";
  return id == 0 ? "leader" : "vehicle " + std::to_string(id);
}

/// The overrun notes of the leader or a vehicle, or the channel emulator's notes of its
/// late releases (runtime/overrun_note.h), from its output file; false when it has none
/// to read, or wrote that more followed than it noted.
bool ReadOverrunNotes(const LaunchResult& l, int id, std::vector<OverrunNote>* notes) {
  const bool emulator = id == kEmulatorId;
  const std::string tag = emulator ? "emulator" : id == 0 ? "leader" : "vehicle" + std::to_string(id);
  const std::string prefix = emulator ? "late release:" : "overrun:";
  std::ifstream in(l.process_output_dir + "/" + tag + ".txt");
  if (!in) return false;
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(prefix, 0) != 0) continue;
    OverrunNote n;
    // More than it noted, or a note another thread's output cut into: one not judged.
    const bool read = emulator ? line != kLateReleaseNotesEnd && ParseLateReleaseNote(line, &n)
                               : line != kOverrunNotesEnd && ParseOverrunNote(line, &n);
    if (!read) return false;
    if (l.t0_monotonic_ns > 0) n.due_s = (n.due_ns - l.t0_monotonic_ns) * 1e-9;
    notes->push_back(n);
  }
  return true;
}

/// The machine's worst stall among those that account for each overrun of process `id`
/// (for the channel emulator: each note of its late releases): a stall that covers at
/// least half the time the tick lost (from when it was due to when its step ended; for a
/// note, from its first release's due time to when its last went out). nullptr when one
/// overrun has none; when the process noted fewer overruns than it counted (more than
/// kOverrunNotes) or a note cannot be read; when the emulator noted no late release; for
/// a process that was started again (its last report is the new process's, whose notes
/// are in another file); or when the witness cannot speak for the process.
/// Half: once the machine runs again, every loop it held wakes at once and queues for the
/// CPUs, so a loop loses more than the stall. A stall that covers less of the lost time
/// (the process stopped, or stuck in its own work, for the rest) does not account for it.
const MachineStall* MachineExplains(const LaunchResult& l, int id, std::int64_t overruns) {
  const std::int64_t needed = id == kEmulatorId ? 1 : overruns;
  if (!l.machine.watched || needed <= 0 ||
      std::find(l.unwatched_ids.begin(), l.unwatched_ids.end(), id) != l.unwatched_ids.end()) {
    return nullptr;
  }
  for (const ProcessRestart& r : l.restarts) {
    if (r.process == ProcessName(id)) return nullptr;
  }
  std::vector<OverrunNote> notes;
  if (!ReadOverrunNotes(l, id, &notes) || static_cast<std::int64_t>(notes.size()) < needed) {
    return nullptr;
  }
  const MachineStall* worst = nullptr;
  for (const OverrunNote& n : notes) {
    double covered_s = 0.0;
    const MachineStall* s = l.machine.MostOverlapping(n.due_s, n.due_s + n.done_s, &covered_s);
    if (s == nullptr || covered_s < 0.5 * n.done_s) return nullptr;
    if (worst == nullptr || s->length_s > worst->length_s) worst = s;
  }
  return worst;
}

}  // namespace

void JudgeTiming(const RunAnalysis& a, double period_s, RunReport* r) {
  int machines = 0;
  for (const ProcessAnalysis& p : a.processes) {
    const HealthRecord& h = p.last;
    if (p.id != kEmulatorId && h.lateness_p99_s > kSlowLoopFraction * period_s) ++r->slow_loops;
    if (h.overruns == 0 && h.lateness_p99_s <= kMaxLatenessP99S) continue;
    char text[384];
    int n = std::snprintf(text, sizeof(text),
                          "%s: %lld overruns, %s p99 %.1f ms (limits: 0 overruns, p99 %.0f ms)",
                          ProcessName(p.id).c_str(), static_cast<long long>(h.overruns),
                          p.id == kEmulatorId ? "release error" : "loop lateness",
                          h.lateness_p99_s * 1e3, kMaxLatenessP99S * 1e3);
    // Where the limit is shorter than a period, a loop can be late beyond it without
    // overrunning: ticks no note names. The emulator notes every release later than it.
    static_assert(kLateReleaseNoteS <= kMaxLatenessP99S, "a release over the limit is noted");
    const bool noted = p.id == kEmulatorId || h.lateness_p99_s <= kMaxLatenessP99S ||
                       period_s <= kMaxLatenessP99S;
    const MachineStall* s = noted ? MachineExplains(r->launch, p.id, h.overruns) : nullptr;
    if (s != nullptr) {
      ++machines;
      std::snprintf(text + n, sizeof(text) - n,
                    "; the machine itself stalled for at least half of each %s (worst "
                    "%.1f ms, at t = %.3f s)",
                    p.id == kEmulatorId ? "late release" : "overrun", s->length_s * 1e3,
                    s->start_s);
    }
    r->timing_problems.push_back(text);
  }
  r->timing_ok = r->timing_problems.empty();
  r->timing_machine_limited =
      !r->timing_ok && machines == static_cast<int>(r->timing_problems.size());
}

namespace {

std::string Lost(std::int64_t have, std::int64_t expected, const std::string& what) {
  return "the log holds " + std::to_string(have) + " of " + std::to_string(expected) + " " + what +
         ": " + std::to_string(expected - have) + " lost (" +
         std::to_string((expected - have) * 100 / std::max<std::int64_t>(1, expected)) + " %)";
}

/// What the log lacks: vehicle states (lcm-logger drops what exceeds its 30-message
/// queue; a process that stopped publishes no more), or everything after the logger died.
/// `clock_ticks`: lockstep, the clock ticks the log's SHOAL_CLOCK messages cover (one
/// window each reaches the logger); -1 when not judged.
void JudgeLog(std::int64_t clock_ticks, std::int64_t expected_ticks, RunReport* r) {
  // States a restarted process never published (the ticks it was down for) were not lost
  // by the log; the report names them apart (PrintRestarts).
  const std::int64_t states = r->summary.states;
  const std::int64_t expected = r->log_states_expected - r->states_missing_in_restarts;
  // A run stopped early never ran the rest: the log is not the whole run, and that is
  // said as it is; what it lost of the part that ran (the states missing before each
  // vehicle's last one) is a loss like any other.
  const auto lacks = [&](std::int64_t have, std::int64_t whole, const std::string& what) {
    if (!r->launch.interrupted) return Lost(have, whole, what);
    return "the run was interrupted: the log holds " + std::to_string(have) + " of the " +
           std::to_string(whole) + " " + what + " of the whole run";
  };
  if (states < expected) r->log_problems.push_back(lacks(states, expected, "vehicle states"));
  if (r->launch.interrupted && r->states_lost_before_interruption > 0) {
    r->log_problems.push_back("the log lost " + std::to_string(r->states_lost_before_interruption) +
                              " vehicle states of the part that ran, before each vehicle's "
                              "last logged state");
  }
  if (clock_ticks >= 0 && clock_ticks < expected_ticks) {
    r->log_problems.push_back(lacks(clock_ticks, expected_ticks, "clock ticks"));
  }
  r->log_complete = r->log_readable && r->log_problems.empty();
}

/// What did not authenticate: in the log (the shared bus), and as each process dropped
/// it (its own group included); processes that dropped nothing are not named.
void PrintAuthentication(const RunReport& r, std::FILE* out) {
  if (!r.launch.key) {
    std::fprintf(
        out,
        "  bus NOT authenticated (--insecure): anyone on the host could publish into the run\n");
    return;
  }
  if (r.unauthenticated > 0) {
    std::fprintf(out,
                 "  authentication: %lld messages on the bus did not authenticate "
                 "(forged or another run's): dropped, never used\n",
                 static_cast<long long>(r.unauthenticated));
  }
  std::string named, silent;
  std::int64_t total = 0;
  for (const auto& [name, n] : r.launch.unauthenticated_by_process) {
    if (n < 0) silent += (silent.empty() ? "" : ", ") + name;
    if (n <= 0) continue;
    total += n;
    named += (named.empty() ? "" : ", ") + name + " " + std::to_string(n);
  }
  if (total > 0) {
    std::fprintf(out,
                 "  authentication: the processes dropped %lld messages that did not "
                 "authenticate (%s)\n",
                 static_cast<long long>(total), named.c_str());
  }
  if (!silent.empty()) {
    std::fprintf(out, "  authentication: not known what %s dropped (no exit line)\n",
                 silent.c_str());
  }
}

/// The restarts: each as shoal run saw it, and the states the log lacks because of them.
void PrintRestarts(const RunReport& r, std::FILE* out) {
  const std::vector<ProcessRestart>& rs = r.launch.restarts;
  if (rs.empty()) return;
  std::fprintf(out, "  %zu restart(s):\n", rs.size());
  for (const ProcessRestart& p : rs) {
    std::fprintf(out, "    %s (pid %d) %s at t = %.2f s of the mission: restarted as pid %d\n",
                 p.process.c_str(), p.pid, p.reason.c_str(), p.mission_s, p.new_pid);
  }
  for (const RestartAnalysis& a : r.log_restarts) {
    if (a.states_missing == 0) continue;
    std::fprintf(out,
                 "  MISSING (restart): %s published no state for %lld tick(s) before t = %.2f s "
                 "(it was down: stepped again on its restart, not published)\n",
                 ProcessName(a.id).c_str(), static_cast<long long>(a.states_missing),
                 ToSeconds(a.utime));
  }
}

/// Stalls at least this long are listed one by one (--json "machine.stalls"), at most
/// kStallsListed of them; the count and the worst cover all.
constexpr std::size_t kStallsListed = 100;

int StallsAtLeast(const MachineWatch& m, double min_s) {
  int n = 0;
  for (const MachineStall& s : m.stalls) n += s.length_s >= min_s;
  return n;
}

nlohmann::ordered_json MachineJson(const MachineWatch& m, double period_s) {
  nlohmann::ordered_json j;
  j["watched"] = m.watched;
  j["how"] = m.note;
  j["cpus"] = m.cpus;
  j["stall_min_s"] = kMachineStallMinS;
  j["stall_count"] = m.stalls.size() + m.stalls_not_kept;
  j["stalls_half_period"] = StallsAtLeast(m, 0.5 * period_s);
  j["worst_stall_s"] = m.worst_s();
  nlohmann::ordered_json list = nlohmann::ordered_json::array();
  for (const MachineStall& s : m.stalls) {
    if (list.size() >= kStallsListed) break;
    list.push_back({{"start_s", s.start_s}, {"length_s", s.length_s}, {"cpu", s.cpu}});
  }
  j["stalls"] = list;
  return j;
}

void PrintMachine(const MachineWatch& m, double period_s, bool limited, std::FILE* out) {
  if (!m.watched) {
    std::fprintf(out, "  machine: not watched (%s)\n", m.note.c_str());
    return;
  }
  const MachineStall* worst = nullptr;
  for (const MachineStall& s : m.stalls) {
    if (worst == nullptr || s.length_s > worst->length_s) worst = &s;
  }
  std::fprintf(out, "  machine: %lld stall(s) of %.0f ms or more on %d CPU(s), %d of half a "
               "period or more",
               static_cast<long long>(m.stalls.size() + m.stalls_not_kept),
               kMachineStallMinS * 1e3, m.cpus, StallsAtLeast(m, 0.5 * period_s));
  if (worst != nullptr) {
    std::fprintf(out, "; worst %.1f ms at t = %.2f s on CPU %d", worst->length_s * 1e3,
                 worst->start_s, worst->cpu);
  }
  std::fprintf(out, "\n");
  if (limited) {
    std::fprintf(out, "  the run missed its timing targets where the machine itself stalled: "
                 "its timing is what this machine allows (docs/run.md, \"When the machine "
                 "stalls\")\n");
  }
}

}  // namespace

namespace {

/// The states missing between tick 0 and each vehicle's last state at a possible time,
/// less the ticks a restarted process was down for before that state: what a log lost of
/// a run that stopped early, whose tail the stop cut off.
std::int64_t StatesLostBeforeLast(const RunData& run, const RunAnalysis& a) {
  if (a.period_us <= 0) return 0;
  std::int64_t lost = 0;
  for (std::size_t id = 0; id < run.vehicles.size(); ++id) {
    std::int64_t have = 0;
    Micros last = -1;
    for (const StateMsg& m : run.vehicles[id].samples) {
      if (m.utime < 0 || (a.bounds.limit_us >= 0 && m.utime > a.bounds.limit_us)) continue;
      ++have;
      last = m.utime;
    }
    if (last < 0) continue;
    std::int64_t missing = last / a.period_us + 1 - have;
    for (const RestartAnalysis& r : a.restarts) {
      if (r.id == static_cast<int>(id) && r.utime <= last) missing -= r.states_missing;
    }
    lost += std::max<std::int64_t>(0, missing);
  }
  return lost;
}

}  // namespace

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
  if (!r.log_readable) r.problems.push_back("the log " + r.launch.log + " cannot be read");
  RunData run;
  LoadOptions lo;
  lo.scenario = &s;
  lo.key = r.launch.key;  // the key shoal run holds: forged states cannot fill the log
  std::string error;
  // Without Shoal data in the log the summary stays all zero.
  std::int64_t clock_ticks = -1;
  if (r.log_readable && LoadRunLog(r.launch.log, lo, &run, &error)) {
    const RunAnalysis a = AnalyseRun(run);
    r.summary = a.summary;
    r.log_restarts = a.restarts;
    r.states_missing_in_restarts = a.states_missing_in_restarts;
    if (r.launch.interrupted) {
      r.states_lost_before_interruption = StatesLostBeforeLast(run, a);
    }
    r.diverged_follower = a.diverged_follower;
    r.converged = FormationConverged(a);
    r.bus_authenticated = run.bus_authenticated();
    r.unauthenticated = run.unauthenticated;
    r.unauthenticated_by_channel = run.unauthenticated_by_channel;
    if (r.launch.mode == ModeName(Mode::kRealtime)) JudgeTiming(a, 1.0 / s.control_rate_hz, &r);
    if (r.launch.mode == ModeName(Mode::kLockstep)) {
      clock_ticks = ClockTicks(run);
    }
    // The emulator's first status carries it; without it shoal analyze, render and soak
    // cannot judge the formation from the log alone.
    if (run.scenario_text.empty()) {
      r.log_problems.push_back(
          "the log holds no scenario text (the channel emulator's first status): "
          "shoal analyze and shoal render need --scenario FILE");
    }
  }
  if (!r.launch.logger_exited_early.empty()) {
    char text[64];
    std::snprintf(text, sizeof(text), "%.2f", r.summary.sim_time_s);
    r.problems.push_back("lcm-logger exited early (" + r.launch.logger_exited_early + ") at " +
                         r.launch.logger_exited_at + r.launch.logger_exit_note +
                         ": the log ends at t = " + text + " s");
  }
  JudgeLog(clock_ticks, s.final_tick(r.launch.duration_s) + 1, &r);
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
  j["stopped_by"] = l.stopped_by;
  nlohmann::ordered_json restarts = nlohmann::ordered_json::array();
  for (const ProcessRestart& p : l.restarts) {
    restarts.push_back({{"process", p.process},
                        {"pid", p.pid},
                        {"new_pid", p.new_pid},
                        {"reason", p.reason},
                        {"mission_s", p.mission_s}});
  }
  j["restarts"] = restarts;
  j["states_missing_in_restarts"] = r.states_missing_in_restarts;
  j["states_lost_before_interruption"] = r.states_lost_before_interruption;
  j["interrupted"] = l.interrupted;
  j["log"] = l.log;
  j["process_output_dir"] = l.process_output_dir;
  j["log_states"] = sum.states;
  j["log_states_expected"] = r.log_states_expected;
  j["log_complete"] = r.log_complete;
  j["log_problems"] = r.log_problems;
  j["timing_ok"] = r.timing_ok;
  j["timing_problems"] = r.timing_problems;
  j["timing_machine_limited"] = r.timing_machine_limited;
  if (realtime) j["machine"] = MachineJson(l.machine, 1.0 / r.control_rate_hz);
  j["hints"] = r.hints;
  j["lcm_url"] = l.lcm_url;
  j["bus_authenticated"] = r.bus_authenticated;
  j["key_file"] = l.key_file;
  j["unauthenticated"] = r.unauthenticated;
  j["unauthenticated_by_channel"] = r.unauthenticated_by_channel;
  // null: the process did not say (it was killed before its end).
  nlohmann::ordered_json by_process = nlohmann::ordered_json::object();
  for (const auto& [name, n] : l.unauthenticated_by_process) {
    by_process[name] = n >= 0 ? nlohmann::ordered_json(n) : nlohmann::ordered_json();
  }
  j["unauthenticated_by_process"] = by_process;
  j["sched_fifo"] = l.sched_fifo;
  j["cpu_latency_request"] = l.cpu_latency_request;
  j["cpuidle_driver"] = l.cpuidle_driver;
  j["idle_poll_threads"] = l.idle_poll_threads;
  j["idle_poll_cpu_s"] = l.idle_poll_cpu_s;
  return j;
}

namespace {

/// Several loops of a real-time run on one machine with fewer CPUs than loops were late:
/// they queued for the CPUs. One late process is that process's trouble (a stall, a fault).
bool LoopsQueued(const RunReport& r, const LoopPlacement& p) {
  const long loops = r.followers + 2;
  const bool several_late = r.timing_problems.size() >= 2 || r.slow_loops >= 2;
  return r.launch.mode == ModeName(Mode::kRealtime) && several_late && !r.launch.interrupted &&
         p.one_host && loops > p.cpus;
}

std::string Cpus(long n) { return std::to_string(n) + " CPU" + (n == 1 ? "" : "s"); }

}  // namespace

std::string StaggerHint(const RunReport& r, const LoopPlacement& p) {
  if (!LoopsQueued(r, p) || p.staggered || !p.stagger_allowed) return "";
  return "the " + std::to_string(r.followers + 2) + " loops woke at the start of each period "
         "on " + Cpus(p.cpus) + ", and the last waited for the others; without --no-stagger "
         "the followers are spread over half a period (docs/run.md, \"Many vehicles on few "
         "CPUs\")";
}

std::string FifoHint(const RunReport& r, const LoopPlacement& p) {
  if (!LoopsQueued(r, p) || !StaggerHint(r, p).empty() ||
      r.launch.sched_fifo == kSchedFifoAll) {
    return "";
  }
  return "several of the " + std::to_string(r.followers + 2) + " loops on " + Cpus(p.cpus) +
         " were late; --sched-fifo all (it needs CAP_SYS_NICE, which root has) runs every "
         "loop at SCHED_FIFO, so that each gets a CPU at its instant ahead of the machine's "
         "other work, though where real-time tasks are throttled the machine's own stalls "
         "are then not watched (docs/run.md, \"SCHED_FIFO\")";
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
    std::fprintf(out, "  loops: lateness p99 %.3f ms, %lld overruns; SCHED_FIFO asked for: %s\n",
                 sum.lateness_p99_s * 1e3, static_cast<long long>(sum.overruns),
                 l.sched_fifo.c_str());
  }
  for (const std::string& p : r.problems) std::fprintf(out, "  PROBLEM: %s\n", p.c_str());
  std::fprintf(out, "  log: %s (URL %s), %lld of %lld vehicle states recorded\n", l.log.c_str(),
               l.lcm_url.c_str(), static_cast<long long>(sum.states),
               static_cast<long long>(r.log_states_expected));
  for (const std::string& p : r.log_problems) {
    std::fprintf(out, "  LOG INCOMPLETE: %s\n", p.c_str());
  }
  PrintRestarts(r, out);
  for (const std::string& p : r.timing_problems) {
    std::fprintf(out, "  LATE (real time): %s\n", p.c_str());
  }
  if (realtime) PrintMachine(l.machine, 1.0 / r.control_rate_hz, r.timing_machine_limited, out);
  PrintAuthentication(r, out);
  for (const std::string& h : r.hints) std::fprintf(out, "  hint: %s\n", h.c_str());
  std::fprintf(out, "  output of each process: %s/\n", l.process_output_dir.c_str());
}

int RunExitStatus(const RunReport& r) {
  if (r.launch.interrupted) return kExitInterrupted;
  const bool ok = r.all_processes_ok() && r.log_complete && r.timing_ok && r.converged;
  return ok ? kExitOk : kExitFailed;
}

}  // namespace shoal
