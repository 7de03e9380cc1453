#include "analysis/analysis_json.h"

#include <cmath>

#include "analysis/live.h"
#include "analysis/verdict.h"

namespace shoal {
namespace {

using Json = nlohmann::ordered_json;

Json QuantileJson(const Quantiles& q) {
  return Json{{"count", q.count}, {"p50", q.p50}, {"p99", q.p99},
              {"max", q.max},     {"min", q.min}, {"mean", q.mean}};
}

Json Vec3Json(const Vec3& v) {
  if (!v.allFinite()) return nullptr;
  return Json::array({v(0), v(1), v(2)});
}

/// A string, or null when empty.
Json StringOrNull(const std::string& s) { return s.empty() ? Json(nullptr) : Json(s); }

/// Last health report of process `id`, or null.
const HealthRecord* LastHealth(const RunAnalysis& a, int id) {
  for (const ProcessAnalysis& p : a.processes) {
    if (p.id == id) return &p.last;
  }
  return nullptr;
}

Json LinkJson(const LinkAnalysis& l) {
  return Json{{"from", l.from},
              {"to", l.to},
              {"in_scenario", l.in_scenario},
              {"sent", l.sent},
              {"delivered", l.delivered},
              {"dropped_loss", l.dropped_loss},
              {"dropped_queue", l.dropped_queue},
              {"dropped_invalid", l.dropped_invalid},
              {"dropped_range", l.dropped_range},
              {"skipped_modem_busy", l.skipped_busy},
              {"skipped_silent", l.skipped_silent},
              {"dropped_link_down", l.dropped_link_down},
              {"dropped_deaf", l.dropped_deaf},
              {"realised_delay_s", QuantileJson(l.realised_delay_s)},
              {"realised_delay_error_s", QuantileJson(l.delay_error_s)},
              {"message_age_s", QuantileJson(l.age_at_use_s)},
              {"stale_ticks", l.ticks_stale},
              {"ticks_before_first_message", l.ticks_before_first}};
}

Json ChannelJson(const ChannelAnalysis& c) {
  Json links = Json::array();
  for (const LinkAnalysis& l : c.links) links.push_back(LinkJson(l));
  return Json{{"delivered", c.delivered},
              {"dropped", c.dropped},
              {"delay_error_p99_s", c.release_error_p99_s},
              {"sent", c.sent},
              {"dropped_loss", c.dropped_loss},
              {"dropped_queue", c.dropped_queue},
              {"dropped_invalid", c.dropped_invalid},
              {"dropped_range", c.dropped_range},
              {"skipped_modem_busy", c.skipped_busy},
              {"skipped_silent", c.skipped_silent},
              {"dropped_link_down", c.dropped_link_down},
              {"dropped_deaf", c.dropped_deaf},
              {"realised_delay_error_p50_s", c.delay_error_s.p50},
              {"realised_delay_error_p99_s", c.delay_error_s.p99},
              {"realised_delay_error_max_s", c.delay_error_s.max},
              {"realised_delay_error_min_s", c.delay_error_s.min},
              {"realised_delay_p50_s", c.realised_delay_s.p50},
              {"realised_delay_max_s", c.realised_delay_s.max},
              {"message_age_p50_s", c.age_at_use_s.p50},
              {"message_age_p99_s", c.age_at_use_s.p99},
              {"message_age_max_s", c.age_at_use_s.max},
              {"model_mismatches", c.model_mismatches},
              {"unknown_link_events", c.unknown_links},
              {"links", links}};
}

Json LoopJson(const RunAnalysis& a) {
  Json procs = Json::array();
  for (const ProcessAnalysis& p : a.processes) {
    const HealthRecord& h = p.last;
    procs.push_back(Json{{"id", p.id},
                         {"reports", p.reports},
                         {"ticks", h.ticks},
                         {"lateness_p50_s", h.lateness_p50_s},
                         {"lateness_p99_s", h.lateness_p99_s},
                         {"lateness_max_s", h.lateness_max_s},
                         {"overruns", h.overruns},
                         {"saturation_fraction", h.saturation_fraction},
                         {"neighbour_timeouts", h.neighbour_timeouts},
                         {"msgs_received", h.msgs_received},
                         {"msgs_dropped_invalid", h.msgs_dropped_invalid},
                         {"msgs_dropped_old", h.msgs_dropped_old}});
  }
  return Json{{"lateness_p99_s", a.summary.lateness_p99_s},
              {"overruns", a.summary.overruns},
              {"processes", procs}};
}

/// Per follower: shoal sim's keys first (same values for a shoal sim log), then the
/// analysis' own.
Json FollowersJson(const RunAnalysis& a) {
  Json per = Json::array();
  for (std::size_t i = 0; i < a.followers.size(); ++i) {
    const FollowerAnalysis& fa = a.followers[i];
    const FormationErrors e = i < a.final_errors.size() ? a.final_errors[i]
                                                        : FormationErrors{kNaN, kNaN, kNaN};
    const HealthRecord* h = LastHealth(a, fa.id);
    per.push_back(Json{{"id", fa.id},
                       {"final_position_error_m", e.position_m},
                       {"final_velocity_error_mps", e.velocity_mps},
                       {"final_attitude_error_rad", e.attitude_rad},
                       {"saturation_fraction", fa.saturation_fraction},
                       {"neighbour_timeouts", h ? Json(h->neighbour_timeouts) : Json(nullptr)},
                       {"msgs_received", h ? Json(h->msgs_received) : Json(nullptr)},
                       {"converged", a.has_formation ? Json(fa.converged) : Json(nullptr)},
                       {"convergence_time_s", fa.convergence_time_s},
                       {"max_position_error_m", fa.max_position_error_m},
                       {"samples", fa.samples},
                       {"compared_samples", fa.compared},
                       {"stale_ticks", fa.stale_ticks},
                       {"stale_events", fa.stale_events}});
  }
  return per;
}

/// A finite number, or null.
Json NumberOrNull(double x) { return std::isfinite(x) ? Json(x) : Json(nullptr); }

Json EventsJson(const RunAnalysis& a) {
  Json events = Json::array();
  for (const EventAnalysis& e : a.events) {
    Json decisions = Json::object();
    for (int st = 0; st < kChannelStatuses; ++st) decisions[ChannelStatusKey(st)] = e.decisions[st];
    events.push_back(Json{{"index", e.index},
                          {"kind", EventKindName(e.kind)},
                          {"at_s", e.at_s},
                          {"end_s", NumberOrNull(e.end_s)},
                          {"ends_in_run", e.ends_in_run},
                          {"affects", e.affects},
                          {"max_position_error_m", NumberOrNull(e.max_position_error_m)},
                          {"max_position_error_follower", e.max_position_follower},
                          {"max_position_error_time_s", NumberOrNull(e.max_position_time_s)},
                          {"max_velocity_error_mps", NumberOrNull(e.max_velocity_error_mps)},
                          {"reference_s", NumberOrNull(e.reference_s)},
                          {"horizon_s", NumberOrNull(e.horizon_s)},
                          {"reconverged", e.reconverged},
                          {"reconverged_at_s", NumberOrNull(e.reconverged_at_s)},
                          {"time_to_reconverge_s", NumberOrNull(e.time_to_reconverge_s)},
                          {"decisions", decisions}});
  }
  return events;
}

}  // namespace

void AddFormationKeys(bool converged, double convergence_time_s,
                      const FormationErrors& final_worst, Json* j) {
  (*j)["converged"] = converged;
  (*j)["convergence_time_s"] = converged ? convergence_time_s : kNaN;
  (*j)["final_position_error_m"] = final_worst.position_m;
  (*j)["final_velocity_error_mps"] = final_worst.velocity_mps;
  (*j)["final_attitude_error_rad"] = final_worst.attitude_rad;
}

void AddTimingKeys(double sim_time_s, double wall_time_s, Json* j) {
  (*j)["sim_time_s"] = sim_time_s;
  (*j)["wall_time_s"] = wall_time_s;
  (*j)["realtime_factor"] = wall_time_s > 0 ? sim_time_s / wall_time_s : kNaN;
}

namespace {

/// --live: whether the stream held the whole run (JudgeLiveStream); null for a log. A
/// retimed log: where its wall time comes from.
void AddStreamKeys(const RunData& run, const RunAnalysis& a, Json* j) {
  if (!run.stream.live) {
    (*j)["complete"] = nullptr;
    (*j)["states_missed"] = nullptr;
    (*j)["stream"] = nullptr;
  } else {
    const LiveCompleteness c = JudgeLiveStream(run, a);
    (*j)["complete"] = c.complete;
    (*j)["states_missed"] = c.states_missed;
    (*j)["stream"] = Json{{"end_status_received", run.stream.end_status},
                          {"stopped_by", run.stream.stopped_by},
                          {"until_idle_s", run.stream.idle_s},
                          {"messages_missed", c.messages_missed},
                          {"messages_missed_by_channel", run.stream.missed_by_channel},
                          {"incomplete_reasons", c.reasons}};
  }
  const RetimedFrom& r = run.retimed_from;
  (*j)["retimed_from"] =
      r.retimed ? Json{{"log", r.source},
                       {"first_timestamp_us", r.first_timestamp},
                       {"last_timestamp_us", r.last_timestamp}}
                : Json(nullptr);
}

}  // namespace

Json AnalysisJson(const RunData& run, const RunAnalysis& a, const AnalysisSource& source) {
  const RunSummary& s = a.summary;
  const bool f = a.has_formation;
  const bool conv = FormationConverged(a);
  Json j;
  j["scenario"] = StringOrNull(run.scenario_name);
  j["scenario_source"] = StringOrNull(run.scenario_origin);
  j["mode"] = a.mode;
  AddFormationKeys(conv, s.convergence_time_s,
                   f ? s.final_worst : FormationErrors{kNaN, kNaN, kNaN}, &j);
  j["max_position_error_m"] = f ? s.max_position_error_m : kNaN;
  // Unknown without the scenario's formation or a tick of every vehicle's state, not false.
  if (!f || a.complete_samples == 0) j["converged"] = nullptr;
  AddTimingKeys(s.sim_time_s, a.wall_time_s, &j);
  j["ticks"] = a.ticks;
  j["channel_delivered"] = a.channel.delivered;
  j["channel_dropped"] = a.channel.dropped;
  j["interrupted"] = a.interrupted;
  j["diverged_follower"] = a.diverged_follower;
  j["followers"] = FollowersJson(a);
  j["channel"] = ChannelJson(a.channel);
  j["events"] = EventsJson(a);
  j["loop"] = LoopJson(a);
  j["all_processes_ok"] = a.problems.empty() && !a.interrupted;
  j["problems"] = a.problems;
  nlohmann::ordered_json restarts = nlohmann::ordered_json::array();
  for (const RestartAnalysis& r : a.restarts) {
    restarts.push_back({{"id", r.id}, {"t_s", ToSeconds(r.utime)},
                        {"states_missing", r.states_missing}, {"message", r.message}});
  }
  j["logged_restarts"] = restarts;
  j["states_missing_in_restarts"] = a.states_missing_in_restarts;
  j["log"] = source.live ? Json(nullptr) : Json(source.log);
  j["log_events"] = run.events;
  j["log_undecodable"] = run.undecodable;
  j["log_rejected"] = run.rejected;
  j["log_states"] = s.states;
  j["log_states_expected"] = a.states_expected;
  j["log_states_damaged"] = a.states_damaged;
  j["log_states_negative_time"] = a.states_negative_time;
  j["log_states_after_end"] = a.states_after_end;
  j["log_end_s"] = a.end_s;
  j["channel_events_damaged"] = a.channel.events_damaged;
  j["channel_events_sent_at_impossible_time"] = a.channel.events_sent_impossible;
  j["channel_events_delivered_at_impossible_time"] = a.channel.events_delivered_impossible;
  j["log_last_delivery_s"] =
      a.bounds.deliver_limit_us >= 0 ? ToSeconds(a.bounds.deliver_limit_us) : kNaN;
  j["lcm_url"] = source.live ? Json(run.source) : Json(nullptr);
  AddStreamKeys(run, a, &j);
  j["complete_samples"] = a.complete_samples;
  j["leader"] = Json{{"path_length_m", a.leader_path_length_m},
                     {"start_m", Vec3Json(a.leader_start_m)},
                     {"end_m", Vec3Json(a.leader_end_m)}};
  j["damaged"] = run.damaged;
  j["bus_authenticated"] = run.bus_authenticated();
  j["authentication"] = Json{{"key", run.key_used},
                             {"verified", run.verified},
                             {"unauthenticated", run.unauthenticated},
                             {"unauthenticated_by_channel", run.unauthenticated_by_channel},
                             {"unverified", run.unverified},
                             {"insecure_run", run.insecure_run}};
  j["warnings"] = run.warnings;
  return j;
}

}  // namespace shoal
