#include "core/swarm.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace shoal {

// Cost of a tick, a follower-tick and a link-tick of shoal sim, fitted (within a factor of
// two) to scenarios/paper_example2.toml (5 followers: 30001 ticks in 0.35 s), to 200
// followers with 3891 links (3001 ticks in 0.7 s) on a current PC, and to densely linked
// swarms (every follower hears every other, 0.1 s delay) on a 2-vCPU AMD EPYC VM, shared,
// 2026-12-01 (docs/benchmarks.md), seconds per tick:
//   followers (links)   100 (9901)   200 (39801)    400 (159601)   1000 (999001)
//   measured            0.00042      0.0028-0.0033  0.018-0.025    0.058-0.12
// and 1000 chained followers (1000 links): 0.00075. A link-tick costs more as the links
// grow (their pending deliveries and the neighbours' histories leave the caches): from
// 0.04 us to 0.1 us at 150000 links and beyond (a constant 0.03 us put 1000 dense
// followers at a quarter of their time).
namespace {
constexpr double kSecondsPerTick = 3e-6;
constexpr double kSecondsPerFollowerTick = 1.2e-6;
constexpr double kSecondsPerLinkTickSmall = 0.04e-6;
constexpr double kSecondsPerLinkTickLarge = 0.1e-6;
constexpr double kLinksLarge = 150000.0;

double SecondsPerLinkTick(double links) {
  return kSecondsPerLinkTickSmall + (kSecondsPerLinkTickLarge - kSecondsPerLinkTickSmall) *
                                        std::min(1.0, links / kLinksLarge);
}
}  // namespace
// Per pending delivery: its payload, its queue entry and their bookkeeping.
constexpr double kBytesPerPending = sizeof(StateMsg) + 64.0;
constexpr double kMaxPending = 1 << 20;  // Channel's default max_pending

RunEstimate EstimateRun(const Scenario& s, double duration_s) {
  RunEstimate e;
  e.ticks = s.final_tick(duration_s) + 1;
  const Topology topo = UnionTopology(s);
  e.links = static_cast<std::int64_t>(topo.Links().size());
  const double history = static_cast<double>(Follower::HistoryCapacity(s, duration_s));
  double max_delay = MaxDelaySeconds(BuildLinks(s, topo));
  for (const ScenarioEvent& ev : s.events) {
    if (ev.delay) max_delay = std::max(max_delay, MaxDelaySeconds(*ev.delay));
  }
  const double delay_ticks = std::min(static_cast<double>(e.ticks),
                                      std::ceil(max_delay * 1e6 /
                                                static_cast<double>(s.period_us())) + 2.0);
  const double pending = std::min(kMaxPending, delay_ticks * static_cast<double>(e.links));
  e.memory_bytes = s.followers * history * sizeof(HistorySample) + pending * kBytesPerPending;
  // A follower's tick was measured with one RK4 step (Example 2), about half of it that
  // step: each further step adds that half.
  const double substeps = static_cast<double>(Follower::Rk4Substeps(s));
  const double per_tick = kSecondsPerTick +
                          s.followers * kSecondsPerFollowerTick * 0.5 * (1.0 + substeps) +
                          static_cast<double>(e.links) *
                              SecondsPerLinkTick(static_cast<double>(e.links));
  e.wall_seconds = static_cast<double>(e.ticks) * per_tick;
  return e;
}

std::string RunEstimate::Describe(int followers) const {
  char text[160];
  const double hours = wall_seconds / 3600.0;
  std::snprintf(text, sizeof(text),
                "%.3g ticks x %d followers and %lld links: about %.3g h and %.3g GiB of memory",
                static_cast<double>(ticks), followers, static_cast<long long>(links), hours,
                memory_bytes / (1 << 30));
  return text;
}

std::string LargeRunRefusal(const Scenario& s, double duration_s, RunPace pace,
                            const std::string& shorten, const std::string& anyway) {
  RunEstimate e = EstimateRun(s, duration_s);
  constexpr double kLockstepOverSim = 20.0;  // 600 s of Example 2: 6.1 s against 0.35 s
  if (pace == RunPace::kLockstep) e.wall_seconds *= kLockstepOverSim;
  if (pace == RunPace::kRealtime) {
    e.wall_seconds = static_cast<double>(e.ticks) * static_cast<double>(s.period_us()) * 1e-6;
  }
  if (!e.large()) return "";
  return "refusing a large run (" + e.Describe(s.followers) + "; the limits are 1 h and 4 GiB); shorten " +
         shorten + ", or pass " + anyway + " to run it anyway";
}

