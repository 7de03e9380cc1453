// RunData: everything an analysis or a plot needs from a Shoal log (or a live bus), as
// plain data. Built by LoadRunLog() from an LCM log file or by RunDataBuilder from any
// source of (channel, bytes) events (shoal analyze --live feeds it from an LCM
// subscription).
//
// What is kept, per channel (types in lcmtypes/, names in runtime/channels.h):
//   SHOAL_STATUS      statuses (without the scenario text, which is kept once); the first
//                     one carrying scenario text gives the scenario (parsed with
//                     ParseScenario) unless LoadOptions::scenario is given
//   SHOAL_STATE_<id>  every vehicle_state_t field, per vehicle, sorted by utime, one sample
//                     per utime (a repeated utime keeps the last one recorded)
//   SHOAL_CHANNEL     one compact record per channel decision (no reason string), from
//                     channel_events_t batches (or single channel_event_t, older logs)
//   SHOAL_HEALTH_<id> every health2_t (or health_t, older logs), in log order; a window
//                     histogram whose counts are negative or do not sum to its count is
//                     rejected with its report
//   SHOAL_CLOCK       every tick
//   SHOAL_RX_<id>     counted per receiver only (the same data as SHOAL_CHANNEL + states)
// Messages that do not decode, carry the wrong fingerprint, name an id that does not
// match their channel or is out of range are counted, never kept.
// Authentication (runtime/bus_auth.h): with the run's key (LoadOptions::key, by default
// <log>.key when it exists) every event must verify; what does not is counted per
// channel (unauthenticated) and read no further. Without a key, a message that carries
// an authentication trailer is read without it, unverified (counted). States holding NaN/Inf
// are kept (a diverging vehicle) and counted in VehicleTrack::nonfinite.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/scenario.h"
#include "core/state_msg.h"
#include "runtime/bus_auth.h"

