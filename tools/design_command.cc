// `shoal design`: flags in, the design report (design/report.h) out, as text or JSON. The
// only work done here is file output: the Theorem 3 certificate and the advised scenario.
#include "tools/design_command.h"

#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <string>

#include "design/report.h"
#include "scenario/loader.h"
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
  if (!design::WriteScenarioWithGains(opt.scenario, g.k1, g.k2, opt.write_scenario, &err)) {
    std::cerr << "shoal design: --write-scenario: " << err << "\n";
    return false;
  }
  r->advice->scenario_written = opt.write_scenario;
  return true;
}

}  // namespace

int RunDesign(const DesignOptions& opt) {
  Scenario s;
  if (!LoadScenarioOrReport("shoal design", opt.scenario, &s)) return 2;
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
