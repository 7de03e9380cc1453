#include "tools/compare_command.h"

#include <lcm/lcm-cpp.hpp>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>
#include <utility>

#include <nlohmann/json.hpp>

#include "analysis/verdict.h"
#include "runtime/channels.h"
#include "runtime/lcm_bus.h"
#include "runtime/messages.h"
#include "tools/json_text.h"

namespace shoal {
namespace {

struct Sample {
  Vec5 eta, eta_dot;
};
using Key = std::pair<int, std::int64_t>;  // (vehicle id, utime)

/// Reads every SHOAL_STATE_<id> of a log. Returns false (with a message) if the file is
/// not an LCM log.
bool ReadStates(const std::string& path, std::map<Key, Sample>* out, std::string* err) {
  if (access(path.c_str(), R_OK) != 0) {
    *err = path + ": cannot read";
    return false;
  }
  lcm::LogFile log(path, "r");
  if (!log.good()) {
    *err = path + ": not an LCM log";
    return false;
  }
  std::int64_t events = 0;
  while (const lcm::LogEvent* ev = log.readNextEvent()) {
    ++events;
    if (!channels::ParseStateId(ev->channel)) continue;
    vehicle_state_t m{};
    if (!Decode(ev->data, ev->datalen, &m)) continue;
    (*out)[{m.vehicle_id, m.utime}] = Sample{Load5(m.eta), Load5(m.eta_dot)};
  }
  if (events == 0) {
    *err = path + ": empty or not an LCM log";
    return false;
  }
  return true;
}

}  // namespace

int RunCompare(const CompareOptions& opt) {
  if (!(opt.position_tol_m >= 0) || !(opt.velocity_tol_mps >= 0)) {
    std::cerr << "shoal compare: --position-tol-m and --velocity-tol-mps must be >= 0\n";
    return kExitBadInput;
  }
  std::map<Key, Sample> a, b;
  std::string err;
  if (!ReadStates(opt.a, &a, &err) || !ReadStates(opt.b, &b, &err)) {
    std::cerr << "shoal compare: " << err << "\n";
    return kExitBadInput;
  }
  double max_pos = 0.0, max_vel = 0.0;
  std::int64_t samples = 0;
  for (const auto& [key, sa] : a) {
    auto it = b.find(key);
    if (it == b.end()) continue;
    ++samples;
    max_pos = std::max(max_pos, (sa.eta.head<3>() - it->second.eta.head<3>()).norm());
    max_vel = std::max(max_vel, (sa.eta_dot - it->second.eta_dot).norm());
  }
  // NaN differences (a non-finite state on one side) are beyond any tolerance.
  const bool within = samples > 0 && max_pos <= opt.position_tol_m &&
                      max_vel <= opt.velocity_tol_mps;
  if (opt.json) {
    nlohmann::ordered_json j;
    j["max_position_diff_m"] = samples ? max_pos : NAN;
    j["max_velocity_diff_mps"] = samples ? max_vel : NAN;
    j["samples"] = samples;
    j["states_a"] = a.size();
    j["states_b"] = b.size();
    j["position_tol_m"] = opt.position_tol_m;
    j["velocity_tol_mps"] = opt.velocity_tol_mps;
    j["within_tolerance"] = within;
    std::cout << JsonText(j) << "\n";
  } else {
    std::printf("shoal compare: %lld matching vehicle states (of %zu and %zu)\n",
                static_cast<long long>(samples), a.size(), b.size());
    std::printf("  max position difference %.3e m, max velocity difference %.3e m/s\n",
                max_pos, max_vel);
    std::printf("  %s (tolerances %.3g m, %.3g m/s)\n",
                within ? "within tolerance"
                       : (samples ? "BEYOND TOLERANCE" : "NO matching states"),
                opt.position_tol_m, opt.velocity_tol_mps);
  }
  return within ? kExitOk : kExitFailed;
}

}  // namespace shoal
