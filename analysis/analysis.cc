#include "analysis/analysis.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <map>
#include <optional>
#include <utility>

#include "analysis/event_analysis.h"
#include "analysis/memory.h"
#include "core/channel_model.h"
#include "core/timeline.h"
#include "core/topology.h"
#include "runtime/messages.h"

namespace shoal {
namespace {

constexpr double kPitchLimitRad = 80.0 * 3.14159265358979323846 / 180.0;  // as shoal sim
constexpr std::int8_t kDelivered = 0, kLoss = 1, kQueue = 2, kInvalid = 3;
constexpr std::int8_t kBusy = ChannelDecision::kSkippedBusy, kRange = ChannelDecision::kDroppedRange;
constexpr std::int8_t kSilent = ChannelDecision::kSkippedSilent;
constexpr std::int8_t kLinkDown = ChannelDecision::kDroppedLinkDown;
constexpr std::int8_t kDeaf = ChannelDecision::kDroppedDeaf;

FormationErrors NaNErrors() { return FormationErrors{kNaN, kNaN, kNaN}; }

/// The states of one vehicle within the run's time bounds: samples[first, first + size()).
/// The tracks are sorted by time, so these are one contiguous range.
class Span {
 public:
  Span() = default;
  Span(const std::vector<StateMsg>& s, Micros lo, Micros hi) {
    const auto by_time = [](const StateMsg& m, Micros t) { return m.utime < t; };
    const auto b = std::lower_bound(s.begin(), s.end(), lo, by_time);
    auto e = std::lower_bound(b, s.end(), hi, by_time);
    if (e != s.end() && e->utime == hi) ++e;
    first_ = static_cast<std::size_t>(b - s.begin());
    b_ = s.data() + first_;
    e_ = s.data() + (e - s.begin());
  }
  const StateMsg* begin() const { return b_; }
  const StateMsg* end() const { return e_; }
  std::size_t size() const { return static_cast<std::size_t>(e_ - b_); }
  bool empty() const { return b_ == e_; }
  const StateMsg& operator[](std::size_t k) const { return b_[k]; }
  const StateMsg& front() const { return *b_; }
  const StateMsg& back() const { return e_[-1]; }
  std::size_t first() const { return first_; }  // index of front() in the track

 private:
  const StateMsg* b_ = nullptr;
  const StateMsg* e_ = nullptr;
  std::size_t first_ = 0;
};

/// Every vehicle's Span; an empty one for an id the run has no track for.
class ValidStates {
 public:
  ValidStates(const RunData& run, const StateTimeBounds& b) {
    for (const VehicleTrack& v : run.vehicles) spans_.emplace_back(v.samples, 0, b.limit_us);
  }
  Span operator()(int id) const {
    if (id < 0 || id >= static_cast<int>(spans_.size())) return Span();
    return spans_[static_cast<std::size_t>(id)];
  }

