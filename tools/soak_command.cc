// `shoal soak`: plans the phased run (campaign/soak_plan.h), runs it through the launcher
// as `shoal run` does, and judges its log (analysis/soak_analysis.h).
#include "tools/soak_command.h"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>

#include "analysis/soak_analysis.h"
#include "analysis/verdict.h"
#include "campaign/plan.h"
#include "campaign/soak_plan.h"
#include "core/swarm.h"
#include "launcher/machine_witness.h"
#include "launcher/run_report.h"
#include "runtime/clocked_node.h"
#include "runtime/process.h"
#include "runtime/stop_signals.h"
#include "render/campaign_figures.h"
#include "scenario/loader.h"
#include "tools/json_text.h"

namespace shoal {
namespace {

bool MakeOutDir(const std::string& dir, std::string* error) {
  if (mkdir(dir.c_str(), 0777) != 0 && errno != EEXIST) {
    *error = "--out " + dir + ": cannot create it (" + std::strerror(errno) + ")";
    return false;
  }
  struct stat st {};
  if (stat(dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) {
    *error = "--out " + dir + ": not a directory";
    return false;
  }
  // A soak is hours of machine time: never write over the verdict of another one.
  if (access((dir + "/soak.json").c_str(), F_OK) == 0) {
    *error = "--out " + dir + ": already holds a soak (soak.json); choose another directory";
    return false;
  }
  return true;
}

/// The campaign's [pass] as soak criteria on phase metrics; `converged` means the phase
/// re-converged.
std::vector<SoakCriterion> PhaseCriteria(const Campaign& c) {
  std::vector<SoakCriterion> out;
  for (const CampaignCriterion& k : c.pass) {
    SoakCriterion s;
    s.metric = k.key == "converged" ? "reconverged" : k.key;
    if (k.equals) s.equals = *k.equals;
    s.min = k.min;
    s.max = k.max;
    out.push_back(std::move(s));
  }
  return out;
}

/// The phase metrics a criterion may name (SoakPhaseResult::metrics).
void CheckCriteria(const Campaign& c) {
  static const char* const kMetrics[] = {
      "reconverged",       "reconverged_at_s", "final_position_error_m", "max_position_error_m",
      "delay_error_p99_s", "release_error_p99_s", "lateness_p99_s", "overruns", "states",
      "states_expected"};
  for (const CampaignCriterion& k : c.pass) {
    const std::string m = k.key == "converged" ? "reconverged" : k.key;
    bool known = false;
    for (const char* name : kMetrics) known = known || m == name;
    if (known) continue;
    std::string list;
    for (const char* name : kMetrics) list += (list.empty() ? "" : ", ") + std::string(name);
    throw CampaignError(c.path + ":" + std::to_string(k.line) + ": pass." + k.key +
                        ": not a phase metric of a soak; use one of converged (= " +
                        "reconverged), " + list);
  }
}

LaunchCallbacks Callbacks(const SoakPlan& plan, bool show) {
  LaunchCallbacks cb;
  if (show) {
    cb.progress = [&plan](const LaunchProgress& p) {
      std::size_t k = 0;
      while (k + 1 < plan.phases.size() && p.sim_time_s >= plan.phases[k].end_s) ++k;
      std::fprintf(stderr,
                   "\r  phase %zu/%zu (%s)  t = %.0f / %.0f s  (%.1fx real time)  worst "
                   "position error %.2f m  processes %d/%d   ",
                   k + 1, plan.phases.size(), plan.phases[k].label.c_str(), p.sim_time_s,
                   p.duration_s, p.realtime_factor, p.worst_position_error_m, p.alive,
                   p.processes);
    };
  }
  cb.problem = [show](const std::string& problem, bool) {
    std::fprintf(stderr, "%sshoal soak: %s\n", show ? "\n" : "", problem.c_str());
  };
  cb.restarted = [show](const std::string& what) {
    std::fprintf(stderr, "%sshoal soak: %s\n", show ? "\n" : "", what.c_str());
  };
  return cb;
}

/// The figure's one-line verdict: the failed phases, else the first reason.
std::string ShortVerdict(const SoakResult& r) {
  if (r.pass) return "PASS";
  std::string phases;
  for (const SoakPhaseResult& p : r.phases) {
    if (!p.pass) phases += (phases.empty() ? "" : ", ") + std::to_string(p.index + 1);
  }
  if (!phases.empty()) return "FAIL: phase " + phases + " (soak.json says why)";
  std::string first = r.reasons.empty() ? std::string() : r.reasons[0];
  if (first.size() > 70) first = first.substr(0, 67) + "...";
  return "FAIL: " + first;
}

void AddMinute(const SoakMinute& m, bool realtime, render::SoakFigureData* d) {
  const double t = 0.5 * (m.start_s + m.end_s);  // a minute's figures stand for its middle
  if (m.worst_position_error_m) {
    d->error_t_s.push_back(t);
    d->worst_position_error_m.push_back(*m.worst_position_error_m);
  }
  // Lockstep has no wall-clock loop and releases on ticks: lateness and delay error say
  // nothing there, so their panels are left out.
  if (realtime) {
    d->lateness_t_s.push_back(t);
    d->lateness_p99_s.push_back(m.lateness_p99_s);
    if (m.delay_error_p99_s) {
      d->delay_error_t_s.push_back(t);
      d->delay_error_p99_s.push_back(*m.delay_error_p99_s);
    }
  }
  d->logged_t_s.push_back(t);
  d->logged_per_min.push_back(static_cast<double>(m.states));
  d->expected_per_min.push_back(static_cast<double>(m.states_expected));
  for (const SoakProcessUse& u : m.processes) {
    auto it = std::find_if(d->rss.begin(), d->rss.end(),
                           [&](const auto& p) { return p.name == u.name; });
    if (it == d->rss.end()) it = d->rss.insert(d->rss.end(), {u.name, {}, {}});
    it->t_s.push_back(t);
    it->rss_mib.push_back(u.rss_kib / 1024.0);
  }
}

render::SoakFigureData FigureData(const Campaign& c, const SoakPlan& plan, const SoakResult& r) {
  render::SoakFigureData d;
  d.title = "soak: " + std::filesystem::path(c.path).stem().string() + ", " + EngineName(c.engine);
  d.verdict = ShortVerdict(r);
  d.phase_key = c.axes.size() == 1 ? c.axes[0].key : std::string("phase");
  for (const SoakPhaseResult& p : r.phases) {
    std::string why;
    for (const std::string& w : p.why) why += (why.empty() ? "" : "; ") + w;
    const std::string& label = plan.phases[static_cast<std::size_t>(p.index)].label;
    const std::size_t eq = label.find(" = ");
    const bool one = c.axes.size() == 1 && eq != std::string::npos;
    d.phases.push_back({p.phase.start_s, p.phase.end_s, one ? label.substr(eq + 3) : label,
                        p.pass, why});
  }
  d.position_tol_m = plan.scenario.metrics.position_tol_m;
  const bool realtime = c.engine == CampaignEngine::kRealtime;
  d.lateness_p99_max_s = realtime ? c.soak.lateness_p99_max_s : -1.0;
  d.delay_error_p99_max_s = realtime ? c.soak.delay_error_p99_max_s : -1.0;
  for (const SoakMinute& m : r.minutes) AddMinute(m, realtime, &d);
  return d;
}

bool WriteText(const std::string& path, const std::string& text, std::string* error) {
  std::ofstream f(path, std::ios::trunc);
  f << text;
  f.close();
  if (!f) *error = path + ": cannot write it";
  return static_cast<bool>(f);
}

void PrintSummary(const SoakResult& r, const std::string& dir) {
  std::printf("shoal soak: %zu phases, verdict %s\n", r.phases.size(), r.pass ? "PASS" : "FAIL");
  for (const SoakPhaseResult& p : r.phases) {
    std::string why;
    for (const std::string& w : p.why) why += (why.empty() ? "" : "; ") + w;
    std::printf("  phase %d  %-40s %s%s%s\n", p.index + 1, p.phase.label.c_str(),
                p.pass ? "pass" : "FAIL", why.empty() ? "" : ": ", why.c_str());
  }
  for (const std::string& reason : r.reasons) std::printf("  - %s\n", reason.c_str());
  if (r.timing_machine_limited) {
    std::printf("  the soak missed only timing targets, where the machine itself stalled: its "
                "timing is what this machine allows (docs/campaigns.md, \"The machine's own "
                "stalls\")\n");
  }
  std::printf("  written: %s/soak.json, %s/soak.png, log %s/soak.lcmlog\n", dir.c_str(),
              dir.c_str(), dir.c_str());
}

struct Planned {
  Campaign campaign;
  SoakPlan plan;
};

bool Plan(const SoakOptions& opt, Planned* out) {
  try {
    out->campaign = LoadCampaign(opt.campaign);
    CheckCriteria(out->campaign);
    const std::string text = ReadScenarioText(out->campaign.scenario);
    out->plan = PlanSoak(out->campaign, text, BaseOverrides(out->campaign, opt.set));
    return true;
  } catch (const CampaignError& e) {
    std::cerr << "shoal soak: " << e.what() << "\n";
  } catch (const ScenarioError& e) {
    std::cerr << "shoal soak: " << e.what() << "\n";
  }
  return false;
}

LaunchOptions LaunchOptionsOf(const SoakOptions& opt, const Planned& p) {
  LaunchOptions launch;
  launch.scenario = p.campaign.scenario;
  launch.mode = p.campaign.engine == CampaignEngine::kRealtime ? ModeName(Mode::kRealtime)
                                                               : ModeName(Mode::kLockstep);
  launch.duration_s = p.plan.duration_s;
  launch.out = opt.out + "/soak.lcmlog";
  for (const ScenarioOverride& o : p.plan.overrides) launch.set.push_back(o.key + "=" + o.value);
  launch.resource_interval_s = 60.0;
  launch.sched_fifo = opt.sched_fifo;
  launch.allow_large = opt.allow_large;  // refused by RunSoak before anything is made
  // As shoal run: real-time followers are staggered wherever the channel leaves room.
  launch.stagger = launch.mode == ModeName(Mode::kRealtime) &&
                   ClockedNode::StaggerPhaseUs(p.plan.scenario, p.plan.scenario.followers) > 0;
  return launch;
}

SoakInput InputOf(const Planned& p, const LaunchResult& launch, nlohmann::json report) {
  SoakInput in;
  in.log = launch.log;
  in.key_file = launch.key_file;
  in.resources_csv = launch.resources_file;
  in.report = std::move(report);
  for (const SoakPlanPhase& ph : p.plan.phases) in.phases.push_back({ph.start_s, ph.end_s, ph.label});
  in.settle_s = p.campaign.soak.settle_s;
  in.criteria = PhaseCriteria(p.campaign);
  in.targets.lateness_p99_max_s = p.campaign.soak.lateness_p99_max_s;
  in.targets.delay_error_p99_max_s = p.campaign.soak.delay_error_p99_max_s;
  in.targets.memory_growth_max = p.campaign.soak.memory_growth_max;
  in.targets.overruns_max = p.campaign.soak.overruns_max;
  in.engine = EngineName(p.campaign.engine);
  in.machine_watched = launch.machine.watched;
  std::map<int, std::pair<std::size_t, double>> per_cpu;  // stalls kept, the last one's start
  for (const MachineStall& s : launch.machine.stalls) {
    in.machine_stalls.push_back({s.start_s, s.length_s});
    auto& [kept, last] = per_cpu[s.cpu];
    ++kept;
    last = std::max(last, s.start_s);
  }
  // A thread that filled its room dropped what came after its last stall kept.
  for (const auto& [cpu, c] : per_cpu) {
    if (launch.machine.stalls_not_kept > 0 && c.first >= kStallRoom) {
      in.machine_complete_until_s = std::min(in.machine_complete_until_s, c.second);
    }
  }
  return in;
}

}  // namespace

int RunSoak(const SoakOptions& opt) {
  Planned p;
  if (!Plan(opt, &p)) return kExitBadInput;
  std::string error;
  if (!opt.sched_fifo.empty() && p.campaign.engine != CampaignEngine::kRealtime) {
    std::cerr << "shoal soak: --sched-fifo is for real time; this campaign's engine is "
              << EngineName(p.campaign.engine) << "\n";
    return kExitBadInput;
  }
  std::string why;
  if (!opt.sched_fifo.empty() && !SchedFifoPermitted(kEmulatorFifoPriority, &why)) {
    std::cerr << "shoal soak: --sched-fifo: " << why << "\n";
    return kExitBadInput;
  }
  if (!opt.allow_large) {
    // A soak's length is its phases': refused here, before its output directory is made,
    // in a soak's words rather than shoal run's.
    const std::string refusal = LargeRunRefusal(
        p.plan.scenario, p.plan.duration_s,
        p.campaign.engine == CampaignEngine::kRealtime ? RunPace::kRealtime : RunPace::kLockstep,
        "the soak (fewer phases or a shorter [soak] phase_s)", "--allow-large");
    if (!refusal.empty()) {
      std::cerr << "shoal soak: " << opt.campaign << ": " << refusal << "\n";
      return kExitBadInput;
    }
  }
  if (!MakeOutDir(opt.out, &error)) {
    std::cerr << "shoal soak: " << error << "\n";
    return kExitBadInput;
  }
  const bool show = !opt.quiet && !opt.json && isatty(2);
  if (!opt.json) {
    std::fprintf(stderr, "shoal soak: %zu phases of %.0f s, %.0f s of mission time in %s\n",
                 p.plan.phases.size(), p.campaign.soak.phase_s, p.plan.duration_s,
                 EngineName(p.campaign.engine));
  }
  LaunchResult launch;
  if (!LaunchRun(p.plan.scenario, LaunchOptionsOf(opt, p), Callbacks(p.plan, show), &launch,
                 &error)) {
    std::cerr << "shoal soak: " << error << "\n";
    return kExitBadInput;
  }
  if (show) std::fprintf(stderr, "\r%140s\r", "");
  // The run's own handlers ended with it: a Ctrl-C while its log is judged, its verdict
  // written and its figure drawn (seconds, after hours of soak) waits for them rather than
  // killing the command with nothing written. The verdict is of the run, which had ended.
  const StopSignals judging;
  const bool interrupted = launch.interrupted;
  const RunReport report = MakeRunReport(p.plan.scenario, launch);
  const nlohmann::ordered_json run_json = RunReportJson(report);
  SoakResult result;
  if (!AnalyseSoak(InputOf(p, launch, nlohmann::json::parse(run_json.dump())), &result, &error)) {
    std::cerr << "shoal soak: " << error << "\n";
    return kExitFailed;
  }
  nlohmann::ordered_json soak = SoakJson(result);
  soak["campaign"] = p.campaign.path;
  soak["engine"] = EngineName(p.campaign.engine);
  soak["interrupted"] = interrupted;
  soak["log"] = launch.log;
  soak["run"] = run_json;
  if (!WriteText(opt.out + "/soak.json", JsonText(soak) + "\n", &error)) {
    std::cerr << "shoal soak: " << error << "\n";
    return kExitFailed;
  }
  if (!render::RenderSoakFigure(FigureData(p.campaign, p.plan, result), opt.out + "/soak.png",
                                &error)) {
    std::cerr << "shoal soak: soak.png: " << error << "\n";
  }
  if (opt.json) {
    std::cout << JsonText(soak) << "\n";
  } else {
    PrintSummary(result, opt.out);
  }
  if (interrupted) return kExitInterrupted;
  return result.pass ? kExitOk : kExitFailed;
}

}  // namespace shoal
