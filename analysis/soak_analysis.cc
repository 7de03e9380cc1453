#include "analysis/soak_analysis.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>

#include "analysis/analysis.h"
#include "analysis/run_data.h"
#include "runtime/clock.h"

namespace shoal {
namespace {

constexpr double kMinuteS = 60.0;

/// A complete sample's worst follower (the definitions in soak_analysis.h).
struct Sample {
  double t_s = 0.0;
  double position_m = 0.0;
  bool within = false;
};

struct ResourceRow {
  double sim_s = 0.0, wall_s = 0.0;
  std::string process;
  int pid = 0;
  double rss_kib = 0.0, cpu_s = 0.0;
};

struct DelayError {
  double send_s = 0.0, due_s = 0.0, error_s = 0.0;  // due: send + configured delay
};

/// What the windows are measured from: the run, its analysis and the derived series.
struct SoakData {
  RunData run;
  RunAnalysis a;
  std::vector<Sample> samples;              // in time order
  std::vector<long long> overrun_increase;  // aligned with run.health
  /// Each delivered event's realised - configured delay, by send time.
  std::vector<DelayError> delay_errors;
  /// Each health report's start: its process's previous report (the first: a second
  /// before it), aligned with run.health.
  std::vector<double> health_from_s;
  double end_s = 0.0;                       // the run's expected end (last tick)
  std::map<std::string, std::vector<ResourceRow>> resources;  // per process, in time order
};

std::string Num(double v) {
  char b[48];
  std::snprintf(b, sizeof(b), "%.6g", v);
  return b;
}

/// Complete samples from the followers' errors (aligned with their tracks).
std::vector<Sample> CompleteSamples(const RunData& run, const RunAnalysis& a) {
  std::vector<Sample> out;
  if (!a.has_formation) return out;
  const MetricsConfig& tol = run.scenario.metrics;
  const int n = run.followers;
  std::vector<std::size_t> idx(n + 1, 0);
  for (const StateMsg& l : run.vehicles[0].samples) {
    if (l.utime < 0 || l.utime > a.bounds.limit_us) continue;
    Sample s{ToSeconds(l.utime), 0.0, true};
    bool complete = true;
    for (int i = 1; i <= n && complete; ++i) {
      const std::vector<StateMsg>& tr = run.vehicles[static_cast<std::size_t>(i)].samples;
      std::size_t& k = idx[i];
      while (k < tr.size() && tr[k].utime < l.utime) ++k;
      if (k == tr.size() || tr[k].utime != l.utime) {
        complete = false;
        break;
      }
      const FormationErrors& e = a.followers[static_cast<std::size_t>(i - 1)].errors[k];
      if (!(e.position_m <= s.position_m)) s.position_m = e.position_m;
      if (!(e.position_m <= tol.position_tol_m)) s.within = false;
    }
    if (complete) out.push_back(s);
  }
  return out;
}

/// Each health report's increase of its process's overrun count since the process's
/// previous report (a count that went down belongs to a restarted process: all of it).
std::vector<long long> OverrunIncreases(const std::vector<HealthRecord>& health) {
  std::vector<long long> out(health.size(), 0);
  std::map<int, std::int64_t> last;
  for (std::size_t k = 0; k < health.size(); ++k) {
    const HealthRecord& h = health[k];
    auto it = last.find(h.process_id);
    const std::int64_t before = it == last.end() ? 0 : it->second;
    out[k] = h.overruns >= before ? h.overruns - before : h.overruns;
    last[h.process_id] = h.overruns;
  }
  return out;
}

std::vector<std::string> SplitCsv(const std::string& line) {
  std::vector<std::string> f;
  std::stringstream ss(line);
  std::string cell;
  while (std::getline(ss, cell, ',')) f.push_back(cell);
  return f;
}

bool ReadResources(const std::string& path,
                   std::map<std::string, std::vector<ResourceRow>>* out, std::string* error) {
  std::ifstream in(path);
  std::string line;
  if (!in || !std::getline(in, line) ||
      line.rfind("sim_time_s,wall_time_s,process,pid,rss_kib,cpu_s", 0) != 0) {
    *error = path + ": cannot read the resource samples (no resources.csv header)";
    return false;
  }
  for (int n = 2; std::getline(in, line); ++n) {
    const std::vector<std::string> f = SplitCsv(line);
    // Eight columns; six in files written before the context switches were sampled.
    if (f.size() != 6 && f.size() != 8) {
      *error = path + ":" + std::to_string(n) + ": expected 8 columns";
      return false;
    }
    ResourceRow r;
    try {
      r = {std::stod(f[0]), std::stod(f[1]), f[2], std::stoi(f[3]), std::stod(f[4]),
           std::stod(f[5])};
    } catch (const std::exception&) {
      *error = path + ":" + std::to_string(n) + ": not a number where one is expected";
      return false;
    }
    (*out)[r.process].push_back(r);
  }
  for (auto& [name, rows] : *out) {
    std::stable_sort(rows.begin(), rows.end(),
                     [](const ResourceRow& a, const ResourceRow& b) { return a.sim_s < b.sim_s; });
  }
  return true;
}

/// The first sample at or after `t_s`, else the last one (null if none).
const ResourceRow* SampleAt(const std::vector<ResourceRow>& rows, double t_s) {
  for (const ResourceRow& r : rows) {
    if (r.sim_s >= t_s) return &r;
  }
  return rows.empty() ? nullptr : &rows.back();
}

/// Whether time t lies in [lo, hi), or at hi when hi is the run's end.
bool InWindow(double t, double lo, double hi, double end_s) {
  return t >= lo && (t < hi || (hi >= end_s && t <= end_s + 1e-9));
}

long long StatesIn(const SoakData& d, double lo, double hi) {
  long long k = 0;
  const Micros lo_us = static_cast<Micros>(std::floor(lo * 1e6));
  for (const VehicleTrack& v : d.run.vehicles) {
    auto it = std::lower_bound(v.samples.begin(), v.samples.end(), lo_us,
                               [](const StateMsg& m, Micros t) { return m.utime < t; });
    for (; it != v.samples.end() && it->utime <= d.a.bounds.limit_us; ++it) {
      const double t = ToSeconds(it->utime);
      if (!InWindow(t, lo, hi, d.end_s)) {
        if (t >= lo) break;
        continue;
      }
      ++k;
    }
  }
  return k;
}

std::vector<DelayError> DelayErrors(const RunData& run, const RunAnalysis& a) {
  std::vector<DelayError> out;
  const std::vector<ChannelEventRecord>& ev = run.channel_events;
  for (std::size_t k = 0; k < ev.size(); ++k) {
    const double cfg = a.channel.configured_delay_s[k];
    if (ev[k].status != 0 || std::isnan(cfg)) continue;
    const double send = ToSeconds(ev[k].send_utime);
    out.push_back({send, send + cfg, ToSeconds(ev[k].deliver_utime - ev[k].send_utime) - cfg});
  }
  std::stable_sort(out.begin(), out.end(),
                   [](const DelayError& x, const DelayError& y) { return x.send_s < y.send_s; });
  return out;
}

std::vector<double> HealthStarts(const std::vector<HealthRecord>& health) {
  std::vector<double> out(health.size(), 0.0);
  std::map<int, double> last;
  for (std::size_t k = 0; k < health.size(); ++k) {
    const double t = ToSeconds(health[k].utime);
    auto it = last.find(health[k].process_id);
    out[k] = it == last.end() ? t - 1.0 : it->second;
    last[health[k].process_id] = t;
  }
  return out;
}

long long ExpectedStatesIn(const SoakData& d, double lo, double hi) {
  const Micros p = d.a.period_us;
  if (p <= 0 || d.a.bounds.expected_end_us < 0) return 0;
  const Micros last = d.a.bounds.expected_end_us / p;  // last tick
  long long ticks = 0;
  for (Micros k = std::max<Micros>(0, static_cast<Micros>(std::floor(lo * 1e6 / p)) - 1);
       k <= last; ++k) {
    const double t = ToSeconds(k * p);
    if (t >= hi && !(hi >= d.end_s)) break;
    ticks += InWindow(t, lo, hi, d.end_s);
  }
  return ticks * (d.run.followers + 1);
}

/// The lateness samples of the health reports within a window, summed (definitions in
/// soak_analysis.h).
struct WindowLateness {
  std::array<std::int64_t, LatenessBins::kCount> bins{};
  std::int64_t count = 0;
  double max_s = 0.0;
  bool all_windowed = true;     // every report carried its window (health2_t)
  double since_start_p99 = 0.0;  // older logs: the largest since-start p99 reported