namespace shoal {

/// One SHOAL_CHANNEL decision. Realised delay = deliver_utime - send_utime (delivered only).
struct ChannelEventRecord {
  Micros send_utime = 0;     // [us] the message's utime (its send time)
  Micros deliver_utime = 0;  // [us] when the emulator delivers it; 0 if dropped
  double delay_s = 0.0;      // [s] delay the link's model drew for it (tau(t))
  std::int32_t msg_seq = 0;  // seq of the vehicle_state_t concerned
  std::int16_t sender = 0;
  std::int16_t receiver = 0;
  std::int8_t status = 0;    // channel_event_t::STATUS_*: 0 delivered, 1 loss, 2 queue, 3 invalid
};

/// One lateness_window_bins bin that holds samples (runtime/clock.h LatenessBins).
struct LatenessBinCount {
  std::int16_t bin = 0;
  std::int32_t count = 0;
};

/// One SHOAL_HEALTH_<id> report (health2_t without the header's seq).
struct HealthRecord {
  Micros utime = 0;
  int process_id = 0;  // vehicle id, or -1 for the channel emulator
  std::int64_t ticks = 0;
  double lateness_p50_s = 0.0, lateness_p99_s = 0.0, lateness_max_s = 0.0;
  std::int64_t overruns = 0;
  std::int64_t msgs_received = 0, msgs_dropped_invalid = 0, msgs_dropped_old = 0;
  std::int64_t neighbour_timeouts = 0;
  int active_neighbours = 0;
  std::int64_t saturated_ticks = 0;
  double saturation_fraction = 0.0;
  /// The lateness samples since the process's previous report: their number (-1: not
  /// reported, a health_t of an older log), maximum and histogram, only its non-empty
  /// bins (a report holds a few of its 162: a long run keeps hundreds of thousands).
  std::int64_t lateness_window_count = -1;
  double lateness_window_max_s = 0.0;
  std::vector<LatenessBinCount> lateness_window;
};

/// One clock message: a window of n_ticks ticks from `tick` on, at utime + k * period_us.
/// Kept as a window, not a record per tick: a damaged or forged log of a few kB could
/// otherwise declare 10^5 ticks per message and fill gigabytes.
struct ClockRecord {
  Micros utime = 0;            // of the first tick
  std::int64_t tick = 0;       // the first tick
  std::int32_t n_ticks = 1;
  Micros period_us = 0;
  bool final_tick = false;     // the last tick covered is the run's last
  std::int64_t last_tick() const { return tick + n_ticks - 1; }
  Micros last_utime() const { return utime + (n_ticks - 1) * period_us; }
};

struct StatusRecord {
  Micros utime = 0;
  int vehicle_id = 0;  // publisher: vehicle id, -1 emulator, -2 launcher / shoal sim
  std::string state;   // RunStateName (runtime/messages.h), as the log says it
  std::string scenario_name;
  std::int64_t seed = 0;
  int followers = 0;
  std::string message;
};

/// The states of one vehicle (leader = 0), sorted by utime, unique utimes.
struct VehicleTrack {
  int id = 0;
  std::vector<StateMsg> samples;
  std::int64_t received = 0;    // valid states in the log, including repeats
  std::int64_t repeated = 0;    // same utime as an earlier sample (the last one is kept)
  std::int64_t nonfinite = 0;   // states with NaN/Inf (kept)
  Micros first_nonfinite_utime = -1;
};

/// shoal analyze --live: how the listening ended, and the messages the publishers'
/// sequence numbers say did not arrive (every Shoal message starts with utime,
/// vehicle_id, seq; seq counts +1 per message of a publisher on a channel).
struct LiveStream {
  bool live = false;        // the run was read from a bus, not a log
  bool end_status = false;  // a run-level end status (finished, failed, interrupted) arrived
  /// Why the listening stopped: "end status", "idle", "duration", "signal" or "error".
  std::string stopped_by;
  double idle_s = 0.0;      // --until-idle in force (0: none)
  /// Messages missed inside the stream, by channel: the gaps in each publisher's seq on
  /// SHOAL_CHANNEL, SHOAL_CLOCK, SHOAL_HEALTH_<id> and SHOAL_STATUS. States are judged
  /// by the run's expected states instead (a restarted vehicle skips seqs it never sent).
  std::map<std::string, std::int64_t> missed_by_channel;
  std::int64_t messages_missed() const {
    std::int64_t k = 0;
    for (const auto& [ch, n] : missed_by_channel) k += n;
    return k;
  }
};

/// A log written by `shoal retime` (tools/retime_command.h): event timestamps in mission
/// time; the original recorder's first and last stamps, which the analysis uses for the
/// wall time, kept in its marker event.
struct RetimedFrom {
  bool retimed = false;
  std::string source;  // the original log's name
  std::int64_t first_timestamp = 0, last_timestamp = 0;  // [us] the original's stamps
  std::int64_t first_state_timestamp = -1;  // [us] its first state's stamp (-1: not given)
  /// The original's damage, as its reader said it ("original_damage"): a copy holds only
  /// what could be read, so it is as damaged as its original.
  std::vector<std::string> original_damage;
};

/// The marker event `shoal retime` writes first: not a SHOAL_ channel (no live analysis
/// subscribes to it, no key is needed for it); its data is a JSON object:
/// {"format": kRetimedFormat, "source": the original log's file name,
///  "first_timestamp_us", "last_timestamp_us": the original's stamps, "events": its count,
///  "first_state_timestamp_us": the stamp of its first vehicle state, and, when the
///  original was damaged, "original_damage": its reader's warnings}.
constexpr const char* kRetimedChannel = "SHOAL-RETIMED";
constexpr const char* kRetimedFormat = "shoal retimed log 1";

/// Reads a marker's data into *out (false if it is not a valid marker).
bool ParseRetimedMarker(const std::uint8_t* data, int size, RetimedFrom* out);

struct RunData {
  std::string source;  // log path or LCM URL
  LiveStream stream;   // --live only
  RetimedFrom retimed_from;  // a retimed log's marker

