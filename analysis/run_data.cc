#include "analysis/run_data.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>

#include <unistd.h>

#include <nlohmann/json.hpp>
#include <shoal/channel_event_t.hpp>
#include <shoal/channel_events_t.hpp>
#include <shoal/clock_tick_t.hpp>
#include <shoal/clock_window_t.hpp>
#include <shoal/health2_t.hpp>
#include <shoal/health_t.hpp>
#include <shoal/run_status_t.hpp>
#include <shoal/vehicle_state_t.hpp>

#include "analysis/memory.h"
#include "lcmtypes/wire.h"
#include "runtime/channels.h"
#include "runtime/lcm_bus.h"  // Decode: the generated decoder, made safe
#include "runtime/log_reader.h"
#include "runtime/messages.h"
#include "scenario/loader.h"

namespace shoal {
namespace {

// A hand-written reader for the channel events, the most numerous messages, on the
// LCM wire readers: the generated decoder is correct but allocates each event's reason
// string and throws on a damaged string length (std::length_error for a length <= 0).
using wire::F64;
using wire::I32;
using wire::I64;

constexpr int kChannelFixedBytes = 8 + 8 + 4 + 4 + 4 + 4 + 4 + 8 + 8 + 8 + 1;
constexpr int kEventBodyBytes = kChannelFixedBytes - 8;  // an event without its hash
constexpr int kBatchHeaderBytes = 8 + 8 + 4 + 4 + 4;

/// One channel_event_t without its hash (as nested in a batch) at p, n bytes available:
/// the bytes it takes, or 0 if damaged.
int DecodeEventBody(const std::uint8_t* p, int n, channel_event_t* e) {
  if (n < kEventBodyBytes + 4) return 0;
  const std::int32_t len = I32(p + kEventBodyBytes);  // reason, including its '\0'
  if (len < 1 || len > n - kEventBodyBytes - 4 || p[kEventBodyBytes + 4 + len - 1] != 0) {
    return 0;
  }
  e->utime = I64(p);
  e->vehicle_id = I32(p + 8);
  e->seq = I32(p + 12);
  e->sender = I32(p + 16);
  e->receiver = I32(p + 20);
  e->msg_seq = I32(p + 24);
  e->send_utime = I64(p + 28);
  e->delay_s = F64(p + 36);
  e->deliver_utime = I64(p + 44);
  e->status = static_cast<std::int8_t>(p[52]);
  return kEventBodyBytes + 4 + len;
}

/// SHOAL_CHANNEL: a channel_events_t batch, or (logs written before batching) a single
/// channel_event_t. All or nothing: false, with `out` empty, if anything is damaged.
bool DecodeChannelEvents(const std::uint8_t* p, int size, std::vector<channel_event_t>* out) {
  static const std::int64_t batch_hash = channel_events_t::getHash();
  static const std::int64_t single_hash = channel_event_t::getHash();
  out->clear();
  if (size < 8) return false;
  const std::int64_t hash = I64(p);
  if (hash == single_hash) {
    out->emplace_back();
    const int used = DecodeEventBody(p + 8, size - 8, &out->back());
    if (used == 0 || used != size - 8) {
      out->clear();
      return false;
    }
    return true;
  }
  if (hash != batch_hash || size < kBatchHeaderBytes) return false;
  const std::int32_t n = I32(p + 24);
  if (n < 0 || n > (size - kBatchHeaderBytes) / (kEventBodyBytes + 5)) return false;
  out->resize(static_cast<std::size_t>(n));
  int at = kBatchHeaderBytes;
  for (channel_event_t& e : *out) {
    const int used = DecodeEventBody(p + at, size - at, &e);
    if (used == 0) {
      out->clear();
      return false;
    }
    at += used;
  }
  if (at != size) {
    out->clear();
    return false;
  }
  return true;
}

/// SHOAL_CLOCK: a clock_window_t, or (older logs) a clock_tick_t, one tick per message,
/// read as a window of one tick (only its fixed fields are used).
bool DecodeClock(const std::uint8_t* p, int size, clock_window_t* c) {
  static const std::int64_t tick_hash = clock_tick_t::getHash();
  if (size >= 8 && I64(p) == tick_hash) {
    clock_tick_t t;
    if (!Decode(p, size, &t)) return false;
    c->utime = t.utime;
    c->vehicle_id = t.vehicle_id;
    c->seq = t.seq;
    c->tick = t.tick;
    c->n_ticks = 1;
    c->period_us = t.period_us;
    c->final_tick = t.final_tick;
    c->n_deliveries = 0;
    return true;
  }
  return Decode(p, size, c);
}

/// A health report, health2_t or (older logs) health_t, whose window count is then -1.
bool DecodeHealth(const std::uint8_t* p, int size, health2_t* h) {
  static const std::int64_t old_hash = health_t::getHash();
  if (size >= 8 && I64(p) == old_hash) {
    health_t o;
    if (!Decode(p, size, &o)) return false;
    *h = ToLcmHealth2(o, LatenessWindow());
    h->lateness_window_count = -1;
    return true;
  }
  return Decode(p, size, h);
}

/// The report's window into *r: false if its histogram cannot be (a negative count, or
/// counts that do not sum to its count).
bool WindowOf(const health2_t& h, HealthRecord* r) {
  r->lateness_window_count = h.lateness_window_count;
  r->lateness_window_max_s = h.lateness_window_max_s;
  if (h.lateness_window_count < 0) return h.lateness_window_count == -1;
  std::int64_t sum = 0;
  for (int i = 0; i < health2_t::LATENESS_BINS; ++i) {
    const std::int32_t n = h.lateness_window_bins[i];
    if (n < 0) return false;
    if (n > 0) r->lateness_window.push_back({static_cast<std::int16_t>(i), n});
    sum += n;
  }
  return sum == h.lateness_window_count && std::isfinite(h.lateness_window_max_s);
}

}  // namespace

RunDataBuilder::RunDataBuilder(RunData* out, const LoadOptions& opt) : d_(out), opt_(opt) {
  if (opt_.scenario != nullptr) {
    d_->scenario = *opt_.scenario;
    d_->has_scenario = true;
    d_->scenario_origin = "file";
    d_->scenario_name = d_->scenario.name;
  }
}

int RunDataBuilder::IdLimit() const {
  if (d_->has_scenario) return d_->scenario.followers;
  if (max_status_followers_ > 0) return max_status_followers_;
  return opt_.max_vehicle_id;
}

VehicleTrack* RunDataBuilder::Track(int id) {
  if (id >= static_cast<int>(d_->vehicles.size())) {
    const std::size_t old = d_->vehicles.size();
    d_->vehicles.resize(static_cast<std::size_t>(id) + 1);
    for (std::size_t k = old; k < d_->vehicles.size(); ++k) d_->vehicles[k].id = static_cast<int>(k);
  }
  return &d_->vehicles[static_cast<std::size_t>(id)];
}

bool ParseRetimedMarker(const std::uint8_t* data, int size, RetimedFrom* out) {
  const nlohmann::json j = nlohmann::json::parse(data, data + size, nullptr, false);
  if (!j.is_object() || j.value("format", "") != kRetimedFormat) return false;
  const auto first = j.find("first_timestamp_us"), last = j.find("last_timestamp_us");
  if (first == j.end() || last == j.end() || !first->is_number_integer() ||
      !last->is_number_integer()) {
    return false;
  }
  out->retimed = true;
  out->source = j.value("source", "");
  out->first_timestamp = first->get<std::int64_t>();
  out->last_timestamp = last->get<std::int64_t>();
  const auto first_state = j.find("first_state_timestamp_us");
  if (first_state != j.end() && first_state->is_number_integer()) {
    out->first_state_timestamp = first_state->get<std::int64_t>();
  }
  const auto damage = j.find("original_damage");
  if (damage != j.end() && damage->is_array()) {
    for (const auto& w : *damage) {
      if (w.is_string()) out->original_damage.push_back(w.get<std::string>());
    }
  }
  return true;
}

void RunDataBuilder::Add(std::string_view ch, const std::uint8_t* data, int size,
                         std::int64_t timestamp) {
  // A retimed log's marker is no event of the run: the counts stay the original's. It is
  // the log's first event, stamped with the first stamp it names. A marker played back and
  // recorded again (lcm-logplayer of a retimed log into lcm-logger) carries the recorder's
  // wall-clock stamp instead: that log's stamps are wall time again, and the marker is a
  // foreign event like any other.
  if (ch == kRetimedChannel) {
    RetimedFrom marker;
    if (d_->events == 0 && ParseRetimedMarker(data, size, &marker) &&
        marker.first_timestamp == timestamp) {
      d_->retimed_from = marker;
      return;
    }
  }
  ++d_->events;
  const channels::Parsed c = channels::Parse(ch);
  NoteStamp(timestamp, c.kind == channels::Kind::kState);
  switch (c.kind) {
    case channels::Kind::kState:
      AddState(c.id, data, size);
      break;
    case channels::Kind::kRx:
      if (c.id >= 0 && c.id <= IdLimit()) {
        ++d_->rx_messages[c.id];
      } else {
        ++d_->rejected;
      }
      break;
    case channels::Kind::kChannelEvents:
      AddChannelEvents(data, size);
      break;
    case channels::Kind::kHealth:
      AddHealth(c.id, data, size);
      break;
    case channels::Kind::kClock:
      AddClock(data, size);
      break;
    case channels::Kind::kStatus:
      AddStatus(data, size);
      break;
    case channels::Kind::kOther:
      ++d_->other_events;
      break;
  }
}

void RunDataBuilder::SeenSet::Reserve(std::size_t n) {
  std::size_t want = 64;
  while (want < 2 * n) want *= 2;  // at most half full
  if (want <= slots_.size()) return;
  std::vector<Slot> old(want);
  old.swap(slots_);
  used_ = 0;
  for (const Slot& s : old) {
    if (s.content != 0) Insert(s.key, s.content);
  }
}

bool RunDataBuilder::SeenSet::Insert(std::uint64_t key, std::uint64_t content) {
  if (2 * (used_ + 1) > slots_.size()) Reserve(std::max<std::size_t>(64, 2 * used_ + 2));
  const std::size_t mask = slots_.size() - 1;
  for (std::size_t i = (content ^ (key * 0x9e3779b97f4a7c15ULL)) & mask;; i = (i + 1) & mask) {
    Slot& s = slots_[i];
    if (s.content == 0) {
      s = Slot{key, content};
      ++used_;
      return true;
    }
    if (s.content == content && s.key == key) return false;
  }
}

bool RunDataBuilder::SeenBefore(std::uint64_t key, const std::uint8_t* data, int size) {
  const std::uint64_t content = std::hash<std::string_view>{}(std::string_view(
                                    reinterpret_cast<const char*>(data), static_cast<std::size_t>(size))) |
                                1;  // never 0, the mark of an empty slot
  return !seen_.Insert(key, content);
}

namespace {
/// A message's kind, its publisher's id and the number that tells the publisher's messages
/// apart (a sequence number or a time), mixed: only a shorthand, the bytes decide.
std::uint64_t MessageKey(int kind, std::int32_t publisher, std::uint64_t number) {
  return (static_cast<std::uint64_t>(kind) << 62) ^
         (static_cast<std::uint64_t>(static_cast<std::uint32_t>(publisher)) << 30) ^ number;
}
}  // namespace

void RunDataBuilder::AddChannelEvents(const std::uint8_t* data, int size) {
  static thread_local std::vector<channel_event_t> events;
  if (!DecodeChannelEvents(data, size, &events)) {
    ++d_->undecodable;
    return;
  }
  // A batch (or an older log's single event) is its publisher's by id and sequence number.
  const bool batch = events.empty() || I64(data) == channel_events_t::getHash();
  const std::int32_t publisher = batch ? I32(data + 16) : events.front().vehicle_id;
  const std::int32_t seq = batch ? I32(data + 20) : events.front().seq;
  if (SeenBefore(MessageKey(1, publisher, static_cast<std::uint32_t>(seq)), data, size)) {
    repeated_decisions_ += static_cast<std::int64_t>(events.size());
    return;
  }
  const int lim = IdLimit();
  for (const channel_event_t& e : events) {
    // A status above the largest this reader knows is a newer writer's kind of drop: it is
    // kept and counted as dropped_invalid (lcmtypes/README.md), not rejected.
    if (e.sender < 0 || e.sender > lim || e.receiver < 0 || e.receiver > lim || e.status < 0) {
      ++d_->rejected;
      continue;
    }
    ChannelEventRecord r;
    r.send_utime = e.send_utime;
    r.deliver_utime = e.deliver_utime;
    r.delay_s = e.delay_s;
    r.msg_seq = e.msg_seq;
    r.sender = static_cast<std::int16_t>(e.sender);
    r.receiver = static_cast<std::int16_t>(e.receiver);
    r.status = e.status;
    d_->channel_events.push_back(r);
  }
}

void RunDataBuilder::AddHealth(int id, const std::uint8_t* data, int size) {
  health2_t h{};
  if (!DecodeHealth(data, size, &h)) {
    ++d_->undecodable;
    return;
  }
  HealthRecord r;
  if (h.vehicle_id != id || id < -1 || id > IdLimit() || !WindowOf(h, &r)) {
    ++d_->rejected;
    return;
  }
  if (SeenBefore(MessageKey(2, id, static_cast<std::uint64_t>(h.utime)), data, size)) {
    ++repeated_health_;
    return;
  }
  r.utime = h.utime;
  r.process_id = h.vehicle_id;
  r.ticks = h.ticks;
  r.lateness_p50_s = h.lateness_p50_s;
  r.lateness_p99_s = h.lateness_p99_s;
  r.lateness_max_s = h.lateness_max_s;
  r.overruns = h.overruns;
  r.msgs_received = h.msgs_received;
  r.msgs_dropped_invalid = h.msgs_dropped_invalid;
  r.msgs_dropped_old = h.msgs_dropped_old;
  r.neighbour_timeouts = h.neighbour_timeouts;
  r.active_neighbours = h.active_neighbours;
  r.saturated_ticks = h.saturated_ticks;
  r.saturation_fraction = h.saturation_fraction;
  d_->health.push_back(std::move(r));
}

void RunDataBuilder::AddClock(const std::uint8_t* data, int size) {
  clock_window_t c{};
  if (!DecodeClock(data, size, &c)) {
    ++d_->undecodable;
    return;
  }
  // One record per tick covered (a lockstep clock message covers a window of ticks; at
  // most --max-lookahead's 100000). Checked before any arithmetic on the fields: the
  // window's last tick times its period must fit in 64 bits (2^40 ticks of 1e9 us do not).
  constexpr std::int64_t kMaxTick = std::int64_t{1} << 40;
  constexpr std::int64_t kMaxUtime = std::numeric_limits<std::int64_t>::max() / 2;
  if (c.n_ticks < 1 || c.n_ticks > 100000 || c.period_us <= 0 || c.period_us > 1000000000 ||
      c.tick < 0 || c.tick > kMaxTick || c.tick > kMaxUtime / c.period_us - c.n_ticks ||
      c.utime != c.tick * c.period_us) {
    ++d_->rejected;
    return;
  }
  ClockRecord r;
  r.utime = c.utime;
  r.tick = c.tick;
  r.n_ticks = c.n_ticks;
  r.period_us = c.period_us;
  r.final_tick = c.final_tick != 0;
  d_->clock.push_back(r);
}

std::int64_t ClockTicks(const RunData& run) {
  std::vector<std::pair<std::int64_t, std::int64_t>> spans;  // [first, last] ticks
  spans.reserve(run.clock.size());
  for (const ClockRecord& c : run.clock) spans.emplace_back(c.tick, c.last_tick());
  std::sort(spans.begin(), spans.end());
  std::int64_t ticks = 0, covered_to = -1;  // ticks up to covered_to are counted
  for (const auto& [first, last] : spans) {
    if (last <= covered_to) continue;
    ticks += last - std::max(first, covered_to + 1) + 1;
    covered_to = last;
  }
  return ticks;
}

Micros DecodedTimeOf(std::string_view channel, const std::uint8_t* data, int size) {
  const channels::Parsed c = channels::Parse(channel);
  switch (c.kind) {
    case channels::Kind::kState:
    case channels::Kind::kRx: {
      vehicle_state_t v;
      if (!Decode(data, size, &v)) return -1;
      return c.kind == channels::Kind::kRx || v.vehicle_id == c.id ? v.utime : -1;
    }
    case channels::Kind::kHealth: {
      health2_t h;
      return DecodeHealth(data, size, &h) ? h.utime : -1;
    }
    case channels::Kind::kChannelEvents: {
      static thread_local std::vector<channel_event_t> events;
      return DecodeChannelEvents(data, size, &events) ? I64(data + 8) : -1;
    }
    case channels::Kind::kClock: {
      clock_window_t w;
      return DecodeClock(data, size, &w) ? w.utime : -1;
    }
    case channels::Kind::kStatus: {
      run_status_t st;
      return Decode(data, size, &st) ? st.utime : -1;
    }
    case channels::Kind::kOther:
      break;
  }
  return -1;
}

void RunDataBuilder::AddState(int id, const std::uint8_t* data, int size) {
  vehicle_state_t v;
  if (!Decode(data, size, &v)) {
    ++d_->undecodable;
    return;
  }
  const StateMsg m = FromLcm(v);
  if (m.vehicle_id != id || id < 0 || id > IdLimit()) {
    ++d_->rejected;
    return;
  }
  VehicleTrack* t = Track(id);
  // Kept: a diverging vehicle's NaN state must count as a formation violation (and is a
  // gap in a plot), not vanish.
  if (!m.AllFinite() && t->nonfinite++ == 0) t->first_nonfinite_utime = m.utime;
  ++t->received;
  t->samples.push_back(m);
}

void RunDataBuilder::AddStatus(const std::uint8_t* data, int size) {
  run_status_t st;
  if (!Decode(data, size, &st)) {
    ++d_->undecodable;
    return;
  }
  StatusRecord r;
  r.utime = st.utime;
  r.vehicle_id = st.vehicle_id;
  r.state = st.state;
  r.scenario_name = st.scenario_name;
  r.seed = st.seed;
  r.followers = st.followers;
  r.message = st.message;
  d_->statuses.push_back(std::move(r));
  if (st.followers > 0 && st.followers <= opt_.max_vehicle_id) {
    max_status_followers_ = std::max(max_status_followers_, st.followers);
  }
  if (d_->scenario_name.empty()) d_->scenario_name = st.scenario_name;
  // Another scenario text: another run's log was joined to this one.
  if (!st.scenario_toml.empty() && !d_->scenario_text.empty() &&
      st.scenario_toml != d_->scenario_text) {
    ++other_scenarios_;
  }
  if (!st.scenario_toml.empty() && d_->scenario_text.empty()) {
    d_->scenario_text = st.scenario_toml;
    if (!d_->has_scenario) {
      const std::string where = "scenario text in " + d_->source + " (SHOAL_STATUS)";
      try {
        d_->scenario = ParseScenario(st.scenario_toml, where);
        if (!st.scenario_name.empty()) d_->scenario.name = st.scenario_name;
        d_->has_scenario = true;
        d_->scenario_origin = "log";
        d_->scenario_name = d_->scenario.name;
      } catch (const std::exception& e) {
        d_->warnings.push_back(std::string("the scenario text in the log does not load (") +
                               e.what() + "); formation errors need --scenario FILE");
      }
    }
  }
}

void RunDataBuilder::ReserveByExtrapolation(double fraction) {
  if (!(fraction > 0.0 && fraction <= 1.0)) return;
  const auto room = [&](std::size_t now) {
    return static_cast<std::size_t>(static_cast<double>(now) / fraction * 1.05) + 1024;
  };
  for (VehicleTrack& v : d_->vehicles) {
    if (!v.samples.empty()) ReserveHuge(&v.samples, room(v.samples.size()));
  }
  if (!d_->channel_events.empty()) ReserveHuge(&d_->channel_events, room(d_->channel_events.size()));
  seen_.Reserve(room(seen_.size()));
}

namespace {
/// Two receive stamps more than an hour apart: no two neighbouring events of a run are (a
/// run publishes every period), while one damaged bit of a stamp moves it by far more.
bool FarApart(Micros a, Micros b) {
  constexpr std::uint64_t kHourUs = 3600ULL * 1000000ULL;
  const auto ua = static_cast<std::uint64_t>(a), ub = static_cast<std::uint64_t>(b);
  return (a > b ? ua - ub : ub - ua) > kHourUs;  // modulo 2^64: the exact distance
}
}  // namespace

void RunDataBuilder::NoteStamp(Micros t, bool state) {
  if (stamps_ < 3) {
    recent_[static_cast<std::size_t>(stamps_)] = {t, state};
  } else {
    recent_[0] = recent_[1];
    recent_[1] = recent_[2];
    recent_[2] = {t, state};
  }
  if (++stamps_ < 3) return;
  const Micros a = recent_[0].t, b = recent_[1].t, c = recent_[2].t;
  if (stamps_ == 3) JudgeStamp(0, FarApart(a, b) && FarApart(a, c) && !FarApart(b, c));
  JudgeStamp(1, FarApart(b, a) && FarApart(b, c) && !FarApart(a, c));
}

void RunDataBuilder::JudgeStamp(int k, bool damaged) {
  const Stamp& s = recent_[static_cast<std::size_t>(k)];
  if (damaged) {
    ++stamps_damaged_;
    return;
  }
  // The earliest and latest stamps, not the first and last in the file: a log whose
  // events are out of order (cut and joined again) still spans the time it recorded.
  if (!have_time_) {
    d_->first_timestamp = d_->last_timestamp = s.t;
    have_time_ = true;
  }
  d_->first_timestamp = std::min(d_->first_timestamp, s.t);
  d_->last_timestamp = std::max(d_->last_timestamp, s.t);
  if (s.state && (d_->first_state_timestamp < 0 || s.t < d_->first_state_timestamp)) {
    d_->first_state_timestamp = s.t;
  }
}

void RunDataBuilder::StampsFinish() {
  if (stamps_ < 3) {  // too few to judge: all taken
    for (int k = 0; k < stamps_; ++k) JudgeStamp(k, false);
  } else {
    const Micros a = recent_[0].t, b = recent_[1].t, c = recent_[2].t;
    JudgeStamp(2, FarApart(c, b) && FarApart(c, a) && !FarApart(a, b));
  }
  stamps_ = 0;
  if (stamps_damaged_ > 0) {
    d_->warnings.push_back(std::to_string(stamps_damaged_) +
                           " event(s) have a receive time over an hour from both of their "
                           "neighbours': damaged, left out of the recording's span");
  }
}

void RunDataBuilder::Finish() {
  StampsFinish();
  // n: the scenario's, else the statuses', else the largest id seen.
  int n = 0;
  if (d_->has_scenario) {
    n = d_->scenario.followers;
  } else if (max_status_followers_ > 0) {
    n = max_status_followers_;
  } else {
    for (const VehicleTrack& v : d_->vehicles) {
      if (v.received > 0) n = std::max(n, v.id);
    }
  }
  // States accepted before n was known that lie beyond it are inconsistent data.
  for (std::size_t k = static_cast<std::size_t>(n) + 1; k < d_->vehicles.size(); ++k) {
    d_->rejected += d_->vehicles[k].received;
  }
  if (d_->vehicles.size() > static_cast<std::size_t>(n) + 1) d_->vehicles.resize(n + 1);
  Track(n);
  d_->followers = n;
  for (VehicleTrack& v : d_->vehicles) {
    auto& s = v.samples;
    const auto by_time = [](const StateMsg& a, const StateMsg& b) { return a.utime < b.utime; };
    if (!std::is_sorted(s.begin(), s.end(), by_time)) std::stable_sort(s.begin(), s.end(), by_time);
    // One sample per utime: the last one recorded wins (as in shoal run's summary).
    std::size_t w = 0;
    for (std::size_t r = 0; r < s.size(); ++r) {
      if (w > 0 && s[w - 1].utime == s[r].utime) {
        s[w - 1] = s[r];
        ++v.repeated;
      } else {
        if (w != r) s[w] = s[r];
        ++w;
      }
    }
    s.resize(w);
  }
  std::int64_t repeated = 0;
  for (const VehicleTrack& v : d_->vehicles) repeated += v.repeated;
  if (repeated > 0) {
    d_->warnings.push_back(std::to_string(repeated) +
                           " vehicle states appear more than once (same vehicle and time: a "
                           "log recorded twice or concatenated, or replayed onto a recording "
                           "bus); each is counted once, the last copy kept");
  }
  if (other_scenarios_ > 0) {
    d_->warnings.push_back(std::to_string(other_scenarios_ + 1) +
                           " runs' scenario texts differ in this log (logs of different runs "
                           "joined into one): the first one's scenario is used, and the states, "
                           "decisions and health of every run are read as one run's");
  }
  if (repeated_decisions_ > 0 || repeated_health_ > 0) {
    d_->warnings.push_back(std::to_string(repeated_decisions_) + " channel decisions and " +
                           std::to_string(repeated_health_) +
                           " health reports appear more than once (the same message from "
                           "the same publisher: a log recorded twice or concatenated, or "
                           "replayed onto a recording bus); each is counted once");
  }
}

int LogVerifier::Check(std::string_view channel, const std::uint8_t* data, int size) {
  // Other channels (LCM's own LCM_SELF_TEST, foreign tools) are not read: not checked.
  if (channels::Parse(channel).kind == channels::Kind::kOther) return size;
  if (!auth_) {
    const int trailer = bus_auth::TrailerBytes(data, size);
    if (trailer == 0) return size;
    ++d_->unverified;
    return size - trailer;
  }
  const int payload = auth_->Verify(channel, data, size);
  if (payload < 0) {
    ++d_->unauthenticated;
    // Per channel while few channels are involved (a forger inventing names gets one
    // bucket rather than unbounded memory).
    auto& by = d_->unauthenticated_by_channel;
    const std::string name(channel);
    if (by.size() < 256 || by.count(name) > 0) {
      ++by[name];
    } else {
      ++by["(other channels)"];
    }
    return -1;
  }
  ++d_->verified;
  return payload;
}

bool KeyForLog(const std::string& path, const std::string& key_file,
               std::optional<bus_auth::Key>* key, std::string* used_file, std::string* error) {
  key->reset();
  used_file->clear();
  std::string file = key_file;
  if (file.empty() && access((path + ".key").c_str(), F_OK) == 0) file = path + ".key";
  if (file.empty()) return true;
  bus_auth::Key k;
  if (!bus_auth::ReadKeyFile(file, &k, error)) return false;
  *key = k;
  *used_file = file;
  return true;
}

void NoteAuthentication(RunData* d) {
  for (const StatusRecord& st : d->statuses) {
    if (st.message.find(bus_auth::kInsecureNote) != std::string::npos) d->insecure_run = true;
  }
  if (d->unauthenticated > 0) {
    d->warnings.push_back(std::to_string(d->unauthenticated) +
                          " events did not authenticate with the run's key (forged, from "
                          "another run, or damaged) and were dropped");
  }
  if (d->unverified > 0) {
    d->warnings.push_back(std::to_string(d->unverified) +
                          " events carry an authentication trailer that could not be "
                          "checked (no key: give --key FILE, or keep <log>.key next to the "
                          "log); they were read unverified");
  }
  if (d->insecure_run) {
    d->warnings.push_back("the run's bus was not authenticated (--insecure): anyone on the "
                          "host could have published into it");
  }
}

void NoteIgnored(RunData* d) {
  if (d->undecodable > 0) {
    d->warnings.push_back(std::to_string(d->undecodable) +
                          " messages on Shoal channels did not decode (wrong size or "
                          "fingerprint, a damaged string length) and were ignored");
  }
  if (d->rejected > 0) {
    d->warnings.push_back(std::to_string(d->rejected) +
                          " messages were inconsistent (a vehicle id that does not match its "
                          "channel or lies beyond the scenario's followers, a health window that "
                          "does not add up) and were ignored");
  }
}

bool LoadRunLog(const std::string& path, const LoadOptions& opt, RunData* out,
                std::string* error) {
  *out = RunData();
  out->source = path;
  std::optional<bus_auth::Key> key = opt.key;
  if (!key && !KeyForLog(path, opt.key_file, &key, &out->key_file, error)) return false;
  out->key_used = key.has_value();
  LcmLogReader reader;
  if (!reader.Open(path, error)) return false;
  RunDataBuilder b(out, opt);
  LogVerifier verifier(key, out);
  LogEventView ev;
  // Big logs: once 2 % is read, reserve for the rest (logs are homogeneous in time).
  const std::int64_t reserve_at = reader.file_size() > (64 << 20) ? reader.file_size() / 50 : -1;
  bool reserved = false;
  while (reader.Next(&ev)) {
    const int size = verifier.Check(ev.channel, ev.data, ev.size);
    if (size < 0) {
      ++out->events;  // read, but not the run's
      continue;
    }
    b.Add(ev.channel, ev.data, size, ev.timestamp);
    if (!reserved && reserve_at > 0 && ev.offset >= reserve_at) {
      b.ReserveByExtrapolation(static_cast<double>(ev.offset) / static_cast<double>(reader.file_size()));
      reserved = true;
    }
  }
  b.Finish();
  NoteAuthentication(out);
  NoteIgnored(out);
  out->warnings.insert(out->warnings.begin(), reader.warnings().begin(), reader.warnings().end());
  out->damaged = reader.damaged_regions() > 0;
  // A retimed copy holds what its original's reader could read: it is as damaged.
  const RetimedFrom& r = out->retimed_from;
  if (r.retimed && !r.original_damage.empty()) {
    out->damaged = true;
    std::vector<std::string> said;
    for (const std::string& w : r.original_damage) said.push_back("the original log: " + w);
    out->warnings.insert(out->warnings.begin(), said.begin(), said.end());
  }
  if (out->events == 0) {
    *error = path + ": no complete LCM event in the file" +
             (reader.warnings().empty() ? std::string() : " (" + reader.warnings().front() + ")");
    return false;
  }
  const bool any_shoal = out->state_messages() > 0 || !out->channel_events.empty() ||
                         !out->health.empty() || !out->clock.empty() || !out->statuses.empty();
  if (!any_shoal && out->unauthenticated > 0) {
    *error = path + ": none of its " + std::to_string(out->events) +
             " events authenticates with the key" +
             (out->key_file.empty() ? std::string() : " in " + out->key_file) +
             " (the log of another run, or of a run with --insecure?)";
    return false;
  }
  if (!any_shoal) {
    *error = path + ": an LCM log with " + std::to_string(out->events) +
             " events but no Shoal message (no valid SHOAL_* channel); analyse a log written "
             "by shoal sim --out, shoal run, or lcm-logger during a Shoal run";
    return false;
  }
  return true;
}

}  // namespace shoal