  void Add(const HealthRecord& h) {
    since_start_p99 = std::max(since_start_p99, h.lateness_p99_s);
    if (h.lateness_window_count < 0) {
      all_windowed = false;
      return;
    }
    for (const LatenessBinCount& b : h.lateness_window) bins[b.bin] += b.count;
    count += h.lateness_window_count;
    max_s = std::max(max_s, h.lateness_window_max_s);
  }
  double P99() const {
    if (!all_windowed) return since_start_p99;
    return LatenessBins::Quantile(bins.data(), count, max_s, 0.99);
  }
};

/// The figures of one window [lo, hi) that minutes and phases share.
struct Window {
  double lateness_p99_s = 0.0, release_error_p99_s = 0.0;
  long long overruns = 0;
  std::optional<double> delay_error_p99_s;
  long long states = 0, states_expected = 0;
};

Window Measure(const SoakData& d, double lo, double hi) {
  Window w;
  WindowLateness loop, release;
  for (std::size_t k = 0; k < d.run.health.size(); ++k) {
    const HealthRecord& h = d.run.health[k];
    if (!InWindow(ToSeconds(h.utime), lo, hi, d.end_s)) continue;
    (h.process_id >= 0 ? loop : release).Add(h);
    w.overruns += d.overrun_increase[k];
  }
  w.lateness_p99_s = loop.P99();
  w.release_error_p99_s = release.P99();
  std::vector<double> err;
  auto e = std::lower_bound(d.delay_errors.begin(), d.delay_errors.end(), lo,
                            [](const DelayError& x, double t) { return x.send_s < t; });
  for (; e != d.delay_errors.end() && InWindow(e->send_s, lo, hi, d.end_s); ++e) {
    err.push_back(e->error_s);
  }
  if (!err.empty()) w.delay_error_p99_s = QuantilesOf(&err).p99;
  w.states = StatesIn(d, lo, hi);
  w.states_expected = ExpectedStatesIn(d, lo, hi);
  return w;
}

std::vector<SoakProcessUse> ProcessesAtMinute(const SoakData& d, int m, int last_minute) {
  std::vector<SoakProcessUse> out;
  for (const auto& [name, rows] : d.resources) {
    const double end = m == last_minute ? 1e300 : (m + 1) * kMinuteS;
    const ResourceRow* now = SampleAt(rows, end);
    const ResourceRow* before = m == 0 ? &rows.front() : SampleAt(rows, m * kMinuteS);
    if (now == nullptr) continue;
    SoakProcessUse u{name, now->pid, now->rss_kib, std::nullopt};
    if (before != nullptr && before->pid == now->pid && now->wall_s > before->wall_s) {
      u.cpu_percent = 100.0 * (now->cpu_s - before->cpu_s) / (now->wall_s - before->wall_s);
    }
    out.push_back(u);
  }
  return out;
}

std::vector<SoakMinute> Minutes(const SoakData& d) {
  std::vector<SoakMinute> out;
  const int minutes = std::max(1, static_cast<int>(std::ceil(d.end_s / kMinuteS - 1e-9)));
  std::size_t s = 0;
  for (int m = 0; m < minutes; ++m) {
    SoakMinute row;
    row.minute = m;
    row.start_s = m * kMinuteS;
    row.end_s = std::min(d.end_s, (m + 1) * kMinuteS);
    const double hi = m == minutes - 1 ? d.end_s : row.end_s;
    for (; s < d.samples.size() && InWindow(d.samples[s].t_s, row.start_s, hi, d.end_s); ++s) {
      const double e = d.samples[s].position_m;
      if (!row.worst_position_error_m || !(e <= *row.worst_position_error_m)) {
        row.worst_position_error_m = e;
      }
    }
    const Window w = Measure(d, row.start_s, hi);
    row.lateness_p99_s = w.lateness_p99_s;
    row.release_error_p99_s = w.release_error_p99_s;
    row.overruns = w.overruns;
    row.delay_error_p99_s = w.delay_error_p99_s;
    row.states = w.states;
    row.states_expected = w.states_expected;
    row.processes = ProcessesAtMinute(d, m, minutes - 1);
    out.push_back(row);
  }
  return out;
}

nlohmann::ordered_json Opt(const std::optional<double>& v) {
  return v ? nlohmann::ordered_json(*v) : nlohmann::ordered_json();
}

/// The formation metrics of a phase; *why gets a sentence if it did not re-converge.
void PhaseFormation(const SoakData& d, const SoakPhase& p, double settle_s,
                    nlohmann::ordered_json* m, std::vector<std::string>* why) {
  const double from = p.start_s + settle_s;
  std::optional<double> final_error, max_error;
  double reconverged_at = kNaN;  // the first sample of the last stretch within tolerance
  const Sample* first_out = nullptr;
  long long judged = 0;
  for (const Sample& s : d.samples) {
    if (!InWindow(s.t_s, p.start_s, p.end_s, d.end_s)) continue;
    final_error = s.position_m;
    if (!s.within) reconverged_at = kNaN;
    if (s.within && std::isnan(reconverged_at)) reconverged_at = s.t_s;
    if (s.t_s < from) continue;
    ++judged;
    if (!max_error || !(s.position_m <= *max_error)) max_error = s.position_m;
    if (!s.within && first_out == nullptr) first_out = &s;
  }
  // A run that ended before the phase did (interrupted) did not run its window whole: what
  // it ran of it says nothing of the rest.
  const double period_s = d.run.has_scenario ? ToSeconds(d.run.scenario.period_us()) : 0.0;
  const bool cut_short = p.end_s > d.end_s + period_s + 1e-9;
  const bool ok = judged > 0 && first_out == nullptr && !cut_short;
  (*m)["reconverged"] = ok;
  (*m)["reconverged_at_s"] =
      std::isnan(reconverged_at) ? nlohmann::ordered_json() : nlohmann::ordered_json(reconverged_at);
  (*m)["final_position_error_m"] = Opt(final_error);
  (*m)["max_position_error_m"] = Opt(max_error);
  if (cut_short) {
    why->push_back("the run ended at " + Num(d.end_s) + " s, before the phase's end at " +
                   Num(p.end_s) + " s: the phase did not run whole");
  } else if (judged == 0) {
    why->push_back("no complete formation sample from " + Num(from) + " s (start + settle_s " +
                   Num(settle_s) + " s) to " + Num(p.end_s) + " s to judge re-convergence");
  } else if (first_out != nullptr) {
    const MetricsConfig& tol = d.run.scenario.metrics;
    why->push_back("did not re-converge: at " + Num(first_out->t_s) + " s, " +
                   Num(first_out->t_s - p.start_s) + " s into the phase (settle_s " +
                   Num(settle_s) + " s), the worst follower position error was " +
                   Num(first_out->position_m) + " m > metrics.position_tol_m " +
                   Num(tol.position_tol_m) + " m (at most " + Num(*max_error) +
                   " m after settling)");
  }
}

/// One criterion on a phase's metrics: "" if met, else why not.
std::string CheckCriterion(const SoakCriterion& c, const nlohmann::ordered_json& m) {
  if (!m.contains(c.metric)) return "criterion on " + c.metric + ": no such phase metric";
  const nlohmann::ordered_json& v = m[c.metric];
  if (!c.equals.is_null() && nlohmann::json(v) != c.equals) {
    return c.metric + " is " + v.dump() + ", not " + c.equals.dump();
  }
  if (!c.min && !c.max) return "";
  if (!v.is_number()) return c.metric + " is " + v.dump() + ": no number to bound";
  const double x = v.get<double>();
  if (c.min && !(x >= *c.min)) return c.metric + " " + Num(x) + " < min " + Num(*c.min);
  if (c.max && !(x <= *c.max)) return c.metric + " " + Num(x) + " > max " + Num(*c.max);
  return "";
}

/// How far back of a window its health reports reach when it has none: they come once a
/// second, each with the samples since the one before.
constexpr double kHealthReachS = 1.0;
/// The witness notices a stall at its next deadline: a stall it dates from a missed
/// deadline began up to its period (2 ms, launcher/machine_witness.h) before.
constexpr double kWitnessLeadS = 0.002;

/// One stall of the machine: the witness's threads (one per CPU) each see a stall of the
/// whole machine, so overlapping stalls are one. Its span is their union; what it can do
/// to a process is the longest one's (the union of stalls on different CPUs is longer
/// than what any process lost).
struct StallSpan {
  double start_s = 0.0, end_s = 0.0;
  double longest_s = 0.0, longest_start_s = 0.0;
};

std::vector<StallSpan> MergedStalls(const SoakInput& in) {
  std::vector<SoakStall> v;
  if (in.machine_watched) v = in.machine_stalls;
  std::sort(v.begin(), v.end(),
            [](const SoakStall& a, const SoakStall& b) { return a.start_s < b.start_s; });
  std::vector<StallSpan> out;
  for (const SoakStall& s : v) {
    const double end = s.start_s + s.length_s;
    if (out.empty() || s.start_s > out.back().end_s) {
      out.push_back({s.start_s, end, s.length_s, s.start_s});
      continue;
    }
    StallSpan& m = out.back();
    m.end_s = std::max(m.end_s, end);
    if (s.length_s > m.longest_s) {
      m.longest_s = s.length_s;
      m.longest_start_s = s.start_s;
    }
  }
  return out;
}

/// The spans overlapping [from_s, to_s] (a stall taken to begin kWitnessLeadS early): the
/// index of the first, and one past the last. Spans do not overlap, so their ends are in
/// order too.
std::pair<std::size_t, std::size_t> Overlapping(const std::vector<StallSpan>& spans,
                                                double from_s, double to_s) {
  auto first = std::upper_bound(spans.begin(), spans.end(), from_s,
                                [](double t, const StallSpan& s) { return t < s.end_s; });
  auto last = first;
  while (last != spans.end() && last->start_s - kWitnessLeadS <= to_s) ++last;
  return {static_cast<std::size_t>(first - spans.begin()),
          static_cast<std::size_t>(last - spans.begin())};
}

/// What one stall may still account for in one process: ticks, each late by at most
/// `latest_s` (twice the stall: it covers at least half of what a tick lost, as shoal
/// run's verdict asks). A stall that overlaps two of a process's reports gives its ticks
/// once, to the two together.
struct Allowance {
  double latest_s = 0.0;
  long long* left = nullptr;
};

/// Adds a report's lateness samples to `w`, less those beyond `target_s` that the
/// allowances account for: from the latest sample down, each taken from a stall that could
/// have made it that late. The number left out.
long long AddExcusing(const HealthRecord& h, std::vector<Allowance> allowances, double target_s,
                      WindowLateness* w) {
  if (h.lateness_window_count < 0 || allowances.empty()) {
    w->Add(h);
    return 0;
  }
  std::sort(allowances.begin(), allowances.end(),
            [](const Allowance& a, const Allowance& b) { return a.latest_s > b.latest_s; });
  HealthRecord kept = h;
  kept.lateness_window.clear();
  std::vector<long long*> pool;
  std::size_t next = 0;
  long long excused = 0;
  for (auto b = h.lateness_window.rbegin(); b != h.lateness_window.rend(); ++b) {
    // No sample of the bin is later than its upper edge, nor than the report's largest.
    const double latest = std::min(LatenessBins::UpperS(b->bin), h.lateness_window_max_s);
    while (next < allowances.size() && allowances[next].latest_s >= latest) {
      pool.push_back(allowances[next++].left);
    }
    // From the stall least able to make a sample late: the longer ones may still be
    // needed for later samples of the process's next report.
    long long take = 0;
    for (std::size_t k = pool.size(); k-- > 0 && latest > target_s && take < b->count;) {
      const long long t = std::min(*pool[k], b->count - take);
      *pool[k] -= t;
      take += t;
    }
    if (b->count > take) {
      kept.lateness_window.push_back({b->bin, static_cast<std::int32_t>(b->count - take)});
    }
    excused += take;
  }
  std::reverse(kept.lateness_window.begin(), kept.lateness_window.end());
  kept.lateness_window_count -= excused;
  w->Add(kept);
  return excused;
}

/// A phase's timing figures without what the machine's stalls account for (definitions
/// in soak_analysis.h), and the stalls within its reach.
struct MachineAccount {
  bool accounted = false;  // the figures below were measured
  long long stall_count = 0;
  const StallSpan* worst = nullptr;
  long long late_ticks = 0, overruns = 0, late_releases = 0, delay_errors = 0;  // excused
  double lateness_p99_s = 0.0, release_error_p99_s = 0.0;
  long long overruns_left = 0;
  std::optional<double> delay_error_p99_s;
  double reach_s = 0.0;      // the earliest time the phase's reports cover
  double reach_end_s = 0.0;  // the latest: its end, or an accounted delivery's arrival
};

/// Per process and stall, what the stall may still account for: late ticks (or late
/// releases) and overruns.
using Allowances = std::map<std::pair<int, std::size_t>, std::array<long long, 2>>;

void AccountReport(const SoakData& d, const std::vector<StallSpan>& spans, const SoakTargets& t,
                   std::size_t k, Allowances* left, WindowLateness* loop,
                   WindowLateness* release, MachineAccount* m) {
  const HealthRecord& h = d.run.health[k];
  const double period_s = ToSeconds(d.a.period_us);
  const double to = ToSeconds(h.utime), from = d.health_from_s[k];
  const bool emulator = h.process_id < 0;
  // A loop: the tick due just before the stall, still waiting for a CPU, and those due
  // during it. The emulator: the releases due during it, at the report's own rate.
  const double rate = std::max<double>(0.0, h.lateness_window_count) / std::max(1e-3, to - from);
  const double target = emulator ? t.delay_error_p99_max_s : t.lateness_p99_max_s;
  std::vector<Allowance> late;
  long long overruns = d.overrun_increase[k];
  const auto [first, last] = Overlapping(spans, from, to);
  for (std::size_t s = first; s < last; ++s) {
    const double len = spans[s].longest_s;
    auto [it, fresh] = left->try_emplace({h.process_id, s});
    if (fresh) {
      const long long ticks =
          emulator ? static_cast<long long>(std::ceil((len + kWitnessLeadS) * rate))
                   : static_cast<long long>(std::ceil(len / period_s - 1e-9)) + 1;
      it->second = {len >= 0.5 * target ? ticks : 0,
                    !emulator && len >= 0.5 * period_s ? ticks : 0};
    }
    late.push_back({2.0 * len, &it->second[0]});
    const long long excused = std::min(overruns, it->second[1]);
    it->second[1] -= excused;
    overruns -= excused;
    m->overruns += excused;
  }
  m->overruns_left += overruns;
  const long long excused = AddExcusing(h, late, target, emulator ? release : loop);
  (emulator ? m->late_releases : m->late_ticks) += excused;
}

/// `left` is the whole run's: a stall across two phases gives its ticks once.
void AccountLoops(const SoakData& d, const std::vector<StallSpan>& spans, const SoakTargets& t,
                  double lo, double hi, Allowances* left, MachineAccount* m) {
  m->reach_s = lo - kHealthReachS;
  if (!(d.a.period_us > 0)) return;
  WindowLateness loop, release;
  for (std::size_t k = 0; k < d.run.health.size(); ++k) {
    if (!InWindow(ToSeconds(d.run.health[k].utime), lo, hi, d.end_s)) continue;
    m->reach_s = std::min(m->reach_s, d.health_from_s[k]);
    AccountReport(d, spans, t, k, left, &loop, &release, m);
  }
  m->lateness_p99_s = loop.P99();
  m->release_error_p99_s = release.P99();
  m->accounted = true;
}

/// Delivered messages late beyond the target whose lateness (from their due time on) one
/// stall covers at least half of.
void AccountDeliveries(const SoakData& d, const std::vector<StallSpan>& spans, double target_s,
                       double lo, double hi, MachineAccount* m) {
  std::vector<double> err;
  auto e = std::lower_bound(d.delay_errors.begin(), d.delay_errors.end(), lo,
                            [](const DelayError& x, double t) { return x.send_s < t; });
  for (; e != d.delay_errors.end() && InWindow(e->send_s, lo, hi, d.end_s); ++e) {
    bool excused = false;
    if (e->error_s > target_s) {
      const double a = e->due_s, b = e->due_s + e->error_s;
      const auto [first, last] = Overlapping(spans, a, b);
      for (std::size_t s = first; s < last && !excused; ++s) {
        const double from = spans[s].longest_start_s - kWitnessLeadS;
        const double covered = std::min(b, from + spans[s].longest_s + kWitnessLeadS) -
                               std::max(a, from);
        excused = covered >= 0.5 * e->error_s;
      }
    }
    if (excused) {
      ++m->delay_errors;
      m->reach_end_s = std::max(m->reach_end_s, e->due_s + e->error_s);
    } else {
      err.push_back(e->error_s);
    }
  }
  if (!err.empty()) m->delay_error_p99_s = QuantilesOf(&err).p99;
}

/// The stalls the witness saw over the run, and what each may still account for.
struct MachineRecord {
  std::vector<StallSpan> spans;
  Allowances left;
};

MachineAccount AccountForStalls(const SoakData& d, MachineRecord* rec, const SoakTargets& t,
                                double lo, double hi) {
  MachineAccount m;
  m.reach_end_s = hi;
  AccountLoops(d, rec->spans, t, lo, hi, &rec->left, &m);
  AccountDeliveries(d, rec->spans, t.delay_error_p99_max_s, lo, hi, &m);
  const std::vector<StallSpan>& spans = rec->spans;
  const auto [first, last] = Overlapping(spans, m.reach_s, m.reach_end_s);
  for (std::size_t s = first; s < last; ++s) {
    ++m.stall_count;
    if (m.worst == nullptr || spans[s].longest_s > m.worst->longest_s) m.worst = &spans[s];
  }
  return m;
}

nlohmann::ordered_json MachineJson(const MachineAccount& m, bool complete) {
  nlohmann::ordered_json j;
  j["complete"] = complete;
  j["stall_count"] = m.stall_count;
  j["worst_stall_s"] = m.worst ? nlohmann::ordered_json(m.worst->longest_s) : nlohmann::ordered_json();
  j["worst_stall_at_s"] =
      m.worst ? nlohmann::ordered_json(m.worst->longest_start_s) : nlohmann::ordered_json();
  j["late_ticks_accounted"] = m.late_ticks;
  j["overruns_accounted"] = m.overruns;
  j["late_releases_accounted"] = m.late_releases;
  j["delay_errors_accounted"] = m.delay_errors;
  return j;
}

/// Every timing target met once what the machine accounts for is left out.
bool MetWithout(const SoakTargets& t, const MachineAccount& m) {
  return m.accounted && m.overruns_left <= t.overruns_max &&
         !(m.lateness_p99_s > t.lateness_p99_max_s) &&
         !(m.release_error_p99_s > t.delay_error_p99_max_s) &&
         !(m.delay_error_p99_s && *m.delay_error_p99_s > t.delay_error_p99_max_s);
}

/// Real time: a phase's loop and channel timing against the targets. Each sentence says so
/// when the machine's stalls account for every miss (*machine_limited).
void PhaseTargets(const SoakTargets& t, const Window& w, const MachineAccount* m,
                  std::vector<std::string>* why, bool* machine_limited) {
  const std::size_t before = why->size();
  if (w.overruns > t.overruns_max) {
    why->push_back(std::to_string(w.overruns) + " control ticks overran their period" +
                   (t.overruns_max > 0 ? " (at most " + std::to_string(t.overruns_max) + ")"
                                       : std::string()));
  }
  if (w.lateness_p99_s > t.lateness_p99_max_s) {
    why->push_back("loop lateness p99 " + Num(w.lateness_p99_s * 1e3) + " ms > target " +
                   Num(t.lateness_p99_max_s * 1e3) + " ms");
  }
  if (w.release_error_p99_s > t.delay_error_p99_max_s) {
    why->push_back("channel release error p99 " + Num(w.release_error_p99_s * 1e3) +
                   " ms > target " + Num(t.delay_error_p99_max_s * 1e3) + " ms");
  }
  if (w.delay_error_p99_s && *w.delay_error_p99_s > t.delay_error_p99_max_s) {
    why->push_back("channel delay error p99 " + Num(*w.delay_error_p99_s * 1e3) +
                   " ms > target " + Num(t.delay_error_p99_max_s * 1e3) + " ms");
  }
  *machine_limited = why->size() > before && m != nullptr && m->worst != nullptr &&
                     MetWithout(t, *m);
  if (!*machine_limited) return;
  const std::string text = "; the machine itself stalled " + std::to_string(m->stall_count) +
                           " time(s) within the phase's reach (worst " +
                           Num(m->worst->longest_s * 1e3) + " ms, at t = " +
                           Num(m->worst->longest_start_s) + " s), which accounts for it";
  for (std::size_t k = before; k < why->size(); ++k) (*why)[k] += text;
}

/// `*other_why`: the phase's sentences the machine does not account for.
SoakPhaseResult JudgePhase(const SoakData& d, const SoakInput& in, MachineRecord* machine,
                           int index, std::size_t* other_why) {
  SoakPhaseResult r;
  r.index = index;
  r.phase = in.phases[static_cast<std::size_t>(index)];
  PhaseFormation(d, r.phase, in.settle_s, &r.metrics, &r.why);
  const Window w = Measure(d, r.phase.start_s, r.phase.end_s);
  r.metrics["delay_error_p99_s"] = Opt(w.delay_error_p99_s);
  r.metrics["release_error_p99_s"] = w.release_error_p99_s;
  r.metrics["lateness_p99_s"] = w.lateness_p99_s;
  r.metrics["overruns"] = w.overruns;
  r.metrics["states"] = w.states;
  r.metrics["states_expected"] = w.states_expected;
  std::size_t timing_why = 0;  // sentences that the machine accounts for
  if (in.engine == "realtime") {
    std::optional<MachineAccount> m;
    if (in.machine_watched) {
      m = AccountForStalls(d, machine, in.targets, r.phase.start_s, r.phase.end_s);
      r.machine = MachineJson(*m, r.phase.end_s <= in.machine_complete_until_s);
    }
    const std::size_t before = r.why.size();
    PhaseTargets(in.targets, w, m ? &*m : nullptr, &r.why, &r.timing_machine_limited);
    if (r.timing_machine_limited) timing_why = r.why.size() - before;
  }
  for (const SoakCriterion& c : in.criteria) {
    const std::string miss = CheckCriterion(c, r.metrics);
    if (!miss.empty()) r.why.push_back(miss);
  }
  r.pass = r.why.empty();
  *other_why = r.why.size() - timing_why;
  return r;
}

std::string PhaseName(const SoakPhaseResult& p) {
  return "phase " + std::to_string(p.index + 1) + " (" + p.phase.label + ", " +
         Num(p.phase.start_s) + "-" + Num(p.phase.end_s) + " s)";
}

/// The run report's faults: failed or stopped processes, restarts, interruption, lost
/// states.
void JudgeReport(const nlohmann::json& j, std::vector<std::string>* reasons) {
  if (!j.value("all_processes_ok", false)) {
    std::string text = "a process failed or the run was interrupted";
    for (const auto& p : j.value("problems", nlohmann::json::array())) {
      text += "; " + p.get<std::string>();
    }
    if (j.value("interrupted", false)) text += "; the run was interrupted";
    reasons->push_back(text);
  }
  for (const auto& r : j.value("restarts", nlohmann::json::array())) {
    reasons->push_back(r.value("process", std::string("a process")) + " (pid " +
                       std::to_string(r.value("pid", 0)) + ") " +
                       r.value("reason", std::string("died")) + " at t = " +
                       Num(r.value("mission_s", 0.0)) + " s and was restarted as pid " +
                       std::to_string(r.value("new_pid", 0)));
  }
  if (!j.value("log_complete", false)) {
    // An interrupted run is already a reason above; what it never ran was not lost.
    std::string text = (j.value("interrupted", false) ? "the log is not the whole run: "
                                                      : "the log lost states: ") +
                       std::to_string(j.value("log_states", 0LL)) + " of " +
                       std::to_string(j.value("log_states_expected", 0LL)) +
                       " expected vehicle states recorded";
    for (const auto& p : j.value("log_problems", nlohmann::json::array())) {
      text += "; " + p.get<std::string>();
    }
    reasons->push_back(text);
  }
}

std::vector<SoakProcessGrowth> Growth(const SoakData& d, const SoakInput& in,
                                      std::vector<std::string>* reasons) {
  std::vector<SoakProcessGrowth> out;
  // The reference: the end of the first phase; with one phase, the end of its settle time
  // (what comes before is start-up, not growth).
  const double first_end = in.phases.size() > 1
                               ? in.phases.front().end_s
                               : in.phases.front().start_s + in.settle_s;
  for (const auto& [name, rows] : d.resources) {
    const ResourceRow* at = SampleAt(rows, first_end);
    if (at == nullptr || at->rss_kib <= 0) continue;
    SoakProcessGrowth g{name, at->rss_kib, at->rss_kib, 0.0};
    for (const ResourceRow& r : rows) {
      if (r.sim_s >= at->sim_s) g.rss_max_after_kib = std::max(g.rss_max_after_kib, r.rss_kib);
    }
    g.growth = g.rss_max_after_kib / g.rss_first_phase_kib - 1.0;
    if (g.growth > in.targets.memory_growth_max) {
      reasons->push_back(name + ": RSS grew " + Num(g.growth * 100) +
                         " % after the first phase (from " + Num(g.rss_first_phase_kib) +
                         " KiB at t = " + Num(at->sim_s) + " s to " + Num(g.rss_max_after_kib) +
                         " KiB), more than memory_growth_max " +
                         Num(in.targets.memory_growth_max * 100) + " %");
    }
    out.push_back(g);
  }
  if (out.empty()) {
    reasons->push_back("memory growth not measured: no process has a resource sample at or "
                       "after t = " + Num(first_end) + " s (resources.csv)");
  }
  return out;
}

bool LoadSoakData(const SoakInput& in, SoakData* d, std::string* error) {
  LoadOptions opt;
  opt.key_file = in.key_file;
  if (!LoadRunLog(in.log, opt, &d->run, error)) return false;
  if (!d->run.has_scenario) {
    *error = in.log + ": the log holds no scenario: the formation cannot be judged";
    return false;
  }
  d->a = AnalyseRun(d->run);
  // The run ends with its last phase: a real-time log has no final clock tick to say so,
  // and its scenario's own duration is not the soak's (shoal soak sets --duration).
  const Micros period = d->run.scenario.period_us();
  if (!in.phases.empty() && period > 0) {
    const Micros last = static_cast<Micros>(std::llround(in.phases.back().end_s * 1e6)) / period;
    Micros& end = d->a.bounds.expected_end_us;
    if (end < 0 || end > last * period) end = last * period;
  }
  d->samples = CompleteSamples(d->run, d->a);
  d->overrun_increase = OverrunIncreases(d->run.health);
  d->delay_errors = DelayErrors(d->run, d->a);
  d->health_from_s = HealthStarts(d->run.health);
  d->end_s = d->a.bounds.expected_end_us >= 0 ? ToSeconds(d->a.bounds.expected_end_us) : 0.0;
  return in.resources_csv.empty() || ReadResources(in.resources_csv, &d->resources, error);
}

bool CheckPhases(const std::vector<SoakPhase>& phases, std::string* error) {
  if (phases.empty()) {
    *error = "a soak run needs at least one phase";
    return false;
  }
  for (std::size_t k = 0; k < phases.size(); ++k) {
    const bool ordered = k == 0 || phases[k].start_s >= phases[k - 1].end_s;
    if (!(phases[k].end_s > phases[k].start_s) || !ordered) {
      *error = "phase " + std::to_string(k + 1) + " (" + phases[k].label +
               "): its window must be non-empty and after the previous phase's";
      return false;
    }
  }
  return true;
}

}  // namespace

bool ParseSoakCriteria(const nlohmann::json& pass, std::vector<SoakCriterion>* out,
                       std::string* error) {
  out->clear();
  if (pass.is_null()) return true;
  if (!pass.is_object()) {
    *error = "pass criteria: expected a table of metric = value or { min, max }";
    return false;
  }
  for (const auto& [key, v] : pass.items()) {
    SoakCriterion c;
    c.metric = key;
    if (v.is_object()) {
      for (const auto& [bound, x] : v.items()) {
        if ((bound != "min" && bound != "max") || !x.is_number()) {
          *error = "pass criterion " + key + ": only min and max, numbers (got " + bound + ")";
          return false;
        }
        (bound == "min" ? c.min : c.max) = x.get<double>();
      }
    } else {
      c.equals = v;
    }
    out->push_back(c);
  }
  return true;
}

bool AnalyseSoak(const SoakInput& in, SoakResult* out, std::string* error) {
  *out = SoakResult();
  if (!CheckPhases(in.phases, error)) return false;
  SoakData d;
  if (!LoadSoakData(in, &d, error)) return false;
  JudgeReport(in.report, &out->reasons);
  out->minutes = Minutes(d);
  for (const SoakMinute& m : out->minutes) {
    if (m.states < m.states_expected) {
      out->reasons.push_back("minute " + std::to_string(m.minute) + " (" + Num(m.start_s) + "-" +
                             Num(m.end_s) + " s): " + std::to_string(m.states) + " of " +
                             std::to_string(m.states_expected) + " vehicle states logged");
    }
  }
  if (!d.resources.empty()) {
    out->processes = Growth(d, in, &out->reasons);
  } else {
    out->reasons.push_back("memory growth not measured: no resource samples (" +
                           (in.resources_csv.empty() ? std::string("none given")
                                                     : in.resources_csv) + ")");
  }
  const std::size_t other_reasons = out->reasons.size();
  std::size_t not_machine = 0;  // phase sentences the machine does not account for
  MachineRecord machine{MergedStalls(in), {}};
  for (int k = 0; k < static_cast<int>(in.phases.size()); ++k) {
    std::size_t other = 0;
    out->phases.push_back(JudgePhase(d, in, &machine, k, &other));
    not_machine += other;
    const SoakPhaseResult& p = out->phases.back();
    for (const std::string& w : p.why) out->reasons.push_back(PhaseName(p) + ": " + w);
  }
  out->pass = out->reasons.empty();
  out->timing_machine_limited = !out->pass && other_reasons == 0 && not_machine == 0;
  return true;
}

nlohmann::ordered_json SoakJson(const SoakResult& r) {
  nlohmann::ordered_json j;
  j["verdict"] = r.pass ? "pass" : "fail";
  j["timing_machine_limited"] = r.timing_machine_limited;
  j["reasons"] = r.reasons;
  j["phases"] = nlohmann::ordered_json::array();
  for (const SoakPhaseResult& p : r.phases) {
    j["phases"].push_back({{"index", p.index}, {"value", p.phase.label},
                           {"start_s", p.phase.start_s}, {"end_s", p.phase.end_s},
                           {"metrics", p.metrics}, {"pass", p.pass}, {"why", p.why},
                           {"machine", p.machine},
                           {"timing_machine_limited", p.timing_machine_limited}});
  }
  j["minutes"] = nlohmann::ordered_json::array();
  for (const SoakMinute& m : r.minutes) {
    nlohmann::ordered_json procs = nlohmann::ordered_json::array();
    for (const SoakProcessUse& u : m.processes) {
      procs.push_back({{"name", u.name}, {"pid", u.pid}, {"rss_kib", u.rss_kib},
                       {"cpu_percent", Opt(u.cpu_percent)}});
    }
    j["minutes"].push_back(
        {{"minute", m.minute}, {"start_s", m.start_s}, {"end_s", m.end_s},
         {"worst_position_error_m", Opt(m.worst_position_error_m)},
         {"lateness_p99_s", m.lateness_p99_s}, {"release_error_p99_s", m.release_error_p99_s},
         {"overruns", m.overruns}, {"delay_error_p99_s", Opt(m.delay_error_p99_s)},
         {"states", m.states}, {"states_expected", m.states_expected}, {"processes", procs}});
  }
  j["processes"] = nlohmann::ordered_json::array();
  for (const SoakProcessGrowth& g : r.processes) {
    j["processes"].push_back({{"name", g.name}, {"rss_first_phase_kib", g.rss_first_phase_kib},
                              {"rss_max_after_kib", g.rss_max_after_kib}, {"growth", g.growth}});
  }
  return j;
}

}  // namespace shoal
