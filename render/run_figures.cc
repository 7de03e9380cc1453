#include "render/run_figures.h"

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <set>
#include <utility>

#include "core/channel_model.h"
#include "core/timeline.h"
#include "core/topology.h"
#include "render/figure.h"

namespace shoal::render {
namespace {

bool Finite(const FormationErrors& e) {
  return std::isfinite(e.position_m) && std::isfinite(e.velocity_mps) &&
         std::isfinite(e.attitude_rad);
}

// Most topology segments drawn in each formation snapshot: beyond this a dense swarm's
// snapshot is a solid blot (400 densely linked followers: 80,000 pairs, six times over,
// took most of a 20 s render), so the snapshots then show the vehicles only.
constexpr std::size_t kMaxSnapshotEdges = 2000;

// Snapshot segments along the topology's links (each unordered pair once, in first-seen
// order); none when there are more than kMaxSnapshotEdges.
std::vector<std::pair<int, int>> SnapshotEdges(const RunData& run) {
  std::vector<std::pair<int, int>> edges;
  if (!run.has_scenario) return edges;
  const Topology topo =
      Topology::Build(run.scenario.followers, run.scenario.edges, run.scenario.leader_links);
  std::set<std::pair<int, int>> seen;
  for (const auto& [from, to] : topo.Links()) {
    const auto e = std::make_pair(std::min(from, to), std::max(from, to));
    if (seen.insert(e).second) edges.push_back(e);
    if (edges.size() > kMaxSnapshotEdges) return {};
  }
  return edges;
}

template <typename Options>
void SetSize(const RunFigureOptions& o, Options* f) {
  if (o.width_px > 0) {
    f->width_px = o.width_px;
    f->height_px = o.height_px;
  }
}

/// The state of `track` at time t: the last sample at or before it; null if none.
const StateMsg* StateAt(const VehicleTrack& track, Micros t) {
  const std::vector<StateMsg>& s = track.samples;
  auto it = std::upper_bound(s.begin(), s.end(), t,
                             [](Micros v, const StateMsg& m) { return v < m.utime; });
  return it == s.begin() ? nullptr : &*(it - 1);
}

/// Index of an acoustic model in *models (appended if new).
std::size_t ModelIndex(const DelayConfig& c, const std::string& label,
                       std::vector<AcousticModelLine>* models) {
  for (std::size_t k = 0; k < models->size(); ++k) {
    const AcousticModelLine& m = (*models)[k];
    if (m.sound_speed_mps == c.sound_speed_mps && m.processing_s == c.processing_s &&
        m.jitter_s == c.jitter_s && m.max_range_m == c.max_range_m) {
      return k;
    }
  }
  models->push_back({label, c.sound_speed_mps, c.processing_s, c.jitter_s, c.max_range_m});
  return models->size() - 1;
}

}  // namespace

std::vector<EventWindow> EventWindowsOf(const RunData& run, double end_s) {
  std::vector<EventWindow> w;
  if (!run.has_scenario) return w;
  for (const ScenarioEvent& e : run.scenario.events) {
    w.push_back({e.at_s, std::min(e.end_s(), end_s), EventKindName(e.kind)});
  }
  return w;
}

std::vector<LinkOutage> OutagesOf(const RunData& run, double end_s) {
  std::vector<LinkOutage> out;
  if (!run.has_scenario || run.scenario.events.empty()) return out;
  const Timeline timeline(run.scenario);
  const auto has = [](const std::vector<int>& v, int id) {
    return std::find(v.begin(), v.end(), id) != v.end();
  };
  for (const ScenarioEvent& e : run.scenario.events) {
    const double t1 = std::min(e.end_s(), end_s);
    for (const auto& [from, to] : timeline.links()) {
      const char* label = nullptr;
      switch (e.kind) {
        case EventKind::kLinkDown:
          if (e.links.empty() || std::find(e.links.begin(), e.links.end(),
                                           std::make_pair(from, to)) != e.links.end()) {
            label = "link down";
          }
          break;
        case EventKind::kVehicleSilent: label = has(e.vehicles, from) ? "silent" : nullptr; break;
        case EventKind::kLeaderSilent: label = from == 0 ? "silent" : nullptr; break;
        case EventKind::kVehicleDeaf: label = has(e.vehicles, to) ? "deaf" : nullptr; break;
        default: break;
      }
      if (label != nullptr) out.push_back({from, to, e.at_s, t1, label});
    }
  }
  return out;
}

bool AcousticOf(const RunData& run, AcousticPoints* points, std::vector<AcousticModelLine>* models) {
  if (!run.has_scenario) return false;
  const Scenario& s = run.scenario;
  const Timeline timeline(s);
  std::map<std::pair<int, int>, DelayConfig> base;
  bool any = false;
  for (const Link& l : BuildAllLinks(s)) {
    base[{l.from, l.to}] = l.delay;
    if (l.delay.kind == DelayKind::kAcoustic) any = true, ModelIndex(l.delay, "[channel]", models);
  }
  for (std::size_t k = 0; k < s.events.size(); ++k) {
    const ScenarioEvent& e = s.events[k];
    if (e.kind == EventKind::kChannel && e.delay && e.delay->kind == DelayKind::kAcoustic) {
      any = true;
      ModelIndex(*e.delay, "of event " + std::to_string(k + 1), models);
    }
  }
  if (!any) return false;
  for (const ChannelEventRecord& e : run.channel_events) {
    if (e.status != 0) continue;
    auto it = base.find({e.sender, e.receiver});
    if (it == base.end()) continue;
    const int k = timeline.LinkIndex(e.sender, e.receiver);
    const ScenarioEvent* change =
        k < 0 ? nullptr : timeline.ChannelChange(static_cast<std::size_t>(k), e.send_utime);
    const DelayConfig& model = change && change->delay ? *change->delay : it->second;
    if (model.kind != DelayKind::kAcoustic) continue;
    if (e.sender >= static_cast<int>(run.vehicles.size()) ||
        e.receiver >= static_cast<int>(run.vehicles.size()) || e.sender < 0 || e.receiver < 0) {
      continue;
    }
    // The channel's range (docs/scenario.md, "Acoustic range"): the sender's position in
    // the message, the receiver's in its newest state sent strictly before the send tick,
    // 0 before the receiver's first state.
    const StateMsg* a = StateAt(run.vehicles[static_cast<std::size_t>(e.sender)], e.send_utime);
    const StateMsg* b =
        StateAt(run.vehicles[static_cast<std::size_t>(e.receiver)], e.send_utime - 1);
    if (a == nullptr) continue;
    points->send_s.push_back(ToSeconds(e.send_utime));
    points->range_m.push_back(b == nullptr ? 0.0 : (a->eta.head<3>() - b->eta.head<3>()).norm());
    points->drawn_delay_s.push_back(e.delay_s);
    points->realised_delay_s.push_back(ToSeconds(e.deliver_utime - e.send_utime));
  }
  return true;
}

std::vector<VehicleSeries> VehicleSeriesOf(const RunData& run) {
  std::vector<VehicleSeries> vehicles;
  for (const VehicleTrack& track : run.vehicles) {
    if (track.samples.empty()) continue;
    VehicleSeries v;
    v.id = track.id;
    const std::size_t n = track.samples.size();
    v.t_s.reserve(n);
    for (auto& c : v.eta) c.reserve(n);
    for (auto& c : v.nu) c.reserve(n);
    for (const StateMsg& m : track.samples) {
      v.t_s.push_back(ToSeconds(m.utime));
      for (int k = 0; k < 5; ++k) {
        v.eta[static_cast<std::size_t>(k)].push_back(m.eta(k));
        v.nu[static_cast<std::size_t>(k)].push_back(m.nu(k));
      }
    }
    vehicles.push_back(std::move(v));
  }
  return vehicles;
}

std::vector<ErrorSeries> ErrorSeriesOf(const RunData& run, const RunAnalysis& a) {
  std::vector<ErrorSeries> errors;
  if (!a.has_formation) return errors;
  for (const FollowerAnalysis& fa : a.followers) {
    if (fa.id <= 0 || fa.id >= static_cast<int>(run.vehicles.size())) continue;
    const VehicleTrack& track = run.vehicles[static_cast<std::size_t>(fa.id)];
    ErrorSeries e;
    e.id = fa.id;
    for (std::size_t k = 0; k < fa.errors.size() && k < track.samples.size(); ++k) {
      if (!Finite(fa.errors[k])) continue;
      e.t_s.push_back(ToSeconds(track.samples[k].utime));
      e.position_m.push_back(fa.errors[k].position_m);
      e.velocity_mps.push_back(fa.errors[k].velocity_mps);
      e.attitude_rad.push_back(fa.errors[k].attitude_rad);
    }
    if (!e.t_s.empty()) errors.push_back(std::move(e));
  }
  return errors;
}

std::vector<LinkSeries> LinkSeriesOf(const RunData& run) {
  std::map<std::pair<int, int>, LinkSeries> links;
  // The figure reads each link's series in time order: a log whose events are out of order
  // (cut and joined again) is taken in order of send time.
  const auto by_send = [](const ChannelEventRecord& a, const ChannelEventRecord& b) {
    return a.send_utime < b.send_utime;
  };
  std::vector<ChannelEventRecord> sorted;
  const std::vector<ChannelEventRecord>* events = &run.channel_events;
  if (!std::is_sorted(events->begin(), events->end(), by_send)) {
    sorted = run.channel_events;
    std::stable_sort(sorted.begin(), sorted.end(), by_send);
    events = &sorted;
  }
  for (const ChannelEventRecord& e : *events) {
    // A state the sender never transmitted (modem busy, sender silent) was neither
    // delivered nor dropped: shoal analyze does not count it as sent, nor does the figure.
    if (NotTransmitted(e.status)) continue;
    LinkSeries& l = links[{e.sender, e.receiver}];
    l.from = e.sender;
    l.to = e.receiver;
    if (e.status == 0) {
      l.sent_s.push_back(ToSeconds(e.send_utime));
      l.delay_s.push_back(ToSeconds(e.deliver_utime - e.send_utime));
      l.model_delay_s.push_back(e.delay_s);
    } else {
      l.dropped_s.push_back(ToSeconds(e.send_utime));
    }
  }
  std::vector<LinkSeries> list;
  for (auto& [key, l] : links) list.push_back(std::move(l));
  return list;
}

ChannelOptions ChannelOptionsOf(const RunData& run, const RunAnalysis& a) {
  ChannelOptions o;
  o.scenario = run.scenario_name.empty() ? "run" : run.scenario_name;
  if (run.has_scenario && !run.channel_events.empty()) {  // the default link delay
    Micros last = run.channel_events.front().send_utime;
    for (const ChannelEventRecord& e : run.channel_events) last = std::max(last, e.send_utime);
    const double end = ToSeconds(last);
    for (double t = 0.0; t <= end + 1e-9; t += 0.01) {
      o.tau_t_s.push_back(t);
      o.tau_s.push_back(NominalDelaySeconds(run.scenario.delay, t));
    }
  }
  o.mode = a.mode;
  for (const ProcessAnalysis& p : a.processes) {  // the emulator's health (process -1)
    if (p.id == -1 && a.mode == "realtime") o.release_error_p99_s = a.channel.release_error_p99_s;
  }
  if (a.period_us > 0) {
    o.control_period_s = ToSeconds(a.period_us);
  } else if (run.has_scenario) {
    o.control_period_s = ToSeconds(run.scenario.period_us());
  }
  return o;
}

bool WriteRunFigures(const RunData& run, const std::string& out, const RunFigureOptions& o,
                     RunFigureReport* report, std::string* err) {
  // The paths it reports: "figures/x.png" for --out figures/, not "figures//x.png".
  std::string out_dir = out;
  while (out_dir.size() > 1 && out_dir.back() == '/') out_dir.pop_back();
  const std::vector<VehicleSeries> vehicles = VehicleSeriesOf(run);
  if (vehicles.empty()) {
    if (err) *err = run.source + ": no vehicle states to draw";
    return false;
  }
  const RunAnalysis a = AnalyseRun(run);
  const std::string name = run.scenario_name.empty() ? "run" : run.scenario_name;
  std::string why;
  const auto emit = [&](bool ok, const std::string& path) {
    if (ok) {
      report->written.push_back(path);
    } else {
      report->failures.push_back(path + ": " + why);
    }
  };
  TrajectoryOptions t;
  t.scenario = name;
  t.snapshot_edges = SnapshotEdges(run);
  SetSize(o, &t);
  const std::string trajectory = out_dir + "/trajectory.png";
  emit(RenderPng(TrajectoryFigure(vehicles, t), trajectory, &why), trajectory);
  const std::string states = out_dir + "/states.png";
  const Figure2D sf = o.width_px > 0 ? StateFigure(vehicles, name, o.width_px, o.height_px)
                                     : StateFigure(vehicles, name);
  emit(RenderPng(sf, states, &why), states);

  const std::vector<ErrorSeries> errors = ErrorSeriesOf(run, a);
  if (!a.has_formation) {
    report->skipped.push_back(
        "no scenario (offsets) or no leader states in the log: errors.png skipped (give "
        "--scenario FILE)");
  } else if (errors.empty()) {
    report->skipped.push_back(
        "no follower has a leader state at the same time: errors.png skipped");
  } else {
    ErrorOptions e;
    e.scenario = name;
    e.log_y = !o.linear_errors;
    e.position_tol_m = run.scenario.metrics.position_tol_m;
    e.velocity_tol_mps = run.scenario.metrics.velocity_tol_mps;
    e.converged_s = a.summary.converged ? a.summary.convergence_time_s : -1.0;
    e.events = EventWindowsOf(run, a.end_s);
    SetSize(o, &e);
    const std::string path = out_dir + "/errors.png";
    emit(RenderPng(ErrorFigure(errors, e), path, &why), path);
  }

  if (run.channel_events.empty()) {
    report->skipped.push_back("no SHOAL_CHANNEL events in the log: channel.png skipped");
  } else {
    ChannelOptions c = ChannelOptionsOf(run, a);
    c.outages = OutagesOf(run, a.end_s);
    SetSize(o, &c);
    const std::string path = out_dir + "/channel.png";
    emit(RenderPng(ChannelFigure(LinkSeriesOf(run), c), path, &why), path);
  }
  AcousticPoints points;
  std::vector<AcousticModelLine> models;
  if (AcousticOf(run, &points, &models)) {
    AcousticOptions ao;
    ao.scenario = name;
    SetSize(o, &ao);
    const std::string path = out_dir + "/acoustic_delay.png";
    emit(RenderPng(AcousticDelayFigure(points, models, ao), path, &why), path);
  }
  return true;
}

bool PrepareOutputDir(const std::string& out_dir, std::string* err) {
  const auto fail = [&](const std::string& m) {
    if (err) *err = out_dir + ": " + m;
    return false;
  };
  if (mkdir(out_dir.c_str(), 0755) != 0 && errno != EEXIST) {
    return fail(std::string("cannot create the output directory (") + std::strerror(errno) + ")");
  }
  struct stat st {};
  if (stat(out_dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) {
    return fail("exists and is not a directory; give --out a directory");
  }
  // Writable before anything is loaded or drawn.
  const std::string probe = out_dir + "/.shoal_render_probe";
  FILE* f = std::fopen(probe.c_str(), "w");
  if (!f) return fail(std::string("cannot write there (") + std::strerror(errno) + ")");
  std::fclose(f);
  std::remove(probe.c_str());
  return true;
}

}  // namespace shoal::render