 private:
  std::vector<Span> spans_;
};

void AnalyseFollowers(const RunData& run, const ValidStates& valid, RunAnalysis* a) {
  const int n = run.followers;
  const Span lead = valid(0);
  a->followers.resize(n);
  for (int i = 1; i <= n; ++i) {
    FollowerAnalysis& f = a->followers[i - 1];
    f.id = i;
    const Span s = valid(i);
    f.samples = static_cast<std::int64_t>(s.size());
    bool prev_stale = false;
    for (const StateMsg& m : s) {
      f.saturated_ticks += (m.flags & StateMsg::kFlagSaturated) != 0;
      const bool stale = (m.flags & StateMsg::kFlagStaleNeighbour) != 0;
      f.stale_ticks += stale;
      f.stale_events += stale && !prev_stale;
      prev_stale = stale;
    }
    if (!s.empty()) f.saturation_fraction = static_cast<double>(f.saturated_ticks) / s.size();
    if (!a->has_formation) continue;
    // Aligned with the whole track: NaN for the states left out.
    const std::size_t track = run.vehicles[static_cast<std::size_t>(i)].samples.size();
    ReserveHuge(&f.errors, track);
    f.errors.assign(track, NaNErrors());
    FormationMetrics one({run.scenario.offsets_m[i - 1]}, run.scenario.metrics);
    std::vector<const StateMsg*> ptr(1);
    std::size_t l = 0;
    for (std::size_t k = 0; k < s.size(); ++k) {
      while (l < lead.size() && lead[l].utime < s[k].utime) ++l;
      if (l == lead.size()) break;
      if (lead[l].utime != s[k].utime) continue;
      f.errors[s.first() + k] = ErrorsOf(s[k], run.scenario.offsets_m[i - 1], lead[l]);
      ptr[0] = &s[k];
      one.Add(lead[l], ptr);
    }
    f.compared = one.samples();
    if (f.compared > 0) {
      f.converged = one.converged();
      f.convergence_time_s = f.converged ? one.convergence_time_s() : kNaN;
      f.final_errors = one.final_errors()[0];
      f.max_position_error_m = one.max_position_error_m();
    } else {
      f.final_errors = NaNErrors();
    }
  }
}

/// The worst follower of one complete sample, and whether it violates the tolerances as
/// FormationMetrics::Add decides.
WorstSample WorstOf(const RunData& run, const StateMsg& l, const std::vector<const StateMsg*>& f) {
  WorstSample w;
  w.t_s = ToSeconds(l.utime);
  const MetricsConfig& tol = run.scenario.metrics;
  for (std::size_t i = 0; i < f.size(); ++i) {
    const FormationErrors e = ErrorsOf(*f[i], run.scenario.offsets_m[i], l);
    if (!(e.position_m <= w.position_m)) {
      w.position_m = e.position_m;
      w.position_follower = static_cast<int>(i) + 1;
    }
    w.velocity_mps = std::max(w.velocity_mps, e.velocity_mps);
    if (!(e.position_m <= tol.position_tol_m && e.velocity_mps <= tol.velocity_tol_mps)) {
      w.violating = true;
    }
  }
  return w;
}

/// The swarm-level metrics of shoal sim / shoal run: only times at which the leader and
/// every follower have a state. `worst` (may be null): each complete sample's worst
/// follower, for the events.
/// Calls `f(leader, followers)` at each time at which the leader and every follower have a
/// state; `followers` points into `valid`'s spans. Returns how many such times there are.
template <class F>
std::int64_t ForEachCompleteSample(const RunData& run, const ValidStates& valid, F&& f) {
  const int n = run.followers;
  std::vector<std::size_t> idx(n + 1, 0);
  std::vector<const StateMsg*> ptr(n);
  std::int64_t samples = 0;
  for (const StateMsg& l : valid(0)) {
    bool complete = true;
    for (int i = 1; i <= n; ++i) {
      const Span s = valid(i);
      std::size_t& k = idx[i];
      while (k < s.size() && s[k].utime < l.utime) ++k;
      if (k == s.size() || s[k].utime != l.utime) {
        complete = false;
        continue;
      }
      ptr[i - 1] = &s[k];
    }
    if (!complete) continue;
    ++samples;
    f(l, ptr);
  }
  return samples;
}

void AnalyseFormation(const RunData& run, const ValidStates& valid, RunAnalysis* a,
                      std::vector<WorstSample>* worst) {
  FormationMetrics m(run.scenario.offsets_m, run.scenario.metrics);
  a->complete_samples = ForEachCompleteSample(
      run, valid, [&](const StateMsg& l, const std::vector<const StateMsg*>& ptr) {
        m.Add(l, ptr);
        if (worst != nullptr) worst->push_back(WorstOf(run, l, ptr));
        a->summary.sim_time_s = ToSeconds(l.utime);
      });
  a->summary.converged = m.converged();
  a->summary.convergence_time_s = m.convergence_time_s();
  a->summary.final_worst = m.final_worst();
  a->summary.max_position_error_m = m.max_position_error_m();
  if (m.samples() > 0) a->final_errors = m.final_errors();
}

/// The channel's links: the scenario's, of every topology its timeline produces (with
/// their delay models, in (from, to) order), then any other link the log shows, in order
/// of appearance.
class LinkTable {
 public:
  LinkTable(const RunData& run, std::vector<LinkAnalysis>* links) : links_(links) {
    if (run.has_scenario) {
      const Scenario& s = run.scenario;
      for (const Link& l : BuildAllLinks(s)) model_[{l.from, l.to}] = l.delay;
      timeline_ = Timeline(s);
      for (const ScenarioEvent& e : s.events) {
        changes_delay_ = changes_delay_ || (e.kind == EventKind::kChannel && e.delay);
      }
    }
    for (const auto& [key, cfg] : model_) {
      index_.emplace(key, links_->size());
      LinkAnalysis l;
      l.from = key.first;
      l.to = key.second;
      l.in_scenario = true;
      links_->push_back(l);
    }
  }

  /// The delay model of a link of the scenario, null for any other.
  const DelayConfig* Model(int from, int to) const {
    auto it = model_.find({from, to});
    return it == model_.end() ? nullptr : &it->second;
  }

  /// The delay model in force on link (from, to) at send time t: a channel event's, else
  /// `base` (the link's Model()).
  const DelayConfig* ModelAt(const DelayConfig* base, int from, int to, Micros t) const {
    if (base == nullptr || !changes_delay_) return base;
    const int k = timeline_.LinkIndex(from, to);
    if (k < 0) return base;
    const ScenarioEvent* change = timeline_.ChannelChange(static_cast<std::size_t>(k), t);
    return change != nullptr && change->delay ? &*change->delay : base;
  }

  /// Index of the link in *links, appended on first sight if not in the scenario.
  std::size_t Of(int from, int to) {
    auto it = index_.find({from, to});
    if (it != index_.end()) return it->second;
    LinkAnalysis l;
    l.from = from;
    l.to = to;
    links_->push_back(l);
    index_.emplace(std::make_pair(from, to), links_->size() - 1);
    return links_->size() - 1;
  }

