#include "vehicle/vehicle_app.h"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <iostream>
#include <shoal/vehicle_state_t.hpp>

#include "core/channel_model.h"
#include "core/topology.h"
#include "runtime/channels.h"
#include "runtime/messages.h"

namespace shoal {

namespace {
// Lockstep bound on what a vehicle holds: far more than a run ever has in flight (a
// window's deliveries), so that only forged traffic can reach it.
constexpr std::size_t kMaxHeldDeliveries = 4096;

// A slot for every neighbour any topology of the timeline gives this vehicle.
Topology TopologyOf(const Scenario& s) { return UnionTopology(s); }
}  // namespace

VehicleApp::VehicleApp(const Scenario& s, int id, Mode mode, std::int64_t t0_ns, double duration_s,
                       Bus* bus, Bus* rx_bus)
    : ClockedNode(s, id, mode, t0_ns, duration_s, bus, rx_bus),
      follower_(s, TopologyOf(s), id, nullptr, duration_s) {
  // Lockstep: a message is delivered (listed) at the latest one period after send time +
  // the largest delay of the links' delay models.
  double max_delay = MaxDelaySeconds(BuildLinks(s, TopologyOf(s)));
  for (const ScenarioEvent& e : s.events) {
    if (e.delay) max_delay = std::max(max_delay, MaxDelaySeconds(*e.delay));
  }
  listable_us_ = static_cast<Micros>(std::ceil(max_delay * 1e6)) + 2 * period_us();
}

void VehicleApp::SubscribeInputs() { SubscribeInput(channels::Rx(id()), kRxKind); }

bool VehicleApp::OnInput(int /*kind*/, const unsigned char* data, int size) {
  vehicle_state_t m{};
  if (!Decode(data, size, &m)) {
    ++rx_counters_.bad_rx;
    return false;
  }
  const StateMsg msg = FromLcm(m);
  if (mode() != Mode::kLockstep) {
    // The timeline of the tick about to be stepped decides (a reset controller keeps
    // nothing); then Receive validates and counts (NaN/Inf, unknown, old).
    follower_.BeginTick(next_tick() * period_us());
    follower_.Receive(msg);
    return false;
  }
  // Lockstep: hold it until the clock tick that lists it, and apply it there (Receive
  // counts it then, as shoal sim does at that tick -- an old one too: a delay model that
  // lets messages overtake makes the channel deliver it after a newer one). What can never
  // be used (NaN/Inf, unknown sender) is dropped and counted now.
  const RxResult r = follower_.Check(msg);
  if (r == RxResult::kUnknownSender || r == RxResult::kNonFinite) {
    follower_.CountRejected(r);
    return false;
  }
  if (held_.size() >= kMaxHeldDeliveries) DropHeld(0);
  held_.push_back(Held{msg.vehicle_id, msg.seq, msg.utime, DeliveryDigest(data, size), msg.eta,
                       msg.eta_dot});
  return true;
}

StateMsg VehicleApp::Unheld(const Held& h) {
  // The other numbers stay zero: Receive and Check use only these (Check's finiteness test
  // also reads the zeros, which pass as the held message's own numbers did).
  StateMsg m;
  m.vehicle_id = h.sender;
  m.seq = h.seq;
  m.utime = h.utime;
  m.eta = h.eta;
  m.eta_dot = h.eta_dot;
  return m;
}

const ClockedNode::Delivery* VehicleApp::ApplyListed(const std::vector<Delivery>& listed) {
  // Every listed delivery must be here; apply them in the listed order, as shoal sim.
  std::vector<std::size_t>& at = listed_at_;
  at.clear();
  for (const Delivery& want : listed) {
    std::size_t k = 0;
    while (k < held_.size() &&
           (held_[k].sender != want.sender || held_[k].seq != want.seq ||
            held_[k].digest != want.digest || std::find(at.begin(), at.end(), k) != at.end())) {
      ++k;
    }
    if (k == held_.size()) return &want;
    at.push_back(k);
  }
  follower_.BeginTick(next_tick() * period_us());  // as shoal sim: before the deliveries
  for (std::size_t k : at) follower_.Receive(Unheld(held_[k]));
  if (at.empty()) return nullptr;
  // The applied ones leave in one pass, the rest keeping their order (erasing each would
  // move every delivery behind it again).
  std::sort(at.begin(), at.end());
  std::size_t kept = at.front();
  for (std::size_t k = at.front(), a = 0; k < held_.size(); ++k) {
    if (a < at.size() && at[a] == k) {
      ++a;
    } else {
      held_[kept++] = held_[k];
    }
  }
  held_.resize(kept);
  return nullptr;
}

void VehicleApp::AfterLockstepStep(std::int64_t tick) {
  // What no later tick can list any more (sent longer ago than the largest delay, plus a
  // period) is dropped and counted.
  const Micros oldest_listable = tick * period_us() - listable_us_;
  for (std::size_t k = 0; k < held_.size();) {
    if (held_[k].utime < oldest_listable) {
      DropHeld(k);
    } else {
      ++k;
    }
  }
}

void VehicleApp::DropHeld(std::size_t k) {
  // Never listed: old if older than what was applied (a replay), else unlisted.
  if (follower_.Check(Unheld(held_[k])) == RxResult::kOld) {
    follower_.CountRejected(RxResult::kOld);
  } else {
    ++rx_counters_.unlisted_rx;
  }
  held_.erase(held_.begin() + static_cast<std::ptrdiff_t>(k));
}

health_t VehicleApp::Health(Micros utime) const {
  health_t h = ToLcmHealth(utime, follower_, 0);
  h.msgs_dropped_invalid += rx_counters_.bad_rx + counters().bad_clock + rx_counters_.unlisted_rx;
  return h;
}

namespace {
void Put5(const Vec5& v, CheckpointPayload* out) {
  for (int k = 0; k < 5; ++k) out->Put(v(k));
}
bool Get5(CheckpointPayload* in, Vec5* v) {
  bool ok = true;
  for (int k = 0; k < 5; ++k) ok = ok && in->Get(&(*v)(k));
  return ok;
}
}  // namespace

void VehicleApp::SaveCheckpoint(CheckpointPayload* out) const {
  const Follower::Checkpoint c = follower_.MakeCheckpoint();
  const StateMsg& m = c.published;
  out->Put(m.seq);
  out->Put(m.utime);
  for (const Vec5* v : {&m.eta, &m.nu, &m.eta_dot, &m.accel_cmd, &m.tau, &c.eta, &c.nu}) {
    Put5(*v, out);
  }
  out->Put(m.flags);
  const FollowerCounters& n = c.counters;
  for (std::int64_t v : {n.ticks, n.msgs_received, n.msgs_dropped_invalid, n.msgs_dropped_old,
                         n.neighbour_timeouts, n.saturated_ticks}) {
    out->Put(v);
  }
  for (std::int64_t v : n.saturated_channel) out->Put(v);
  out->Put(static_cast<std::int32_t>(n.active_neighbours));
  out->Put(static_cast<std::uint8_t>(c.diverged));
  for (double v : {c.trig.ct, c.trig.st, c.trig.cp, c.trig.sp}) out->Put(v);
  out->Put(static_cast<std::int32_t>(c.trig_age));
  for (const CarriedSinCos::Carried& d : c.delayed) {
    for (double v : {d.x, d.sin, d.cos}) out->Put(v);
    out->Put(static_cast<std::int32_t>(d.age));
  }
}

bool VehicleApp::RestoreCheckpoint(std::int64_t tick, CheckpointPayload* in) {
  Follower::Checkpoint c;
  StateMsg& m = c.published;
  bool ok = in->Get(&m.seq) && in->Get(&m.utime);
  for (Vec5* v : {&m.eta, &m.nu, &m.eta_dot, &m.accel_cmd, &m.tau, &c.eta, &c.nu}) {
    ok = ok && Get5(in, v);
  }
  ok = ok && in->Get(&m.flags);
  FollowerCounters& n = c.counters;
  for (std::int64_t* v : {&n.ticks, &n.msgs_received, &n.msgs_dropped_invalid,
                          &n.msgs_dropped_old, &n.neighbour_timeouts, &n.saturated_ticks}) {
    ok = ok && in->Get(v);
  }
  for (std::int64_t& v : n.saturated_channel) ok = ok && in->Get(&v);
  std::int32_t active = 0;
  std::uint8_t diverged = 0;
  ok = ok && in->Get(&active) && in->Get(&diverged);
  std::int32_t trig_age = 0;
  for (double* v : {&c.trig.ct, &c.trig.st, &c.trig.cp, &c.trig.sp}) {
    ok = ok && in->Get(v) && std::isfinite(*v);
  }
  ok = ok && in->Get(&trig_age);
  c.trig_age = trig_age;
  for (CarriedSinCos::Carried& d : c.delayed) {
    std::int32_t age = 0;
    ok = ok && in->Get(&d.x) && in->Get(&d.sin) && in->Get(&d.cos) && in->Get(&age);
    d.age = age;
  }
  // The record must be this vehicle's state of that tick.
  if (!ok || m.utime != tick * period_us() || m.seq < 0 || !m.AllFinite()) return false;
  n.active_neighbours = active;
  c.diverged = diverged != 0;
  m.vehicle_id = id();
  follower_.Resume(c);
  return true;
}

int VehicleMain(int argc, char** argv) {
  CLI::App app{"Shoal vehicle process: one follower UUV running protocol (10)"};
  int id = 0;
  app.add_option("--id", id, "Follower id (1..n)")->required();
  const auto valid_id = [&](const Scenario& s) {
    if (id >= 1 && id <= s.followers) return true;
    std::cerr << "shoal_vehicle: --id must be in 1.." << s.followers << " (got " << id << ")\n";
    return false;
  };
  return ClockedNodeMain(&app, argc, argv, "shoal_vehicle", valid_id, [&](const NodeContext& c) {
    return std::make_unique<VehicleApp>(c.scenario, id, c.mode, c.t0_ns, c.duration_s, c.bus,
                                        c.rx_bus);
  });
}

}  // namespace shoal
