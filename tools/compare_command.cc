#include "tools/compare_command.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <limits>
#include <map>
#include <optional>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "analysis/run_data.h"
#include "analysis/verdict.h"
#include "runtime/channels.h"
#include "runtime/lcm_bus.h"
#include "runtime/log_reader.h"
#include "runtime/messages.h"
#include "tools/json_text.h"

namespace shoal {
namespace {

struct Sample {
  Vec5 eta, eta_dot;
};
using Key = std::pair<int, std::int64_t>;  // (vehicle id, utime)
using States = std::map<Key, Sample>;

/// What ReadStates left out or could not check, one warning each.
void WarnStates(const std::string& path, const std::string& used, const RunData& counts,
                std::int64_t repeated, std::int64_t conflicting, std::int64_t undecodable,
                std::int64_t inconsistent, std::vector<std::string>* warnings) {
  if (repeated > 0) {
    warnings->push_back(path + ": " + std::to_string(repeated) +
                        " vehicle states appear more than once (same vehicle and time: a log "
                        "recorded twice or concatenated, or replayed onto a recording bus), " +
                        std::to_string(conflicting) + " of them with different values; the "
                        "last copy of each is compared");
  }
  if (undecodable + inconsistent > 0) {
    warnings->push_back(path + ": " + std::to_string(undecodable) +
                        " vehicle states do not decode and " + std::to_string(inconsistent) +
                        " name another vehicle than their channel's: damaged, not compared");
  }
  if (counts.unauthenticated > 0) {
    warnings->push_back(path + ": " + std::to_string(counts.unauthenticated) +
                        " states did not authenticate with " + used + " and were ignored");
  }
  if (counts.unverified > 0) {
    warnings->push_back(path + ": " + std::to_string(counts.unverified) +
                        " states were read unverified (no key file)");
  }
}

/// Reads every SHOAL_STATE_<id> of a log with the project's log reader, so that a damaged
/// or truncated log is read up to the damage and said to be so (the reader's warnings,
/// which name the file). False, with a message, if the file cannot be read, is empty, or holds
/// no complete LCM event.
bool ReadStates(const std::string& path, const std::string& key_file, States* out,
                std::vector<std::string>* warnings, std::string* err) {
  std::optional<bus_auth::Key> key;
  std::string used;
  if (!KeyForLog(path, key_file, &key, &used, err)) return false;
  LcmLogReader reader;
  if (!reader.Open(path, err)) return false;
  RunData counts;  // authentication counts only
  LogVerifier verifier(key, &counts);
  LogEventView ev;
  std::int64_t repeated = 0, conflicting = 0, undecodable = 0, inconsistent = 0;
  while (reader.Next(&ev)) {
    const std::optional<int> id = channels::ParseStateId(ev.channel);
    if (!id) continue;
    const int size = verifier.Check(ev.channel, ev.data, ev.size);
    if (size < 0) continue;  // counted by the verifier
    vehicle_state_t m{};
    if (!Decode(ev.data, size, &m)) {
      ++undecodable;
      continue;
    }
    if (m.vehicle_id != *id) {  // another vehicle's state on this one's channel
      ++inconsistent;
      continue;
    }
    const Sample s{Load5(m.eta), Load5(m.eta_dot)};
    // The last copy of a state wins, as in shoal analyze; a copy that differs is two runs'
    // (or a damaged) state under one name, which the user must hear of.
    const auto [it, inserted] = out->try_emplace({m.vehicle_id, m.utime}, s);
    if (inserted) continue;
    ++repeated;
    if (std::memcmp(&it->second, &s, sizeof s) != 0) ++conflicting;
    it->second = s;
  }
  warnings->insert(warnings->end(), reader.warnings().begin(), reader.warnings().end());
  WarnStates(path, used, counts, repeated, conflicting, undecodable, inconsistent, warnings);
  if (reader.events() == 0) {
    *err = path + ": no complete LCM event in the file" +
           (reader.warnings().empty() ? std::string() : " (" + reader.warnings().front() + ")");
    return false;
  }
  // A key that verifies none of the states is the wrong key (as shoal analyze says), not
  // a log without states: bad input, not a comparison that failed. So is a log with no
  // state at all: there is nothing of a run in it to compare.
  if (out->empty() && counts.unauthenticated > 0) {
    *err = path + ": none of its " + std::to_string(counts.unauthenticated) +
           " states authenticates with " + used +
           " (the log of another run, or of a run with --insecure?)";
    return false;
  }
  if (out->empty() && undecodable + inconsistent > 0) {
    *err = path + ": none of its " + std::to_string(undecodable + inconsistent) +
           " vehicle states is whole (they do not decode, or name another vehicle)";
    return false;
  }
  if (out->empty()) {
    *err = path + ": no vehicle state (SHOAL_STATE_<id>) in its " +
           std::to_string(reader.events()) + " events: not the log of a Shoal run";
    return false;
  }
  return true;
}

struct Comparison {
  std::int64_t samples = 0;     // states held by both logs
  std::int64_t only_in_a = 0, only_in_b = 0;
  std::int64_t non_finite = 0;  // matching states whose difference is NaN or infinite
  // Largest finite differences; NaN when no matching state has one.
  double max_pos = std::numeric_limits<double>::quiet_NaN();
  double max_vel = std::numeric_limits<double>::quiet_NaN();
  bool within_tolerance = false;  // samples, every difference finite and within tolerance
  bool complete = false;          // no state in only one log
  bool passed = false;            // the verdict: exit 0
};

/// Largest of `m` (NaN: none yet) and a finite `d`.
double Max(double m, double d) { return std::isnan(m) ? d : std::max(m, d); }

Comparison Compare(const States& a, const States& b, const CompareOptions& opt) {
  Comparison c;
  for (const auto& [key, sa] : a) {
    const auto it = b.find(key);
    if (it == b.end()) continue;
    ++c.samples;
    const double dp = (sa.eta.head<3>() - it->second.eta.head<3>()).norm();
    const double dv = (sa.eta_dot - it->second.eta_dot).norm();
    // std::max would let a NaN through unseen; a non-finite difference is a failure of
    // its own, counted apart from the finite ones.
    if (!std::isfinite(dp) || !std::isfinite(dv)) {
      ++c.non_finite;
      continue;
    }
    c.max_pos = Max(c.max_pos, dp);
    c.max_vel = Max(c.max_vel, dv);
  }
  c.only_in_a = static_cast<std::int64_t>(a.size()) - c.samples;
  c.only_in_b = static_cast<std::int64_t>(b.size()) - c.samples;
  // With samples and none non-finite, the maxima are finite numbers.
  c.within_tolerance = c.samples > 0 && c.non_finite == 0 && c.max_pos <= opt.position_tol_m &&
                       c.max_vel <= opt.velocity_tol_mps;
  c.complete = c.only_in_a == 0 && c.only_in_b == 0;
  c.passed = c.within_tolerance && (c.complete || opt.allow_missing);
  return c;
}

void PrintJson(const Comparison& c, std::size_t states_a, std::size_t states_b,
               const std::vector<std::string>& warnings, const CompareOptions& opt) {
  nlohmann::ordered_json j;
  j["max_position_diff_m"] = c.max_pos;  // NaN is written as null
  j["max_velocity_diff_mps"] = c.max_vel;
  j["samples"] = c.samples;
  j["states_a"] = states_a;
  j["states_b"] = states_b;
  j["only_in_a"] = c.only_in_a;
  j["only_in_b"] = c.only_in_b;
  j["non_finite_diffs"] = c.non_finite;
  j["position_tol_m"] = opt.position_tol_m;
  j["velocity_tol_mps"] = opt.velocity_tol_mps;
  j["allow_missing"] = opt.allow_missing;
  j["within_tolerance"] = c.within_tolerance;
  j["complete"] = c.complete;
  j["passed"] = c.passed;
  j["warnings"] = warnings;
  std::cout << JsonText(j) << "\n";
}

void PrintText(const Comparison& c, std::size_t states_a, std::size_t states_b,
               const CompareOptions& opt) {
  std::printf("shoal compare: %lld matching vehicle states (of %zu and %zu); "
              "%lld only in A, %lld only in B\n",
              static_cast<long long>(c.samples), states_a, states_b,
              static_cast<long long>(c.only_in_a), static_cast<long long>(c.only_in_b));
  if (c.samples > c.non_finite) {
    std::printf("  max position difference %.3e m, max velocity difference %.3e m/s\n",
                c.max_pos, c.max_vel);
  }
  if (c.non_finite > 0) {
    std::printf("  %lld matching states differ by a non-finite amount (NaN or Inf)\n",
                static_cast<long long>(c.non_finite));
  }
  if (c.samples == 0) {
    std::printf("  NO matching states\n");
  } else {
    std::printf("  %s (tolerances %.3g m, %.3g m/s)\n",
                c.within_tolerance ? "within tolerance" : "BEYOND TOLERANCE",
                opt.position_tol_m, opt.velocity_tol_mps);
  }
  if (!c.complete) {
    std::printf(opt.allow_missing
                    ? "  states only in one log ignored (--allow-missing)\n"
                    : "  INCOMPLETE: states only in one log fail the comparison "
                      "(--allow-missing compares only the states both logs hold)\n");
  }
}

}  // namespace

int RunCompare(const CompareOptions& opt) {
  if (!(opt.position_tol_m >= 0) || !(opt.velocity_tol_mps >= 0)) {
    std::cerr << "shoal compare: --position-tol-m and --velocity-tol-mps must be >= 0\n";
    return kExitBadInput;
  }
  States a, b;
  std::vector<std::string> warnings;
  std::string err;
  if (!ReadStates(opt.a, opt.key_a, &a, &warnings, &err) ||
      !ReadStates(opt.b, opt.key_b, &b, &warnings, &err)) {
    std::cerr << "shoal compare: " << err << "\n";
    return kExitBadInput;
  }
  for (const std::string& w : warnings) std::cerr << "shoal compare: warning: " << w << "\n";
  const Comparison c = Compare(a, b, opt);
  if (opt.json) {
    PrintJson(c, a.size(), b.size(), warnings, opt);
  } else {
    PrintText(c, a.size(), b.size(), opt);
  }
  return c.passed ? kExitOk : kExitFailed;
}

}  // namespace shoal