 private:
  std::vector<LinkAnalysis>* links_;
  std::map<std::pair<int, int>, DelayConfig> model_;
  std::map<std::pair<int, int>, std::size_t> index_;
  Timeline timeline_;
  bool changes_delay_ = false;  // some channel event gives a delay model
};

/// Whether an event's drawn delay is a draw of its link's model to check: a decision that
/// sent nothing (modem busy, sender silent) drew none, an out-of-range one carries the
/// delay of a range beyond max_range_m, and so may a link-down one of an acoustic link
/// (the link was down whatever the range).
bool CheckedDelay(const ChannelEventRecord& e, const DelayConfig& model) {
  if (NotTransmitted(e.status) || e.status == kRange) return false;
  return !(e.status == kLinkDown && model.kind == DelayKind::kAcoustic);
}

/// Counts one possible decision in its link's figures.
void CountStatus(std::int8_t status, LinkAnalysis* l) {
  if (status == kBusy) {  // never transmitted: not sent
    ++l->skipped_busy;
    return;
  }
  if (status == kSilent) {
    ++l->skipped_silent;
    return;
  }
  ++l->sent;
  switch (status) {
    case kDelivered: ++l->delivered; break;
    case kLoss: ++l->dropped_loss; break;
    case kQueue: ++l->dropped_queue; break;
    case kRange: ++l->dropped_range; break;
    case kLinkDown: ++l->dropped_link_down; break;
    case kDeaf: ++l->dropped_deaf; break;
    default: ++l->dropped_invalid; break;
  }
}

/// Link index of an event left out (at an impossible time).
constexpr std::uint32_t kNoLink = std::numeric_limits<std::uint32_t>::max();

/// The scenario's tau for event e, counting a mismatch with the drawn delay. Uniform: the
/// drawn one (a draw cannot be recomputed). Acoustic: the drawn one, checked only against
/// the model's bounds [processing_s, max_range_m / sound_speed_mps + processing_s +
/// jitter_s]: the range it used is not recomputed from the logged states.
double ConfiguredDelay(const DelayConfig& cfg, const ChannelEventRecord& e,
                       std::int64_t* mismatches) {
  if (cfg.kind == DelayKind::kUniform) return e.delay_s;
  if (cfg.kind == DelayKind::kAcoustic) {
    if (!(e.delay_s >= MinDelaySeconds(cfg) - 1e-9 && e.delay_s <= MaxDelaySeconds(cfg) + 1e-9)) {
      ++*mismatches;
    }
    return e.delay_s;
  }
  const double tau = DelaySeconds(cfg, ToSeconds(e.send_utime), nullptr);
  if (!(std::abs(tau - e.delay_s) <= 1e-9)) ++*mismatches;
  return tau;
}

/// Per event: its configured delay (checked against the drawn one) and its link's counts;
/// an event at an impossible time is counted as damaged only. Returns each event's link
/// index (kNoLink for a damaged one).
std::vector<std::uint32_t> CountChannelEvents(const std::vector<ChannelEventRecord>& ev,
                                              const StateTimeBounds& b, LinkTable* table,
                                              ChannelAnalysis* c) {
  ReserveHuge(&c->configured_delay_s, ev.size());
  c->configured_delay_s.resize(ev.size());
  std::vector<std::uint32_t> link_of_event(ev.size());
  const DelayConfig* last_cfg = nullptr;
  int last_from = -1, last_to = -1;
  for (std::size_t k = 0; k < ev.size(); ++k) {
    const ChannelEventRecord& e = ev[k];
    const EventTime when = ChannelEventTimeOf(e, b);
    if (when != EventTime::kPossible) {
      ++(when == EventTime::kSendImpossible ? c->events_sent_impossible
                                            : c->events_delivered_impossible);
      c->configured_delay_s[k] = kNaN;
      link_of_event[k] = kNoLink;
      continue;
    }
    if (e.sender != last_from || e.receiver != last_to) {
      last_from = e.sender;
      last_to = e.receiver;
      last_cfg = table->Model(e.sender, e.receiver);
    }
    const DelayConfig* model = table->ModelAt(last_cfg, e.sender, e.receiver, e.send_utime);
    const double cfg = model == nullptr || !CheckedDelay(e, *model)
                           ? e.delay_s
                           : ConfiguredDelay(*model, e, &c->model_mismatches);
    if (last_cfg == nullptr) ++c->unknown_links;
    c->configured_delay_s[k] = cfg;
    const std::size_t li = table->Of(e.sender, e.receiver);
    link_of_event[k] = static_cast<std::uint32_t>(li);
    CountStatus(e.status, &c->links[li]);
  }
  return link_of_event;
}

/// Event indices grouped by link (a counting sort): link li's events, in log order, are
/// order[start[li]] .. order[start[li + 1] - 1]. Events of no link (kNoLink) are left out.
struct EventsByLink {
  std::vector<std::size_t> start;
  std::vector<std::uint32_t> order;

  EventsByLink(const std::vector<std::uint32_t>& link_of_event, std::size_t links)
      : start(links + 1, 0) {
    for (std::uint32_t li : link_of_event) {
      if (li != kNoLink) ++start[li + 1];
    }
    for (std::size_t li = 0; li < links; ++li) start[li + 1] += start[li];
    order.resize(start[links]);
    std::vector<std::size_t> fill(start.begin(), start.end() - 1);
    for (std::size_t k = 0; k < link_of_event.size(); ++k) {
      if (link_of_event[k] != kNoLink) order[fill[link_of_event[k]]++] = static_cast<std::uint32_t>(k);
    }
  }
};

/// Values of one quantity, filled link by link: each link's values are a contiguous range
/// (seg[li] .. seg[li + 1]) for its quantiles, and the whole buffer gives the overall ones.
/// One buffer is reused for every quantity.
struct PerLinkValues {
  std::vector<double> buf;
  std::vector<std::size_t> seg;

  explicit PerLinkValues(std::size_t links) : seg(links + 1, 0) {}

