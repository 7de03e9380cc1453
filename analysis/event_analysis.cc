#include "analysis/event_analysis.h"

#include <algorithm>
#include <cmath>

#include "core/channel_model.h"

namespace shoal {
namespace {

std::string LinkList(const std::vector<std::pair<int, int>>& links) {
  if (links.empty()) return "every link";
  std::string s = links.size() == 1 ? "link " : "links ";
  for (std::size_t k = 0; k < links.size(); ++k) {
    s += (k ? ", " : "") + std::to_string(links[k].first) + "->" + std::to_string(links[k].second);
  }
  return s;
}

std::string IdList(const char* what, const std::vector<int>& ids) {
  std::string s = what;
  for (std::size_t k = 0; k < ids.size(); ++k) s += (k ? ", " : " ") + std::to_string(ids[k]);
  return s;
}

/// Whether decision e is one of those event ev applies to (its links, senders or
/// receivers; every decision for a topology switch and a controller reset).
bool Affected(const ScenarioEvent& ev, const ChannelEventRecord& e) {
  const auto has = [](const std::vector<int>& v, int id) {
    return std::find(v.begin(), v.end(), id) != v.end();
  };
  switch (ev.kind) {
    case EventKind::kLinkDown:
    case EventKind::kChannel:
      return ev.links.empty() ||
             std::find(ev.links.begin(), ev.links.end(), std::make_pair<int, int>(e.sender, e.receiver)) !=
                 ev.links.end();
    case EventKind::kVehicleSilent: return has(ev.vehicles, e.sender);
    case EventKind::kLeaderSilent: return e.sender == 0;
    case EventKind::kVehicleDeaf: return has(ev.vehicles, e.receiver);
    case EventKind::kTopology:
    case EventKind::kControllerReset: return true;
  }
  return false;
}

/// The time at which the channel applied event kind `kind` to decision e: a deaf receiver
/// is judged when the message is due, everything else when it is sent.
Micros DecisionTime(EventKind kind, const ChannelEventRecord& e, Micros period_us) {
  if (kind != EventKind::kVehicleDeaf) return e.send_utime;
  if (e.status == ChannelDecision::kDelivered) return e.deliver_utime;
  if (e.status == ChannelDecision::kDroppedDeaf) {
    return DeliveryTime(e.send_utime, e.delay_s, period_us);
  }
  return e.send_utime;
}

/// The decisions within the event's window [at, end); a window the run's end cuts short
/// (`clipped`: the event holds beyond it) includes the final tick, whose decisions the run
/// makes too. One that ends right at the run's end does not hold at its final tick.
void CountDecisions(const RunData& run, const ScenarioEvent& ev, Micros period_us, bool clipped,
                    EventAnalysis* out) {
  const Micros at = TimelineMicros(out->at_s), end = TimelineMicros(out->end_s);
  const bool to_run_end = clipped;
  for (const ChannelEventRecord& e : run.channel_events) {
    if (e.status < 0 || e.status >= kChannelStatuses || !Affected(ev, e)) continue;
    const Micros t = DecisionTime(ev.kind, e, period_us);
    if (t >= at && (t < end || (to_run_end && t == end))) ++out->decisions[e.status];
  }
}

/// Where an event's change ends: its end_s(), or for a topology without an explicit end
/// the next topology event's start (the timeline replaces it there).
double ChangeEndS(const std::vector<ScenarioEvent>& events, std::size_t k) {
  const ScenarioEvent& ev = events[k];
  double end = ev.end_s();
  if (ev.kind != EventKind::kTopology) return end;
  for (const ScenarioEvent& next : events) {
    if (next.kind == EventKind::kTopology && next.at_s > ev.at_s) end = std::min(end, next.at_s);
  }
  return end;
}

/// Re-convergence after out->reference_s within [reference_s, horizon_s), and the
/// excursion from at_s until then (samples in time order).
void Formation(const std::vector<WorstSample>& samples, bool horizon_is_end, EventAnalysis* out) {
  const auto in_range = [&](double t) {
    return t >= out->reference_s && (t < out->horizon_s || (horizon_is_end && t <= out->horizon_s));
  };
  const WorstSample* first = nullptr;
  const WorstSample* after_violation = nullptr;
  bool last_violating = true;
  for (const WorstSample& w : samples) {
    if (!in_range(w.t_s)) continue;
    if (first == nullptr) first = &w;
    if (w.violating) {
      after_violation = nullptr;
    } else if (last_violating) {
      after_violation = &w;
    }
    last_violating = w.violating;
  }
  out->reconverged = first != nullptr && !last_violating;
  if (out->reconverged) {
    out->reconverged_at_s = after_violation->t_s;
    out->time_to_reconverge_s = out->reconverged_at_s - out->reference_s;
  }
  const auto until = [&](double t) {
    if (out->reconverged) return t <= out->reconverged_at_s;
    return t < out->horizon_s || (horizon_is_end && t <= out->horizon_s);
  };
  for (const WorstSample& w : samples) {
    if (w.t_s < out->at_s || !until(w.t_s)) continue;
    if (!(w.position_m <= out->max_position_error_m)) {
      out->max_position_error_m = w.position_m;
      out->max_position_follower = w.position_follower;
      out->max_position_time_s = w.t_s;
    }
    if (!(w.velocity_mps <= out->max_velocity_error_mps)) out->max_velocity_error_mps = w.velocity_mps;
  }
}

}  // namespace

std::string EventAffects(const ScenarioEvent& e) {
  switch (e.kind) {
    case EventKind::kLinkDown:
    case EventKind::kChannel:
      return LinkList(e.links);
    case EventKind::kVehicleSilent:
    case EventKind::kVehicleDeaf:
    case EventKind::kControllerReset:
      return IdList(e.vehicles.size() == 1 ? "vehicle" : "vehicles", e.vehicles);
    case EventKind::kLeaderSilent:
      return "the leader";
    case EventKind::kTopology: {
      std::string s = "edges";
      for (const auto& [i, j] : e.edges) s += " " + std::to_string(i) + "<-" + std::to_string(j);
      if (e.edges.empty()) s += " none";
      return s + ", " + IdList("leader links", e.leader_links);
    }
  }
  return "";
}

std::vector<EventAnalysis> AnalyseEvents(const RunData& run, const std::vector<WorstSample>& samples,
                                         double end_s, Micros period_us) {
  std::vector<EventAnalysis> out;
  if (!run.has_scenario) return out;
  const std::vector<ScenarioEvent>& events = run.scenario.events;
  for (std::size_t k = 0; k < events.size(); ++k) {
    const ScenarioEvent& ev = events[k];
    if (ev.at_s > end_s) continue;  // after the run's end: not part of this run
    EventAnalysis a;
    a.index = static_cast<int>(k);
    a.kind = ev.kind;
    a.at_s = ev.at_s;
    a.ends_in_run = ChangeEndS(events, k) < end_s;
    a.end_s = std::min(ChangeEndS(events, k), end_s);
    a.affects = EventAffects(ev);
    a.reference_s = a.ends_in_run ? a.end_s : a.at_s;
    a.horizon_s = end_s;
    for (const ScenarioEvent& next : events) {
      if (next.at_s > a.reference_s) a.horizon_s = std::min(a.horizon_s, next.at_s);
    }
    Formation(samples, a.horizon_s == end_s, &a);
    CountDecisions(run, ev, period_us, ChangeEndS(events, k) > end_s, &a);
    out.push_back(a);
  }
  return out;
}

}  // namespace shoal