  // Scenario: from the log's first SHOAL_STATUS with scenario text, or given by the caller.
  bool has_scenario = false;
  std::string scenario_origin;  // "log", "file" or "" (none)
  Scenario scenario;
  std::string scenario_name;    // from the statuses even without scenario text
  std::string scenario_text;    // as logged ("" if not in the log)
  int followers = 0;            // n: scenario, else statuses, else the largest id seen

  std::vector<VehicleTrack> vehicles;            // index = vehicle id (0 = leader)
  std::vector<ChannelEventRecord> channel_events;  // in log order
  std::vector<HealthRecord> health;              // in log order
  std::vector<ClockRecord> clock;                // in log order; see ClockTicks
  std::vector<StatusRecord> statuses;            // in log order
  std::map<int, std::int64_t> rx_messages;       // SHOAL_RX_<id>: messages per receiver

  // Bookkeeping.
  std::int64_t events = 0;          // events read (all channels)
  std::int64_t other_events = 0;    // events on non-Shoal channels (ignored)
  std::int64_t undecodable = 0;     // Shoal channel, but the bytes do not decode
  std::int64_t rejected = 0;        // decoded, but inconsistent (id mismatch / out of range,
                                    // a health window that does not add up)
  // [us] the earliest and latest event timestamps (recorder's clock)
  Micros first_timestamp = 0, last_timestamp = 0;
  /// [us] the earliest vehicle state's stamp (-1: none): where the run's ticks begin, after
  /// the processes' start-up that the first events (their statuses) stamp.
  Micros first_state_timestamp = -1;
  // Authentication (runtime/bus_auth.h).
  bool key_used = false;              // events were checked against the run's key
  std::string key_file;               // where that key came from ("" if given otherwise)
  std::int64_t verified = 0;          // events whose trailer verified
  std::int64_t unauthenticated = 0;   // events dropped: no trailer, or it did not verify
  std::map<std::string, std::int64_t> unauthenticated_by_channel;
  std::int64_t unverified = 0;        // no key: events read with their trailer unchecked
  bool insecure_run = false;          // a status says the bus was not authenticated
  /// The log's messages were authenticated and checked: a key, every Shoal message read
  /// verified, and no status says --insecure.
  bool bus_authenticated() const { return key_used && verified > 0 && !insecure_run; }
  std::vector<std::string> warnings;  // damage and problems, one user-facing sentence each
  bool damaged = false;               // the log was truncated or corrupt

  std::int64_t state_messages() const {
    std::int64_t k = 0;
    for (const VehicleTrack& v : vehicles) k += v.received;
    return k;
  }
  /// Distinct states (one per vehicle and time): what the run recorded, whatever was
  /// recorded twice.
  std::int64_t state_samples() const {
    std::int64_t k = 0;
    for (const VehicleTrack& v : vehicles) k += static_cast<std::int64_t>(v.samples.size());
    return k;
  }
};

struct LoadOptions {
  /// Scenario to use instead of the one in the log (e.g. for logs which do not
  /// carry the scenario text). Null: the log's, if any.
  const Scenario* scenario = nullptr;
  /// Largest vehicle id accepted when the scenario does not say (protects against
  /// absurd ids in damaged data).
  int max_vehicle_id = 1023;
  /// The run's key: every event must verify with it. Unset: `key_file`, else <log>.key if
  /// that file exists, else no verification (trailers are stripped unchecked).
  std::optional<bus_auth::Key> key;
  std::string key_file;
};

/// Checks the events of a log against a run's key, or (no key) strips their trailers.
class LogVerifier {
 public:
  LogVerifier(const std::optional<bus_auth::Key>& key, RunData* counts)
      : d_(counts) {
    if (key) auth_.emplace(*key);
  }
  /// The size of the event's message (its trailer stripped), or -1 to drop it (counted).
  /// Events on non-Shoal channels are passed on as they are.
  int Check(std::string_view channel, const std::uint8_t* data, int size);