  void Quantify(std::vector<LinkAnalysis>* links, Quantiles LinkAnalysis::*field,
                Quantiles* overall) {
    for (std::size_t li = 0; li < links->size(); ++li) {
      (*links)[li].*field = QuantilesOf(buf.data() + seg[li], buf.data() + seg[li + 1]);
    }
    *overall = QuantilesOf(buf.data(), buf.data() + buf.size());
  }
};

/// Realised delay and its error from the configured one, per link and overall.
void DelayQuantiles(const std::vector<ChannelEventRecord>& ev, const EventsByLink& by_link,
                    PerLinkValues* v, ChannelAnalysis* c) {
  for (int pass = 0; pass < 2; ++pass) {  // 0: realised delay, 1: its error
    v->buf.clear();
    ReserveHuge(&v->buf, ev.size());
    for (std::size_t li = 0; li < c->links.size(); ++li) {
      v->seg[li] = v->buf.size();
      for (std::size_t p = by_link.start[li]; p < by_link.start[li + 1]; ++p) {
        const std::size_t k = by_link.order[p];
        const ChannelEventRecord& e = ev[k];
        if (e.status != kDelivered) continue;
        const double real = ToSeconds(e.deliver_utime - e.send_utime);
        v->buf.push_back(pass == 0 ? real : real - c->configured_delay_s[k]);
      }
    }
    v->seg[c->links.size()] = v->buf.size();
    if (pass == 0) {
      v->Quantify(&c->links, &LinkAnalysis::realised_delay_s, &c->realised_delay_s);
    } else {
      v->Quantify(&c->links, &LinkAnalysis::delay_error_s, &c->delay_error_s);
    }
  }
}

/// What a follower keeps of one in-link, tick by tick, by the rules of Follower
/// (core/follower.cc): the newest message delivered so far (largest send time), which a
/// reset that starts and the link's entry into the topology in force both forget; a
/// delivery during a reset is dropped, and an inactive link or a reset tick is not used.
class LinkMemory {
 public:
  LinkMemory(const Timeline* tl, int link, int receiver)
      : tl_(tl != nullptr && (tl->switches_topology() || tl->resets()) ? tl : nullptr),
        link_(link), receiver_(receiver) {}
  /// The timeline's state at tick t, before the deliveries due at t (Follower::BeginTick).
  void BeginTick(Micros t) {
    in_use_ = true;
    if (tl_ == nullptr) return;
    const Micros start = tl_->ResetStart(receiver_, t);
    if (start != Timeline::kNoReset && start != reset_at_) have_ = false;
    reset_at_ = start;
    in_reset_ = start != Timeline::kNoReset;
    if (tl_->switches_topology()) {
      const bool active = link_ >= 0 && tl_->LinkActive(static_cast<std::size_t>(link_), t);
      if (active && !active_) have_ = false;
      active_ = active;
    }
    in_use_ = active_ && !in_reset_;
  }
  void Deliver(Micros send) {
    if (in_reset_) return;
    if (!have_ || send > newest_) newest_ = send;
    have_ = true;
  }
  bool in_use() const { return in_use_; }
  bool have() const { return have_; }
  Micros newest() const { return newest_; }

