#include "core/swarm.h"

#include <cmath>

namespace shoal {

Swarm::Swarm(const Scenario& s, double duration_s)
    : topo_(Topology::Build(s.followers, s.edges, s.leader_links)),
      period_us_(s.period_us()),
      final_tick_(s.final_tick(duration_s)),
      leader_(s),
      channel_(BuildLinks(s, topo_), period_us_),
      metrics_(s.offsets_m, s.metrics),
      env_(std::make_shared<Environment>(s.leader, s.delay, s.disturbance.relative_to_leader)),
      warm_env_(s.disturbance.kind == DisturbanceKind::kPaperExample2) {
  for (int i = 1; i <= s.followers; ++i) {
    followers_.push_back(std::make_unique<Follower>(s, topo_, i, env_));
  }
  published_.resize(followers_.size());
  decisions_.reserve(topo_.Links().size());
}

bool Swarm::Step(SwarmObserver* obs) {
  if (tick_ > final_tick_ || diverged_id_ != 0) return false;
  const Micros now = tick_ * period_us_;
  const bool final_tick = tick_ == final_tick_;
  if (obs) obs->OnTick(tick_, now, final_tick);

  channel_.DeliverDue(now, [&](int receiver, const StateMsg& m) {
    if (obs) obs->OnDeliver(receiver, m);
    followers_[receiver - 1]->Receive(m);
  });

  if (warm_env_) env_->Warm(now);
  const StateMsg& lm = leader_.Tick(now);
  for (std::size_t i = 0; i < followers_.size(); ++i) {
    published_[i] = &followers_[i]->Tick(now);
  }
  metrics_.Add(lm, published_);

  auto publish = [&](const StateMsg& m) {
    if (obs) obs->OnState(m);
    decisions_.clear();
    channel_.Submit(m.vehicle_id, m.seq, m.utime, m, &decisions_);
    for (const ChannelDecision& d : decisions_) {
      if (d.status == ChannelDecision::kDelivered) {
        ++delivered_;
      } else {
        ++dropped_;
      }
      if (obs) obs->OnChannel(d);
    }
  };
  publish(lm);
  for (const StateMsg* m : published_) publish(*m);

  const Micros per_second = static_cast<Micros>(1000000);
  if (obs && ((now % per_second) < period_us_ || final_tick)) {
    for (const auto& f : followers_) obs->OnHealth(now, *f);
  }
  for (const auto& f : followers_) {
    if (f->diverged()) {
      diverged_id_ = f->id();
      break;
    }
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
