#include "tools/compare_command.h"

#include <lcm/lcm-cpp.hpp>
#include <unistd.h>

#include <cstdio>
#include <iostream>
#include <map>
#include <utility>

#include "runtime/lcm_bus.h"
#include "runtime/messages.h"
#include "tools/json.h"

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
    if (ev->channel.rfind("SHOAL_STATE_", 0) != 0) continue;
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
  std::map<Key, Sample> a, b;
  std::string err;
  if (!ReadStates(opt.a, &a, &err) || !ReadStates(opt.b, &b, &err)) {
    std::cerr << "shoal compare: " << err << "\n";
    return 2;
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
  if (opt.json) {
    JsonWriter j;
    j.Num("max_position_diff_m", samples ? max_pos : NAN)
        .Num("max_velocity_diff_mps", samples ? max_vel : NAN)
        .Int("samples", samples)
        .Int("states_a", static_cast<long long>(a.size()))
        .Int("states_b", static_cast<long long>(b.size()));
    std::cout << j.Done() << "\n";
  } else {
    std::printf("shoal compare: %lld matching vehicle states (of %zu and %zu)\n",
                static_cast<long long>(samples), a.size(), b.size());
    std::printf("  max position difference %.3e m, max velocity difference %.3e m/s\n",
                max_pos, max_vel);
  }
  return samples > 0 ? 0 : 1;
}

}  // namespace shoal