 private:
  const Timeline* tl_;
  int link_, receiver_;
  Micros reset_at_ = Timeline::kNoReset;
  bool in_reset_ = false, active_ = true, in_use_ = true, have_ = false;
  Micros newest_ = -1;
};

/// Age at use: at each of the receiver's ticks (its state samples) at which it uses the
/// link, the age of the newest message it keeps (LinkMemory); a message older than the
/// neighbour timeout is not used (a stale tick). Ticks with nothing kept (before the first
/// delivery, or after a reset or the link's entry into the topology) are counted apart.
void AgeAtUse(const RunData& run, const ValidStates& valid, const EventsByLink& by_link,
              PerLinkValues* v, ChannelAnalysis* c) {
  const std::vector<ChannelEventRecord>& ev = run.channel_events;
  const double timeout_s = run.has_scenario ? run.scenario.neighbour_timeout_s : kNaN;
  std::optional<Timeline> timeline;
  if (run.has_scenario && !run.scenario.events.empty()) timeline.emplace(run.scenario);
  v->buf.clear();
  std::vector<std::pair<Micros, Micros>> deliveries;  // (deliver, send) of one link
  for (std::size_t li = 0; li < c->links.size(); ++li) {
    LinkAnalysis& l = c->links[li];
    v->seg[li] = v->buf.size();
    if (l.to < 1) continue;
    deliveries.clear();
    for (std::size_t p = by_link.start[li]; p < by_link.start[li + 1]; ++p) {
      const ChannelEventRecord& e = ev[by_link.order[p]];
      if (e.status == kDelivered) deliveries.emplace_back(e.deliver_utime, e.send_utime);
    }
    if (!std::is_sorted(deliveries.begin(), deliveries.end())) {
      std::sort(deliveries.begin(), deliveries.end());
    }
    LinkMemory memory(timeline ? &*timeline : nullptr,
                      timeline ? timeline->LinkIndex(l.from, l.to) : -1, l.to);
    std::size_t d = 0;
    for (const StateMsg& m : valid(l.to)) {
      memory.BeginTick(m.utime);
      for (; d < deliveries.size() && deliveries[d].first <= m.utime; ++d) {
        memory.Deliver(deliveries[d].second);
      }
      if (!memory.in_use()) continue;
      if (!memory.have()) {
        ++l.ticks_before_first;
        continue;
      }
      const double age = ToSeconds(m.utime - memory.newest());
      if (std::isfinite(timeout_s) && age > timeout_s) {
        ++l.ticks_stale;
        continue;
      }
      v->buf.push_back(age);
    }
  }
  v->seg[c->links.size()] = v->buf.size();
  v->Quantify(&c->links, &LinkAnalysis::age_at_use_s, &c->age_at_use_s);
}

void AnalyseChannel(const RunData& run, const ValidStates& valid, RunAnalysis* a) {
  ChannelAnalysis& c = a->channel;
  LinkTable table(run, &c.links);
  std::vector<std::uint32_t> link_of_event =
      CountChannelEvents(run.channel_events, a->bounds, &table, &c);
  c.events_damaged = c.events_sent_impossible + c.events_delivered_impossible;
  const EventsByLink by_link(link_of_event, c.links.size());
  std::vector<std::uint32_t>().swap(link_of_event);
  PerLinkValues values(c.links.size());
  DelayQuantiles(run.channel_events, by_link, &values, &c);
  AgeAtUse(run, valid, by_link, &values, &c);

  for (const LinkAnalysis& l : c.links) {
    c.sent += l.sent;
    c.delivered += l.delivered;
    c.dropped_loss += l.dropped_loss;
    c.dropped_queue += l.dropped_queue;
    c.dropped_invalid += l.dropped_invalid;
    c.dropped_range += l.dropped_range;
    c.skipped_busy += l.skipped_busy;
    c.skipped_silent += l.skipped_silent;
    c.dropped_link_down += l.dropped_link_down;
    c.dropped_deaf += l.dropped_deaf;
  }
  c.dropped = c.dropped_loss + c.dropped_queue + c.dropped_invalid + c.dropped_range +
              c.dropped_link_down + c.dropped_deaf;
  a->summary.delivered = c.delivered;
  a->summary.dropped = c.dropped;
}

void AnalyseHealth(const RunData& run, RunAnalysis* a) {
  std::map<int, ProcessAnalysis> by_id;
  for (const HealthRecord& h : run.health) {
    ProcessAnalysis& p = by_id[h.process_id];
    p.id = h.process_id;
    // The newest in mission time (of two at one time, the later in the log): a report
    // replayed later in the log, validly signed, must not hide what came after it.
    if (p.reports == 0 || h.utime >= p.last.utime) p.last = h;
    ++p.reports;
  }
  for (const auto& [id, p] : by_id) {
    a->processes.push_back(p);
    if (id == -1) {
      a->channel.release_error_p99_s = p.last.lateness_p99_s;
    } else {
      a->summary.lateness_p99_s = std::max(a->summary.lateness_p99_s, p.last.lateness_p99_s);
      a->summary.overruns += p.last.overruns;
    }
  }
  a->summary.release_error_p99_s = a->channel.release_error_p99_s;
}

/// Interrupted and failed processes from the run statuses, and the mode the log shows.
void AnalyseStatuses(const RunData& run, RunAnalysis* a) {
  bool emulator = false;
  for (const HealthRecord& h : run.health) emulator = emulator || h.process_id == -1;
  for (const StatusRecord& st : run.statuses) {
    emulator = emulator || st.vehicle_id == -1;
    if (st.state == "interrupted") a->interrupted = true;
    if (st.state == "failed" || st.state == "vehicle_lost") {
      const std::string who = st.vehicle_id == -1   ? "channel emulator"
                              : st.vehicle_id == -2 ? "shoal sim / launcher"
                                                    : "vehicle " + std::to_string(st.vehicle_id);
      a->problems.push_back(who + ": " + st.state + (st.message.empty() ? "" : ": " + st.message));
    }
  }
  if (!run.clock.empty()) {
    a->mode = emulator ? "lockstep" : "sim";
  } else {
    a->mode = emulator ? "realtime" : "unknown";
  }
}

/// Control period: the scenario's, else the clock's, else the leader's sample spacing
/// (the median of its first steps, which one state at a damaged time cannot move).
Micros ControlPeriodOf(const RunData& run) {
  if (run.has_scenario) return run.scenario.period_us();
  if (!run.clock.empty() && run.clock.front().period_us > 0) return run.clock.front().period_us;
  if (run.vehicles.empty()) return 0;
  const std::vector<StateMsg>& s = run.vehicles.front().samples;
  std::vector<Micros> dt;
  for (std::size_t k = 1; k < s.size() && k < 1000; ++k) {
    if (s[k - 1].utime >= 0) dt.push_back(s[k].utime - s[k - 1].utime);
  }
  if (dt.empty()) return 0;
  std::nth_element(dt.begin(), dt.begin() + dt.size() / 2, dt.end());
  return dt[dt.size() / 2];
}

/// How far a vehicle's states run without a gap of more than a minute (and 1000 periods):
/// a state that damage or forgery put far away is not part of it. -1 if it has no state
/// at a non-negative time.
Micros ContiguousReach(const std::vector<StateMsg>& s, Micros period) {
  constexpr Micros kMinGap = 60000000;  // 1 min
  const Micros gap = period <= kMinGap / 1000 ? kMinGap
                     : period < kMinGap        ? 1000 * period
                                               : std::numeric_limits<Micros>::max();
  auto it = std::lower_bound(s.begin(), s.end(), Micros{0},
                             [](const StateMsg& m, Micros t) { return m.utime < t; });
  if (it == s.end()) return -1;
  Micros reach = it->utime;
  for (++it; it != s.end() && it->utime - reach <= gap; ++it) reach = it->utime;
  return reach;
}

/// The largest time that a majority of the vehicles with states reach (-1: none): one
/// vehicle's damaged or forged times cannot move it while two or more vehicles report.
Micros MajorityEnd(const RunData& run, Micros period) {
  std::vector<Micros> last;
  for (const VehicleTrack& v : run.vehicles) {
    const Micros r = ContiguousReach(v.samples, period);
    if (r >= 0) last.push_back(r);
  }
  if (last.empty()) return -1;
  std::sort(last.begin(), last.end());
  const std::size_t majority = last.size() / 2 + 1;
  return last[last.size() - majority];
}

/// a + b for b >= 0, at most the largest Micros.
Micros SaturatingAdd(Micros a, Micros b) {
  constexpr Micros kMax = std::numeric_limits<Micros>::max();
  return a > kMax - b ? kMax : a + b;
}

/// The largest delay [us] any link of the scenario can draw (each link's own model or the
/// default), rounded up, plus 1 us for DeliveryTime's rounding of tau to microseconds.
Micros LargestDelayUs(const Scenario& s) {
  double worst = 0.0;
  const auto add = [&](const DelayConfig& c) {
    if (c.kind == DelayKind::kNone) return;
    // MaxDelaySeconds is base + amplitude; |amplitude| keeps a negative one a bound too.
    worst = std::max({worst, MaxDelaySeconds(c), c.base_s + std::fabs(c.amplitude_s)});
  };
  add(s.delay);
  for (const Link& l : BuildAllLinks(s)) add(l.delay);
  for (const DelayConfig& c : Timeline(s).EventDelays()) add(c);
  const double us = std::ceil(worst * 1e6) + 1.0;
  return us < 9e18 ? static_cast<Micros>(us) : std::numeric_limits<Micros>::max();
}

/// The last possible delivery time of a run whose states end at limit_us: see
/// StateTimeBounds::deliver_limit_us.
Micros DeliverLimitOf(const RunData& run, Micros limit_us, Micros period) {
  if (limit_us < 0) return -1;
  const Micros delay = run.has_scenario ? LargestDelayUs(run.scenario) : limit_us;
  return SaturatingAdd(SaturatingAdd(limit_us, delay), std::max<Micros>(period, 0));
}

/// Ticks run, states the log should hold, states at impossible times, and the recording's
/// wall-clock span.
void AnalyseTicks(const RunData& run, const StateTimeBounds& b, const ValidStates& valid,
                  RunAnalysis* a) {
  std::int64_t max_samples = 0;
  for (std::size_t id = 0; id < run.vehicles.size(); ++id) {
    const std::vector<StateMsg>& all = run.vehicles[id].samples;
    const Span s = valid(static_cast<int>(id));
    max_samples = std::max<std::int64_t>(max_samples, s.size());
    a->states_negative_time += static_cast<std::int64_t>(s.first());
    a->states_after_end += static_cast<std::int64_t>(all.size() - s.first() - s.size());
  }
  a->states_damaged = a->states_negative_time + a->states_after_end;
  a->end_s = b.limit_us >= 0 ? ToSeconds(b.limit_us) : kNaN;
  a->ticks = run.clock.empty() ? max_samples : ClockTicks(run);
  if (a->period_us > 0 && b.expected_end_us >= 0) {
    a->states_expected = (b.expected_end_us / a->period_us + 1) * (run.followers + 1);
  }
  // lcm-logger stamps events with the wall clock (us since 1970); shoal sim with
  // simulated time. Only the former gives a recording span: from the first state (tick 0)
  // to the last event, as shoal run measures its run, without the processes' start-up
  // before it. A retimed log's stamps are mission time: its marker keeps the original's.
  const RetimedFrom& r = run.retimed_from;
  const std::int64_t first_event = r.retimed ? r.first_timestamp : run.first_timestamp;
  const std::int64_t first_state = r.retimed ? r.first_state_timestamp : run.first_state_timestamp;
  const std::int64_t last = r.retimed ? r.last_timestamp : run.last_timestamp;
  const std::int64_t first = first_state >= first_event ? first_state : first_event;
  if (first_event > 1000000000000000LL) a->wall_time_s = ToSeconds(last - first);
}

/// The follower that diverged first, as shoal sim defines it: non-finite state or
/// |pitch| > 80 deg.
void FindDivergence(const RunData& run, const ValidStates& valid, RunAnalysis* a) {
  Micros first = -1;
  for (int i = 1; i <= run.followers && i < static_cast<int>(run.vehicles.size()); ++i) {
    Micros t = -1;
    for (const StateMsg& m : valid(i)) {
      if (!m.AllFinite() || std::abs(m.eta(3)) > kPitchLimitRad) {
        t = m.utime;
        break;
      }
    }
    if (t >= 0 && (first < 0 || t < first)) {
      first = t;
      a->diverged_follower = i;
    }
  }
  // shoal sim stops at the tick whose integration diverged, before that state is published:
  // its last status names the follower ("follower 2 diverged at t = 1.8 s").
  for (const StatusRecord& st : run.statuses) {
    int id = 0;
    char tail[16] = {};
    if (a->diverged_follower == 0 && st.vehicle_id == -2 && st.state == "failed" &&
        std::sscanf(st.message.c_str(), "follower %d %15s", &id, tail) == 2 &&
        std::string(tail) == "diverged" && id >= 1 && id <= run.followers) {
      a->diverged_follower = id;
    }
  }
}

/// The restarts the statuses name (a restarted process repeats its status until the clock
/// reaches it: one restart per process and message), and the states each left missing. A
/// restarted lockstep emulator learns the tick from the processes: its time is that of its
/// next "running" status.
void AnalyseRestarts(const RunData& run, RunAnalysis* a) {
  for (std::size_t k = 0; k < run.statuses.size(); ++k) {
    const StatusRecord& st = run.statuses[k];
    if (st.state != "restarted" || st.vehicle_id < -1) continue;  // -1: the emulator
    const bool repeated = std::any_of(a->restarts.begin(), a->restarts.end(), [&](const auto& r) {
      return r.id == st.vehicle_id && r.message == st.message;
    });
    if (repeated) continue;
    RestartAnalysis r;
    r.id = st.vehicle_id;
    r.utime = st.utime;
    r.message = st.message;
    for (std::size_t j = k + 1; r.id == -1 && j < run.statuses.size(); ++j) {
      if (run.statuses[j].vehicle_id != -1 || run.statuses[j].state != "running") continue;
      r.utime = run.statuses[j].utime;
      break;
    }
    if (r.id >= 0 && r.id < static_cast<int>(run.vehicles.size()) && a->period_us > 0) {
      const std::vector<StateMsg>& v = run.vehicles[r.id].samples;
      const auto after = std::lower_bound(
          v.begin(), v.end(), r.utime, [](const StateMsg& m, Micros t) { return m.utime < t; });
      const Micros from = after == v.begin() ? -a->period_us : std::prev(after)->utime;
      r.states_missing = std::max<Micros>(0, (r.utime - from) / a->period_us - 1);
    }
    a->states_missing_in_restarts += r.states_missing;
    a->restarts.push_back(r);
  }
}

void AnalyseRunLevel(const RunData& run, const StateTimeBounds& b, const ValidStates& valid,
                     RunAnalysis* a) {
  AnalyseStatuses(run, a);
  a->period_us = ControlPeriodOf(run);
  AnalyseRestarts(run, a);
  AnalyseTicks(run, b, valid, a);
  FindDivergence(run, valid, a);

  const Span lead = valid(0);
  if (!lead.empty()) {
    double len = 0.0;
    for (std::size_t k = 1; k < lead.size(); ++k) {
      len += (lead[k].eta.head<3>() - lead[k - 1].eta.head<3>()).norm();
    }
    a->leader_path_length_m = len;
    a->leader_start_m = lead.front().eta.head<3>();
    a->leader_end_m = lead.back().eta.head<3>();
  }
}

}  // namespace

const char* ChannelStatusKey(int status) {
  static const char* const kKeys[kChannelStatuses] = {
      "delivered",          "dropped_loss",  "dropped_queue",     "dropped_invalid", "skipped_modem_busy",
      "dropped_range", "skipped_silent", "dropped_link_down", "dropped_deaf"};
  return status >= 0 && status < kChannelStatuses ? kKeys[status] : "invalid";
}

Quantiles QuantilesOf(double* begin, double* end) {
  Quantiles q;
  const std::ptrdiff_t n = end - begin;
  q.count = n;
  if (n <= 0) return q;
  auto rank = [&](double p) {
    return begin + static_cast<std::ptrdiff_t>(p * static_cast<double>(n - 1) + 0.5);
  };
  double sum = 0.0;
  q.min = q.max = *begin;
  for (const double* x = begin; x != end; ++x) {
    sum += *x;
    q.min = std::min(q.min, *x);
    q.max = std::max(q.max, *x);
  }
  q.mean = sum / static_cast<double>(n);
  double* r50 = rank(0.5);
  std::nth_element(begin, r50, end);
  q.p50 = *r50;
  double* r99 = rank(0.99);
  std::nth_element(r50, r99, end);
  q.p99 = *r99;
  return q;
}

Quantiles QuantilesOf(std::vector<double>* v) { return QuantilesOf(v->data(), v->data() + v->size()); }

StateTimeBounds StateTimeBoundsOf(const RunData& run) {
  constexpr Micros kMax = std::numeric_limits<Micros>::max();
  StateTimeBounds b;
  const Micros period = ControlPeriodOf(run);
  const Micros majority = MajorityEnd(run, period);
  if (run.has_scenario) {
    // The scenario's last tick, or later if most vehicles ran longer: shoal sim and shoal
    // run --duration lengthen a run but log the scenario's own text.
    b.declared = true;
    b.limit_us = std::max(run.scenario.final_tick() * run.scenario.period_us(), majority);
    b.expected_end_us = b.limit_us;
  } else if (majority >= 0) {
    // Nothing declared: a vehicle may outlive the others (the others were lost), but not
    // by more than the run's whole length again; a state beyond that is damaged.
    const Micros slack = std::max<Micros>(majority, period);
    b.limit_us = majority > kMax - slack ? kMax : majority + slack;
    b.expected_end_us = majority;
  }
  // A run that ran its final tick says where it ended (sim and lockstep clocks): the
  // expectation of a run shortened with --duration; a final tick beyond the limit is
  // damaged and ignored.
  bool final_seen = false;
  for (auto c = run.clock.rbegin(); c != run.clock.rend(); ++c) {
    if (c->final_tick && c->last_utime() >= 0 && c->last_utime() <= b.limit_us) {
      b.expected_end_us = c->last_utime();
      final_seen = true;
      break;
    }
  }
  // Without it (a stream that missed the final clock window, a real-time run), the
  // run-level "finished" status says the same: the emulator and shoal sim stamp it with the
  // last tick; an "interrupted" or "failed" one (shoal sim stops where a follower diverges)
  // with the tick where the run was stopped, up to which its states are expected.
  bool finished_seen = false;
  for (auto st = run.statuses.rbegin(); !final_seen && st != run.statuses.rend(); ++st) {
    const std::optional<RunState> state = ParseRunState(st->state);
    if (st->vehicle_id < 0 &&
        (state == RunState::kFinished || state == RunState::kInterrupted ||
         state == RunState::kFailed) &&
        st->utime >= 0 && st->utime <= b.limit_us) {
      b.expected_end_us = st->utime;
      finished_seen = state == RunState::kFinished;
      break;
    }
  }
  // A run that ran to its final tick (a clock's final window, or "finished") has no state
  // after it: a run shortened with --duration ends there, not at the scenario's end. (An
  // interrupted or failed run keeps the wider limit: its processes may have gone on a tick
  // or two past the stamp.)
  if (final_seen || finished_seen) b.limit_us = b.expected_end_us;
  b.deliver_limit_us = DeliverLimitOf(run, b.limit_us, period);
  return b;
}

EventTime ChannelEventTimeOf(const ChannelEventRecord& e, const StateTimeBounds& b) {
  if (e.send_utime < 0 || (b.limit_us >= 0 && e.send_utime > b.limit_us)) {
    return EventTime::kSendImpossible;
  }
  if (e.status != kDelivered) return EventTime::kPossible;
  if (e.deliver_utime < e.send_utime ||
      (b.deliver_limit_us >= 0 && e.deliver_utime > b.deliver_limit_us)) {
    return EventTime::kDeliveryImpossible;
  }
  return EventTime::kPossible;
}

std::int64_t DropImpossibleTimes(RunData* run) {
  const StateTimeBounds b = StateTimeBoundsOf(*run);
  std::int64_t states = 0;
  for (VehicleTrack& v : run->vehicles) {
    const Span s(v.samples, 0, b.limit_us);
    states += static_cast<std::int64_t>(v.samples.size() - s.size());
    if (s.size() == v.samples.size()) continue;
    const auto first = v.samples.begin() + static_cast<std::ptrdiff_t>(s.first());
    v.samples.erase(first + static_cast<std::ptrdiff_t>(s.size()), v.samples.end());
    v.samples.erase(v.samples.begin(), first);
  }
  std::vector<ChannelEventRecord>& ev = run->channel_events;
  const auto impossible = [&](const ChannelEventRecord& e) {
    return ChannelEventTimeOf(e, b) != EventTime::kPossible;
  };
  const std::size_t before = ev.size();
  ev.erase(std::remove_if(ev.begin(), ev.end(), impossible), ev.end());
  const auto events = static_cast<std::int64_t>(before - ev.size());
  if (states + events > 0) {
    char end[96];
    std::snprintf(end, sizeof(end), "the run's end at %.6g s, or delivered after %.6g s",
                  ToSeconds(b.limit_us), ToSeconds(b.deliver_limit_us));
    run->warnings.push_back(std::to_string(states) + " vehicle states and " +
                            std::to_string(events) +
                            " channel events at impossible times (negative, after " + end +
                            " or before sent) are damaged and left out");
  }
  return states + events;
}

RunAnalysis AnalyseRun(const RunData& run) {
  RunAnalysis a;
  const StateTimeBounds bounds = StateTimeBoundsOf(run);
  a.bounds = bounds;
  const ValidStates valid(run, bounds);
  a.has_formation = run.has_scenario && !valid(0).empty() &&
                    static_cast<int>(run.scenario.offsets_m.size()) == run.followers;
  AnalyseRunLevel(run, bounds, valid, &a);
  a.summary.states = run.state_samples() - a.states_damaged;
  AnalyseFollowers(run, valid, &a);
  const bool events = run.has_scenario && !run.scenario.events.empty();
  std::vector<WorstSample> worst;
  if (a.has_formation) AnalyseFormation(run, valid, &a, events ? &worst : nullptr);
  if (!a.has_formation || a.complete_samples == 0) {
    // No tick with a state of every vehicle: the swarm's errors are unknown, not zero
    // (each follower's own, against the leader, stand); the latest state time instead.
    a.summary.final_worst = NaNErrors();
    a.summary.max_position_error_m = kNaN;
    a.summary.converged = false;
    a.complete_samples =
        ForEachCompleteSample(run, valid, [](const StateMsg&, const std::vector<const StateMsg*>&) {});
    Micros t = 0;
    for (int id = 0; id < static_cast<int>(run.vehicles.size()); ++id) {
      if (!valid(id).empty()) t = std::max(t, valid(id).back().utime);
    }
    a.summary.sim_time_s = ToSeconds(t);
  }
  AnalyseChannel(run, valid, &a);
  AnalyseHealth(run, &a);
  // A real-time emulator judges deafness at send + tau exactly (no tick grid).
  if (events) {
    // Up to where the run ran (a --duration shorter than the scenario's ends it earlier).
    const double ran_to_s =
        bounds.expected_end_us >= 0 ? ToSeconds(bounds.expected_end_us) : a.end_s;
    a.events = AnalyseEvents(run, worst, ran_to_s, a.mode == "realtime" ? 0 : a.period_us);
  }
  return a;
}

bool SummariseRunLog(const std::string& path, const Scenario& s, RunSummary* out) {
  *out = RunSummary();
  if (access(path.c_str(), R_OK) != 0) return false;
  RunData run;
  LoadOptions opt;
  opt.scenario = &s;
  std::string error;
  if (!LoadRunLog(path, opt, &run, &error)) return true;  // no Shoal data: all zero
  *out = AnalyseRun(run).summary;
  return true;
}

}  // namespace shoal
