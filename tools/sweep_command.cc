// shoal sweep: every point of a campaign as its own `shoal sim|run` process, judged by the
// campaign's criteria, with results that survive an interruption (docs/campaigns.md).
#include "tools/sweep_command.h"

#include <sched.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <iostream>
#include <thread>

#include "analysis/verdict.h"
#include "campaign/campaign_file.h"
#include "campaign/executor.h"
#include "campaign/map.h"
#include "campaign/plan.h"
#include "campaign/points.h"
#include "campaign/results.h"
#include "runtime/stop_signals.h"
#include "scenario/overrides.h"

namespace shoal {
namespace {

using ojson = nlohmann::ordered_json;

/// An argument as a POSIX shell reads it back: as is when plain, else in single quotes.
std::string ShellQuote(const std::string& arg) {
  const bool plain = !arg.empty() && std::all_of(arg.begin(), arg.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || std::string("_-./=:,+@%").find(c) !=
                                                              std::string::npos;
  });
  if (plain) return arg;
  std::string out = "'";
  for (const char c : arg) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

/// The point's command: what a user would type (argv[0] "shoal"); `exe` replaces it to run.
std::vector<std::string> PointArgv(const Campaign& c, const std::string& dir,
                                   const std::vector<ScenarioOverride>& overrides,
                                   const CampaignPoint& p, bool allow_large) {
  std::vector<std::string> argv = {"shoal"};
  if (c.engine == CampaignEngine::kSim) {
    argv.insert(argv.end(), {"sim", c.scenario});
  } else {
    argv.insert(argv.end(), {"run", c.scenario, "--mode", EngineName(c.engine)});
  }
  for (const ScenarioOverride& o : overrides) argv.insert(argv.end(), {"--set", o.key + "=" + o.value});
  if (c.duration_s > 0) argv.insert(argv.end(), {"--duration", ExactNumber(c.duration_s)});
  argv.insert(argv.end(), {"--json", "--quiet"});
  if (allow_large) argv.push_back("--allow-large");
  if (c.engine != CampaignEngine::kSim) {
    char name[32];
    std::snprintf(name, sizeof(name), "point-%05lld.lcmlog", static_cast<long long>(p.index));
    argv.insert(argv.end(), {"--out", dir + "/runs/" + name});
  }
  return argv;
}

std::string CommandText(const std::vector<std::string>& argv) {
  std::string text;
  for (const std::string& a : argv) text += (text.empty() ? "" : " ") + ShellQuote(a);
  return text;
}

/// "points D/P  passed A  failed B  ETA 1m05s", redrawn in place on a terminal.
class Progress {
 public:
  Progress(std::int64_t total, bool live)
      : total_(total), live_(live), start_(std::chrono::steady_clock::now()) {}
  void Count(bool pass) { ++(pass ? passed_ : failed_); }
  void Resumed(bool pass) { Count(pass), ++resumed_; }
  void Draw(bool final) const {
    if (!live_ && !final) return;
    const std::int64_t done = passed_ + failed_, ran = done - resumed_;
    std::string line = "points " + std::to_string(done) + "/" + std::to_string(total_) +
                       "  passed " + std::to_string(passed_) + "  failed " + std::to_string(failed_);
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    if (!final && ran > 0) {
      const double eta = elapsed / static_cast<double>(ran) * static_cast<double>(total_ - done);
      char text[32];
      std::snprintf(text, sizeof(text), "  ETA %dm%02ds", static_cast<int>(eta) / 60,
                    static_cast<int>(eta) % 60);
      line += text;
    }
    std::fprintf(stderr, live_ ? "\r%s\033[K%s" : "%s%s", line.c_str(), final ? "\n" : "");
  }

