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
  LiveOptions live;
  if (opt.live && !LiveKey(opt.key_file, &live.key)) return kExitBadInput;
  lo.key_file = opt.key_file;
  live.url = opt.lcm_url;
  live.duration_s = opt.duration_s;
  live.progress = !opt.quiet && !opt.json;
  const bool ok = opt.live ? ReadLiveRun(live, lo, &run, &error)
                           : LoadRunLog(opt.log, lo, &run, &error);
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
  AnalysisSource source;
  source.live = opt.live;
  source.log = opt.log;
  if (opt.json) {
    std::cout << JsonText(AnalysisJson(run, a, source)) << "\n";
  } else {
    PrintAnalysisText(stdout, run, a, source);
  }
  return kExitOk;
}

}  // namespace shoal
