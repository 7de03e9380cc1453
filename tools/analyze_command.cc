#include "tools/analyze_command.h"

#include <sys/stat.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>

#include "analysis/analysis.h"
#include "analysis/analysis_json.h"
#include "analysis/analysis_text.h"
#include "analysis/csv.h"
#include "analysis/live.h"
#include "analysis/run_data.h"
#include "analysis/verdict.h"
#include "scenario/loader.h"
#include "tools/json_text.h"

namespace shoal {
namespace {

/// --live: the key of --key FILE, else of SHOAL_BUS_KEY, else none. False (said on
/// stderr) if that key is unreadable or malformed.
bool LiveKey(const std::string& key_file, std::optional<bus_auth::Key>* key) {
  bus_auth::Key k;
  std::string error;
  const char* env = std::getenv(bus_auth::kKeyEnv);
  bool ok = true;
  if (!key_file.empty()) {
    ok = bus_auth::ReadKeyFile(key_file, &k, &error);
  } else if (env != nullptr) {
    ok = bus_auth::ParseKey(env, &k, &error);
    if (!ok) error = std::string(bus_auth::kKeyEnv) + ": " + error;
  } else {
    return true;
  }
  if (ok) *key = k;
  if (!ok) std::cerr << "shoal analyze: " << error << "\n";
  return ok;
}

/// The options' problems, said on stderr before anything is read or listened to.
bool CheckOptions(const AnalyzeOptions& opt) {
  const char* who = "shoal analyze: ";
  if (opt.live == !opt.log.empty()) {
    std::cerr << who
              << (opt.live ? "give either a LOG or --live, not both"
                           : "give a LOG to analyse, or --live to listen on an LCM URL")
              << "\n";
    return false;
  }
  if (!opt.live && (!std::isnan(opt.duration_s) || !opt.lcm_url.empty() ||
                    !std::isnan(opt.until_idle_s))) {
    std::cerr << who << "--duration, --until-idle and --lcm-url go with --live\n";
    return false;
  }
  if (opt.live && !std::isnan(opt.duration_s) && !(opt.duration_s > 0 && std::isfinite(opt.duration_s))) {
    std::cerr << who << "--duration must be a positive number of seconds (got " << opt.duration_s
              << ")\n";
    return false;
  }
  if (opt.live && !std::isnan(opt.until_idle_s) &&
      !(opt.until_idle_s >= 0 && std::isfinite(opt.until_idle_s))) {
    std::cerr << who << "--until-idle must be a number of seconds >= 0 (0: never; got "
              << opt.until_idle_s << ")\n";
    return false;
  }
  if (!opt.csv_dir.empty()) {  // before listening for a long time, not after it
    struct stat st {};
    if (mkdir(opt.csv_dir.c_str(), 0755) != 0 && errno != EEXIST) {
      std::cerr << who << opt.csv_dir << ": cannot create the CSV directory ("
                << std::strerror(errno) << ")\n";
      return false;
    }
    if (stat(opt.csv_dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) {
      std::cerr << who << opt.csv_dir << ": exists and is not a directory; give --csv a directory\n";
      return false;
    }
  }
  return true;
}

}  // namespace

int RunAnalyze(const AnalyzeOptions& opt) {
  const char* who = "shoal analyze: ";
  if (!CheckOptions(opt)) return kExitBadInput;
  Scenario scenario;
  LoadOptions lo;
  if (!opt.scenario.empty()) {
    if (!LoadScenarioOrReport("shoal analyze", opt.scenario, &scenario)) return kExitBadInput;
    lo.scenario = &scenario;
  }

  RunData run;
  std::string error;
  LiveOptions live;
  if (opt.live && !LiveKey(opt.key_file, &live.key)) return kExitBadInput;
  lo.key_file = opt.key_file;
  live.url = opt.lcm_url;
  live.duration_s = opt.duration_s;
  live.until_idle_s = std::isnan(opt.until_idle_s) ? kDefaultUntilIdleS : opt.until_idle_s;
  live.progress = !opt.quiet && !opt.json;
  const bool ok = opt.live ? ReadLiveRun(live, lo, &run, &error)
                           : LoadRunLog(opt.log, lo, &run, &error);
  if (!ok) {
    std::cerr << who << error << "\n";
    return kExitBadInput;
  }
  // A scenario text that is there and does not load has its own warning (LoadRunLog).
  if (!run.has_scenario && run.scenario_text.empty()) {
    run.warnings.push_back(std::string("no scenario text in ") +
                           (opt.live ? "the received statuses" : "the log") +
                           "; formation errors and configured delays need --scenario FILE");
  }
  for (const std::string& w : run.warnings) std::cerr << who << "warning: " << w << "\n";
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
  AnalysisSource source;
  source.live = opt.live;
  source.log = opt.log;
  if (opt.json) {
    std::cout << JsonText(AnalysisJson(run, a, source)) << "\n";
  } else {
    PrintAnalysisText(stdout, run, a, source);
  }
  if (!opt.live) return kExitOk;
  const LiveCompleteness c = JudgeLiveStream(run, a);
  if (c.complete) return kExitOk;
  std::cerr << who << "INCOMPLETE: the stream missed part of the run (" << c.states_missed
            << " states missed); the analysis is of the part received\n";
  return kExitIncomplete;
}

}  // namespace shoal