Swarm::Swarm(const Scenario& s, double duration_s)
    : topo_(UnionTopology(s)),
      timeline_(s.events.empty() ? nullptr : std::make_shared<const Timeline>(s)),
      period_us_(s.period_us()),
      final_tick_(s.final_tick(duration_s)),
      leader_(s),
      channel_(BuildLinks(s, topo_), period_us_, std::size_t{1} << 20, ModemIntervals(s),
               timeline_),
      metrics_(s.offsets_m, s.metrics),
      env_(std::make_shared<Environment>(s.leader, s.delay, s.disturbance.relative_to_leader)),
      warm_env_(s.disturbance.kind == DisturbanceKind::kPaperExample2) {
  for (int i = 1; i <= s.followers; ++i) {
    followers_.push_back(std::make_unique<Follower>(s, topo_, i, env_, duration_s, timeline_));
  }
  published_.resize(followers_.size());
  jobs_.resize(followers_.size());
  forces_.resize(followers_.size());
  together_ = true;
  for (const auto& f : followers_) together_ = together_ && f->SamePlant(*followers_.front());
  decisions_.reserve(topo_.Links().size());
}

bool Swarm::Step(SwarmObserver* obs) {
  if (tick_ > final_tick_ || diverged_id_ != 0) return false;
  const Micros now = tick_ * period_us_;
  const bool final_tick = tick_ == final_tick_;
  if (obs) obs->OnTick(tick_, now, final_tick);

  // The timeline of this tick applies to what is delivered at it (a controller reset
  // that ends now keeps this tick's deliveries).
  if (timeline_) {
    for (const auto& f : followers_) f->BeginTick(now);
  }
  channel_.DeliverDue(now, [&](int receiver, const StateMsg& m) {
    if (obs) obs->OnDeliver(receiver, m);
    followers_[receiver - 1]->Receive(m);
  });

  if (warm_env_) env_->Warm(now);
  const StateMsg& lm = leader_.Tick(now);
  if (together_) {
    // The inner loops and the plants run together (in vector lanes), to the bits of Tick().
    int forced = 0;
    for (std::size_t i = 0; i < followers_.size(); ++i) {
      published_[i] = &followers_[i]->Control(now);
      if (ForceJob* j = followers_[i]->force_job()) forces_[forced++] = j;
    }
    const Follower& first = *followers_.front();
    SaturatedFeedbackLineariseMany(first.model(), forces_.data(), forced);
    for (std::size_t i = 0; i < followers_.size(); ++i) {
      followers_[i]->Forced();
      jobs_[i] = followers_[i]->plant_job();
    }
    IntegrateMany(first.model(), ToSeconds(period_us_), first.substeps(), jobs_.data(),
                  static_cast<int>(jobs_.size()));
    for (const auto& f : followers_) f->Integrated();
  } else {
    for (std::size_t i = 0; i < followers_.size(); ++i) {
      published_[i] = &followers_[i]->Tick(now);
    }
  }
  metrics_.Add(lm, published_);

  // Inlined at both calls (a link-time optimised build would otherwise call it).
  auto publish = [&](const StateMsg& m) __attribute__((always_inline)) {
    if (obs) obs->OnState(m);
    decisions_.clear();
    channel_.Submit(m.vehicle_id, m.seq, m.utime, m, &decisions_, m.eta.head<3>());
    for (const ChannelDecision& d : decisions_) {
      if (d.status == ChannelDecision::kDelivered) {
        ++delivered_;
      } else if (!NotTransmitted(d.status)) {
        ++dropped_;
      }
      if (obs) obs->OnChannel(d);
    }
  };
  publish(lm);
  for (const StateMsg* m : published_) publish(*m);

  for (const auto& f : followers_) {
    if (f->diverged()) {
      diverged_id_ = f->id();
      break;
    }
  }
  // A run that stops here, at its last tick or where a follower diverged, reports its
  // followers' health as it stands.
  const Micros per_second = static_cast<Micros>(1000000);
  if (obs && ((now % per_second) < period_us_ || final_tick || diverged_id_ != 0)) {
    for (const auto& f : followers_) obs->OnHealth(now, *f);
  }
  last_utime_ = now;
  ++tick_;
  return tick_ <= final_tick_ && diverged_id_ == 0;
}

void Swarm::Run(SwarmObserver* obs, const volatile bool* stop) {
  while ((stop == nullptr || !*stop) && Step(obs)) {
  }
}

}  // namespace shoal