 private:
  std::optional<bus_auth::Authenticator> auth_;
  RunData* d_;
};

/// After the last event: whether a status says --insecure, and the warnings that the
/// authentication counts call for.
void NoteAuthentication(RunData* d);
/// After the last event: a warning for the messages that did not decode and for those
/// that were inconsistent, which the analysis ignored.
void NoteIgnored(RunData* d);

/// The key for the log at `path`: read from `key_file` if given (any problem is an error),
/// else from <path>.key if that exists; none otherwise. False with *error if a key file
/// cannot be read or is malformed. *used_file says which file gave the key.
bool KeyForLog(const std::string& path, const std::string& key_file,
               std::optional<bus_auth::Key>* key, std::string* used_file, std::string* error);

/// Decodes events into a RunData. Add() never throws and never keeps a pointer to `data`.
class RunDataBuilder {
 public:
  RunDataBuilder(RunData* out, const LoadOptions& opt);
  void Add(std::string_view channel, const std::uint8_t* data, int size, std::int64_t timestamp);
  /// Sorts and de-duplicates the tracks, resolves n; call once after the last Add().
  void Finish();
  /// Reserves room for the whole source when `fraction` of it (0..1, by bytes) has been
  /// added: the counts so far, extrapolated, plus 5 %. Avoids growing the large vectors
  /// by copying (time, and a transient doubling of the peak memory). Optional.
  void ReserveByExtrapolation(double fraction);

 private:
  void AddState(int channel_id, const std::uint8_t* data, int size);
  void AddChannelEvents(const std::uint8_t* data, int size);
  void AddHealth(int channel_id, const std::uint8_t* data, int size);
  void AddClock(const std::uint8_t* data, int size);
  void AddStatus(const std::uint8_t* data, int size);
  int IdLimit() const;
  VehicleTrack* Track(int id);
  /// An event's stamp, judged once its neighbours' are known (StampsFinish for the last):
  /// one far from both of theirs while they are close is damaged, left out of the span.
  void NoteStamp(Micros t, bool state);
  void JudgeStamp(int k, bool damaged);
  void StampsFinish();
  /// Whether a message with this key (its publisher's identity for it) and these bytes was
  /// added before: a copy, as in a log recorded twice or a replay onto a recording bus.
  /// The same key with other bytes is a restarted publisher's message, and is new.
  bool SeenBefore(std::uint64_t key, const std::uint8_t* data, int size);

  /// An open-addressing set of (key, content hash) pairs: one slot per message of a long
  /// log, without a node to allocate for each. A content of 0 marks an empty slot.
  class SeenSet {
   public:
    bool Insert(std::uint64_t key, std::uint64_t content);  // false if already there
    void Reserve(std::size_t n);
    std::size_t size() const { return used_; }

   private:
    struct Slot {
      std::uint64_t key = 0, content = 0;
    };
    std::vector<Slot> slots_;
    std::size_t used_ = 0;
  };

  RunData* d_;
  LoadOptions opt_;
  bool have_time_ = false;
  struct Stamp {
    Micros t = 0;
    bool state = false;
  };
  std::array<Stamp, 3> recent_{};  // the last three events' stamps, oldest first
  std::int64_t stamps_ = 0;        // events stamped so far
  std::int64_t stamps_damaged_ = 0;
  int max_status_followers_ = 0;
  SeenSet seen_;
  std::int64_t repeated_decisions_ = 0;
  std::int64_t repeated_health_ = 0;
  std::int64_t other_scenarios_ = 0;  // scenario texts that differ from the first one
};

/// The distinct ticks the clock messages of a run cover (a window repeated, as in a log
/// recorded twice, counts once).
std::int64_t ClockTicks(const RunData& run);

/// The mission time (utime) a message on a Shoal channel carries, if it decodes as that
/// channel's type (a vehicle state with its channel's vehicle id); -1 otherwise, for a
/// damaged or foreign message as for another channel.
Micros DecodedTimeOf(std::string_view channel, const std::uint8_t* data, int size);

/// Reads an LCM log into *out. False (with *error, a user-facing message) if the file is
/// unreadable, empty, not an LCM log, or holds no complete Shoal message; a damaged log
/// is read up to / around the damage with out->warnings and out->damaged set.
bool LoadRunLog(const std::string& path, const LoadOptions& opt, RunData* out, std::string* error);

}  // namespace shoal