 private:
  std::int64_t total_;
  bool live_;
  std::int64_t passed_ = 0, failed_ = 0, resumed_ = 0;
  std::chrono::steady_clock::time_point start_;
};

/// A value as TOML writes it (strings quoted), so that an axis value "none" does not read
/// as no value, which is "(none)".
std::string ValueText(const ojson& v) { return v.is_null() ? "(none)" : v.dump(); }

/// The end-of-run summary on stdout: counts and the boundary along each axis.
void PrintSummary(const ojson& s, const std::string& dir) {
  std::printf("shoal sweep: %lld of %lld points: %d passed, %d failed, %d crashed, %d timeout, "
              "%d no result\n",
              static_cast<long long>(s["finished"].get<std::int64_t>()),
              static_cast<long long>(s["points"].get<std::int64_t>()), s["passed"].get<int>(),
              s["failed"].get<int>(), s["crashed"].get<int>(), s["timeout"].get<int>(),
              s["no_result"].get<int>());
  constexpr std::size_t kMaxLinesShown = 4;
  for (const ojson& axis : s["axes"]) {
    if (!axis.contains("boundary")) continue;
    const ojson& lines = axis["boundary"];
    for (std::size_t i = 0; i < lines.size() && i < kMaxLinesShown; ++i) {
      std::string fixed;
      for (auto it = lines[i]["fixed"].begin(); it != lines[i]["fixed"].end(); ++it) {
        fixed += (fixed.empty() ? " (" : ", ") + it.key() + " = " + ValueText(*it);
      }
      std::printf("  boundary %s%s: last pass %s, first fail %s\n",
                  axis["key"].get<std::string>().c_str(), (fixed.empty() ? "" : fixed + ")").c_str(),
                  ValueText(lines[i]["last_pass"]).c_str(), ValueText(lines[i]["first_fail"]).c_str());
    }
    if (lines.size() > kMaxLinesShown) {
      std::printf("  ... %zu more lines along %s in summary.json\n", lines.size() - kMaxLinesShown,
                  axis["key"].get<std::string>().c_str());
    }
  }
  std::printf("  results: %s/results.jsonl, results.csv, summary.json\n", dir.c_str());
}

/// Draws DIR/stability_map.png and says where it is, or why there is none.
void ReportMap(const std::string& dir, const ojson& summary, const Rows& rows, bool quiet) {
  std::string why;
  if (DrawStabilityMap(dir, summary, rows, &why)) {
    if (!quiet) std::printf("  stability map: %s/stability_map.png\n", dir.c_str());
  } else {
    std::fprintf(stderr, "shoal sweep: no stability map: %s\n", why.c_str());
  }
}

/// 0 when all `expected` points finished and passed, else 1.
int SummaryStatus(const ojson& s, std::int64_t expected) {
  const bool all_pass = s["passed"].get<std::int64_t>() == expected &&
                        s["finished"].get<std::int64_t>() == expected;
  return all_pass ? kExitOk : kExitFailed;
}

std::string SelfExe() {
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::string("/proc/self/exe") : exe.string();
}

int Workers(const Campaign& c, int flag) {
  if (flag > 0) return flag;
  if (c.workers > 0) return c.workers;
  if (c.engine == CampaignEngine::kRealtime) return 1;  // real-time runs measure timing
  // The CPUs this process may run on (a Slurm task's allocation, taskset), not the node's.
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof(set), &set) == 0) return std::max(1, CPU_COUNT(&set));
  return static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

/// Everything checked before a point runs.
struct Prepared {
  Campaign campaign;
  std::vector<CampaignPoint> points;
  std::vector<PointPlan> plans;
  std::vector<ScenarioOverride> base;
  Shard shard;
  ojson manifest;
};

Prepared Prepare(const SweepOptions& opt) {
  Prepared p;
  std::string error;
  if (!opt.shard.empty() && !ParseShard(opt.shard, &p.shard, &error)) throw CampaignError(error);
  p.campaign = LoadCampaign(opt.campaign);
  const std::string scenario_text = ReadScenarioText(p.campaign.scenario);
  p.base = BaseOverrides(p.campaign, opt.set);
  p.points = MakePoints(p.campaign);
  // Each point's scenario is built and checked first, on the file parsed once: about
  // 0.05 ms a point (a profile of 99,856 points), still a minute for a million (and again
  // in every shard), which should not look like a hang.
  if (!opt.quiet && p.points.size() >= 10000) {
    std::fprintf(stderr, "shoal sweep: checking the scenarios of %zu points before any runs...\n",
                 p.points.size());
  }
  p.plans = PlanPoints(p.campaign, scenario_text, p.base, p.points, !opt.allow_large);
  std::vector<std::string> cli_set = opt.set;
  p.manifest = MakeManifest(p.campaign, scenario_text, cli_set, p.points, p.shard,
                            MapTheory(p.campaign, scenario_text, p.base, p.points));
  return p;
}

/// Runs the points of the shard that `dir` has no row for; false if interrupted.
bool Execute(const Prepared& p, const SweepOptions& opt, ResultsDir* dir,
             std::int64_t* shard_points) {
  const Campaign& c = p.campaign;
  const std::string exe = SelfExe();
  std::vector<PointJob> jobs;
  std::vector<std::string> commands(p.points.size());
  std::int64_t total = 0;
  for (const CampaignPoint& point : p.points) {
    if (!p.shard.Has(point.index)) continue;
    ++total;
    if (dir->rows().count(point.index)) continue;
    std::vector<std::string> argv = PointArgv(c, opt.out, PointOverrides(c, p.base, point), point, opt.allow_large);
    commands[static_cast<std::size_t>(point.index)] = CommandText(argv);
    argv[0] = exe;
    jobs.push_back({point.index, std::move(argv),
                    PointTimeout(c, p.plans[static_cast<std::size_t>(point.index)])});
  }
  Progress progress(total, !opt.quiet && isatty(2));
  for (const auto& [index, row] : dir->rows()) progress.Resumed(row.value("pass", false));
  std::error_code ec;
  if (c.engine != CampaignEngine::kSim) std::filesystem::create_directories(opt.out + "/runs", ec);
  if (ec) throw CampaignError(opt.out + "/runs: cannot create the logs' directory (" + ec.message() + ")");
  ExecutorOptions options;
  options.workers = Workers(c, opt.workers);
  options.stop_requested = &StopSignals::Requested;
  std::string write_error;
  options.on_finished = [&](const PointOutcome& o) {
    const CampaignPoint& point = p.points[static_cast<std::size_t>(o.index)];
    const ojson row = MakeRow(c, point, o, commands[static_cast<std::size_t>(o.index)]);
    try {
      dir->Append(row);
    } catch (const CampaignError& e) {  // results cannot be kept: stop, as Ctrl-C would
      if (write_error.empty()) write_error = e.what();
      StopSignals::Request();
    }
    progress.Count(row["pass"].get<bool>());
  };
  options.on_tick = [&] { progress.Draw(false); };
  // A closed terminal stops the sweep as Ctrl-C does: finished rows kept, points killed.
  const StopSignals signals(StopSignals::Options{true, true});
  const bool finished = RunPoints(jobs, options);
  if (!opt.quiet) progress.Draw(true);
  if (!write_error.empty()) throw CampaignError(write_error);
  *shard_points = total;
  return finished;
}

}  // namespace

