// `shoal design`: flags in, the design report (design/report.h) out, as text or JSON. The
// only work done here is file output: the Theorem 3 certificate and the advised scenario.
#include "tools/design_command.h"

#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "design/report.h"
#include "scenario/loader.h"
#include "scenario/overrides.h"
#include "tools/json_text.h"

namespace shoal {
namespace {

design::DesignRequest RequestOf(const DesignOptions& opt) {
  design::DesignRequest q;
  q.k1 = opt.k1;
  q.k2 = opt.k2;
  q.h_s = opt.h_s;
  q.kappa = opt.kappa;
  q.rho0 = opt.rho0;
  q.alpha = opt.alpha;
  q.beta = opt.beta;
  q.safety = opt.safety;
  q.empirical = opt.empirical;
  q.empirical_duration_s = opt.empirical_duration_s;
  q.tune = opt.tune;
  q.tune_horizon_s = opt.tune_horizon_s;
  q.tune_cost = opt.tune_cost == "ise"            ? design::CostKind::kIse
                : opt.tune_cost == "position_ise" ? design::CostKind::kPositionIse
                                                  : design::CostKind::kItse;
  q.advise = opt.advise || !opt.write_scenario.empty();
  if (!opt.json && isatty(2) != 0) {
    q.progress = [](const std::string& what) { std::cerr << "shoal design: " << what << "\n"; };
  }
  return q;
}

/// A file the command will write must be writable before the solves, not after them.
bool CheckWritable(const char* flag, const std::string& path) {
  if (path.empty()) return true;
  const bool existed = access(path.c_str(), F_OK) == 0;
  FILE* f = std::fopen(path.c_str(), "a");
  if (f && !existed) std::remove(path.c_str());
  if (!f) {
    std::cerr << "shoal design: " << flag << ": " << path << ": cannot write there ("
              << std::strerror(errno) << ")\n";
    return false;
  }
  std::fclose(f);
  return true;
}

/// --certificate: Theorem 3's matrices. False if it was asked for and could not be written.
bool WriteCertificateFile(const std::string& path, design::DesignReport* r) {
  if (path.empty()) return true;
  if (!r->theorem3.evaluated) {
    std::cerr << "shoal design: --certificate: Theorem 3 was not evaluated, nothing written\n";
    return true;
  }
  std::string err;
  if (!design::WriteCertificate(r->theorem3.CertificateResult(), path, &err)) {
    std::cerr << "shoal design: --certificate: " << err << "\n";
    return false;
  }
  r->theorem3.certificate_path = path;
  return true;
}

/// --write-scenario with --set: the effective scenario (the file changed by every --set,
/// then by the advised gains), as shoal sim --set would run it, headed by the changes.
bool WriteEffectiveScenarioWithGains(const DesignOptions& opt, double k1, double k2,
                                     std::string* err) {
  std::vector<ScenarioOverride> changes;
  std::ifstream in(opt.scenario, std::ios::binary);
  std::ostringstream file;
  file << in.rdbuf();
  std::string text;
  try {
    changes = ParseSetFlags(opt.set);
    const std::string origin = "shoal design --advise";
    changes.push_back({"control.k1", ExactNumber(k1), origin});
    changes.push_back({"control.k2", ExactNumber(k2), origin});
    // A scenario named in [run] gets the suffix its advised copy has without --set; one
    // named by its file keeps taking the name of the file written.
    const std::string effective = ApplyOverridesToText(file.str(), opt.scenario, changes);
    if (ParseScenario(effective, "a").name == ParseScenario(effective, "b").name) {
      const std::string name = ParseScenario(effective, "a").name + "_advised";
      changes.push_back({"run.name", "\"" + name + "\"", origin});
    }
    text = ApplyOverridesToText(file.str(), opt.scenario, changes);
    ParseScenario(text, opt.write_scenario);
  } catch (const ScenarioError& e) {
    *err = std::string("the rewritten scenario does not load: ") + e.what();
    return false;
  }
  // Written beside the target and renamed over it, as without --set.
  const std::string tmp = opt.write_scenario + ".tmp";
  std::ofstream f(tmp, std::ios::binary);
  f << text;
  f.close();
  if (!f || std::rename(tmp.c_str(), opt.write_scenario.c_str()) != 0) {
    std::remove(tmp.c_str());
    *err = opt.write_scenario + ": cannot write there";
    return false;
  }
  return true;
}

/// --write-scenario: the scenario with the advised gains. False if it could not be written.
bool WriteAdvisedScenario(const DesignOptions& opt, design::DesignReport* r) {
  if (opt.write_scenario.empty()) return true;
  if (!r->advice || !r->advice->evaluated) {
    std::cerr << "shoal design: --write-scenario: no gains were advised ("
              << (r->advice ? r->advice->not_evaluated_reason : std::string("--advise not run"))
              << "), nothing written\n";
    return false;
  }
  std::string err;
  const design::GainAdvice& g = r->advice->advice;
  if (!g.found) {
    // No scale is certified, not even at h = 0: the "advice" is the scenario's own gains,
    // and a file of them would pass for a certified design.
    std::cerr << "shoal design: --write-scenario: no gains were advised (" << g.how
              << "), nothing written\n";
    return false;
  }
  const bool written =
      opt.set.empty()
          ? design::WriteScenarioWithGains(opt.scenario, g.k1, g.k2, opt.write_scenario, &err)
          : WriteEffectiveScenarioWithGains(opt, g.k1, g.k2, &err);
  if (!written) {
    std::cerr << "shoal design: --write-scenario: " << err << "\n";
    return false;
  }
  r->advice->scenario_written = opt.write_scenario;
  return true;
}

}  // namespace

int RunDesign(const DesignOptions& opt) {
  Scenario s;
  if (!LoadScenarioWithSetsOrReport("shoal design", opt.scenario, opt.set, &s)) return 2;
  const design::DesignRequest request = RequestOf(opt);
  std::string why;
  if (!request.IsValid(s, &why)) {
    std::cerr << "shoal design: " << why << "\n";
    return 2;
  }
  if (!opt.allow_large) {
    const std::string refusal = design::LargeDesignRefusal(s, request);
    if (!refusal.empty()) {
      std::cerr << "shoal design: " << opt.scenario << ": " << refusal << "\n";
      return 2;
    }
  }
  if (!CheckWritable("--certificate", opt.certificate) ||
      !CheckWritable("--write-scenario", opt.write_scenario)) {
    return 2;
  }
  design::DesignReport report = design::BuildDesignReport(s, request);
  const bool files_ok = WriteCertificateFile(opt.certificate, &report) &
                        WriteAdvisedScenario(opt, &report);
  if (opt.json) {
    std::cout << JsonText(design::DesignReportJson(report)) << "\n";
  } else {
    std::cout << design::DesignReportText(report);
  }
  if (!files_ok) return 2;
  return report.verdict.certified ? 0 : 1;
}

}  // namespace shoal