int RunSweep(const SweepOptions& opt) {
  Prepared p;
  std::unique_ptr<ResultsDir> dir;
  std::int64_t shard_points = 0;
  try {
    p = Prepare(opt);
    dir = std::make_unique<ResultsDir>(opt.out, p.manifest);
    // More shards than points (a Slurm array sized before the campaign shrank) leaves
    // some empty: its directory is still written, so that merging every shard works, and
    // the user hears that this one ran nothing.
    if (p.shard.n > 1 && static_cast<std::int64_t>(p.points.size()) < p.shard.k) {
      std::cerr << "shoal sweep: shard " << p.shard.k << "/" << p.shard.n << " holds none of the "
                << p.points.size() << " points of " << opt.campaign
                << " (shard K/N runs the points whose index % N == K-1): nothing to run\n";
    }
  } catch (const CampaignError& e) {
    std::cerr << "shoal sweep: " << e.what() << "\n";
    return kExitBadInput;
  }
  try {
    if (!Execute(p, opt, dir.get(), &shard_points)) {
      std::cerr << "shoal sweep: interrupted; " << dir->rows().size()
                << " finished points kept in " << opt.out
                << "/results.jsonl (run the same command again to resume)\n";
      return kExitInterrupted;
    }
    dir->Finish();
  } catch (const CampaignError& e) {  // the output directory failed (disk full, removed)
    std::cerr << "shoal sweep: " << e.what() << "\n";
    return kExitFailed;
  } catch (const nlohmann::json::exception& e) {
    std::cerr << "shoal sweep: " << opt.out << ": damaged results (" << e.what() << ")\n";
    return kExitFailed;
  }
  const ojson summary = Summarize(p.manifest, dir->rows());
  if (!opt.quiet) PrintSummary(summary, opt.out);
  ReportMap(opt.out, summary, dir->rows(), opt.quiet);
  return SummaryStatus(summary, shard_points);
}

int RunSweepMerge(const SweepMergeOptions& opt) {
  try {
    const Rows rows = MergeResults(opt.dirs, opt.out, opt.allow_missing, opt.allow_overlap);
    const ojson summary = nlohmann::ordered_json::parse(
        [&] {
          std::ifstream in(opt.out + "/summary.json");
          return std::string(std::istreambuf_iterator<char>(in), {});
        }());
    if (!opt.quiet) PrintSummary(summary, opt.out);
    ReportMap(opt.out, summary, rows, opt.quiet);
    return SummaryStatus(summary, summary["points"].get<std::int64_t>());
  } catch (const CampaignError& e) {
    std::cerr << "shoal sweep merge: " << e.what() << "\n";
    return kExitBadInput;
  } catch (const nlohmann::json::exception& e) {
    std::cerr << "shoal sweep merge: damaged results (" << e.what() << ")\n";
    return kExitBadInput;
  }
}

}  // namespace shoal
