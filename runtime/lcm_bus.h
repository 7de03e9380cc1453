// The small transport interface the processes program against (as Drake's
// DrakeLcmInterface), with the LCM implementation. Handlers get raw bytes: decoding,
// validation and counting happen in the caller, so that a malformed message is dropped
// and counted instead of being printed and lost inside LCM's auto-decoding.
#pragma once

#include <lcm/lcm-cpp.hpp>

#include <shoal/channel_event_t.hpp>
#include <shoal/channel_events_t.hpp>
#include <shoal/clock_tick_t.hpp>
#include <shoal/clock_window_t.hpp>
#include <shoal/run_status_t.hpp>

#include <cstdint>
#include <cstring>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <regex>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "lcmtypes/wire.h"
#include "runtime/bus_auth.h"
#include "runtime/state_wire.h"
#include "runtime/udpm_receiver.h"
#include "runtime/udpm_sender.h"

namespace shoal {

class Bus {
 public:
  /// Far more than a run sends a process between two of its calls (a lockstep window's
  /// deliveries and clock messages, a real-time period's states).
  static constexpr int kMaxMessagesPerHandle = 1024;
  using Handler = std::function<void(const std::string& channel, const void* data, int size)>;
  virtual ~Bus() = default;
  /// Publishes raw bytes; returns false on failure.
  virtual bool PublishRaw(const std::string& channel, const void* data, int size) = 0;
  /// `channel` is a regular expression (implicitly ^...$), as in LCM.
  virtual void Subscribe(const std::string& channel, Handler handler) = 0;
  /// As Subscribe, but the handler gets each message that verified as it came, its
  /// trailer included (a bundle's parts each as it would have come alone): to be passed
  /// on unchanged with PublishAsReceived.
  virtual void SubscribeAsReceived(const std::string& channel, Handler handler) {
    Subscribe(channel, std::move(handler));
  }
  /// Publishes a message as another bus received it (SubscribeAsReceived): inside an open
  /// recordable bundle as a part as it is, otherwise alone as it is; never signed again.
  virtual bool PublishAsReceived(const std::string& channel, const void* data, int size) {
    return PublishRaw(channel, data, size);
  }
  /// Dispatches pending messages, waiting at most timeout_ms for the first, and at most
  /// kMaxMessagesPerHandle of them: a flood on the bus then cannot grow what a caller
  /// buffers between two calls without bound; the rest waits, in order, for the next call.
  /// Returns the number of messages handled (0 on timeout), or -1 on error.
  virtual int Handle(int timeout_ms) = 0;
  /// Messages dropped because they did not authenticate (runtime/bus_auth.h).
  virtual std::int64_t rejected() const { return 0; }
  /// From now on, notes when each message reached this host (the kernel's receive time),
  /// for ArrivalNs. False if this bus cannot; then ArrivalNs stays -1.
  virtual bool RecordArrivals() { return false; }
  /// While a handler runs: when its message reached this host, on CLOCK_MONOTONIC in ns;
  /// -1 if not known.
  virtual std::int64_t ArrivalNs() const { return -1; }
  /// Messages this bus has sent: what its receivers each take off their queue (a bundle
  /// counts once). 0 for a bus that does not count.
  virtual std::int64_t sent() const { return 0; }
  /// From BeginBundle to EndBundle, what is published on this bus may go out as one
  /// message (a bundle: LcmBus) that the receiving LcmBus hands to its subscribers part by
  /// part, in order, each as if it had been published alone: one datagram, one wake-up of
  /// the receiver, instead of one per message. Only for buses whose every receiver is an
  /// LcmBus (lcm-logger records a bundle as one message on kBundleChannel). By default the
  /// messages go out one by one.
  ///
  /// `recordable`: each part is authenticated on its own, exactly as it would be if it went
  /// out alone, and the bundle is not authenticated as a whole (bundle_wire::kMagicRecordable):
  /// an LcmBus without a key then hands its subscribers the parts as they would have come
  /// alone (trailer included), and lcm-logger with runtime/lcm_queue_shim.c preloaded records
  /// each part as a message of its own, so the log is what the messages sent one by one make
  /// it. For a bus lcm-logger records only with that shim preloaded. Nested: the outermost
  /// BeginBundle decides.
  virtual void BeginBundle(bool recordable = false) { (void)recordable; }
  /// Sends what BeginBundle kept (a single message as it is). False if a publish failed.
  virtual bool EndBundle() { return true; }
  /// Makes the buffers of the largest bundle now rather than at the first BeginBundle. A
  /// real-time process calls it before its clock starts: allocated and zero-filled at its
  /// first release, they made that release over a millisecond late on a VM, a tick late
  /// for its receivers.
  virtual void PrepareBundles() {}
  /// While `batch` is active (runtime/udpm_sender.h), what this bus sends goes into it, to
  /// leave with the batch's other datagrams in one system call. Only a udpm LcmBus does
  /// this; any other bus sends as before.
  virtual void SendThrough(UdpmBatch* batch) { (void)batch; }

  template <typename Msg>
  bool Publish(const std::string& channel, const Msg& msg) {
    if constexpr (std::is_same_v<Msg, vehicle_state_t>) {
      if (static_cast<int>(buf_.size()) < state_wire::kBytes) buf_.resize(state_wire::kBytes);
      state_wire::Encode(msg, buf_.data());
      return PublishRaw(channel, buf_.data(), state_wire::kBytes);
    } else {
      const int size = msg.getEncodedSize();
      if (static_cast<int>(buf_.size()) < size) buf_.resize(size);
      if (msg.encode(buf_.data(), 0, size) != size) return false;
      return PublishRaw(channel, buf_.data(), size);
    }
  }

 private:
  std::vector<unsigned char> buf_;
};

/// LCM over any provider URL (udpm://... for processes, memq:// for in-process tests).
/// A udpm bus is received, by default, in the thread that calls Handle (runtime/
/// udpm_receiver.h: one wake-up per batch of datagrams instead of LCM's two per message);
/// kLcmThread keeps LCM's receive thread, whose queue in memory outgrows the kernel's
/// socket buffer (a listener slower than a fast replay). Publishing is LCM's either way, so
/// every LCM tool hears what the bus sends. With a key, every message published carries an authentication trailer, and a handler
/// receives only messages whose trailer verifies, without the trailer (so that decoding,
/// size checks and lockstep digests see the message's own bytes); the others are dropped
/// and counted in rejected(). Without a key (--insecure, in-process tests) messages go
/// out and come in as they are.
class LcmBus : public Bus {
 public:
  /// Throws std::runtime_error if LCM cannot be initialised for `url`. Subscribe throws
  /// too if LCM cannot open its receive socket.
  enum class Receiving { kInCaller, kLcmThread };
  explicit LcmBus(const std::string& url, std::optional<bus_auth::Key> key = std::nullopt,
                  Receiving receiving = Receiving::kInCaller);
  bool PublishRaw(const std::string& channel, const void* data, int size) override;
  void Subscribe(const std::string& channel, Handler handler) override;
  void SubscribeAsReceived(const std::string& channel, Handler handler) override;
  bool PublishAsReceived(const std::string& channel, const void* data, int size) override;
  int Handle(int timeout_ms) override;
  /// Dropped unverified, and (received in the caller) datagrams that were not LCM's.
  std::int64_t sent() const override { return sent_; }
  std::int64_t rejected() const override {
    return rejected_ + (receiver_ ? receiver_->malformed() : 0);
  }
  /// Received in the caller only (the kernel's time of each datagram; LCM's own thread
  /// gives none).
  bool RecordArrivals() override { return receiver_ && receiver_->RecordArrivals(); }
  std::int64_t ArrivalNs() const override { return receiver_ ? receiver_->arrival_ns() : -1; }
  /// Datagrams the kernel dropped for a full socket buffer (received in the caller only).
  std::int64_t overflowed() const { return receiver_ ? receiver_->overflowed() : 0; }
  void BeginBundle(bool recordable = false) override;
  bool EndBundle() override;
  void PrepareBundles() override;
  void SendThrough(UdpmBatch* batch) override;
  int fileno() { return receiver_ ? receiver_->fd() : lcm_.getFileno(); }
  const std::string& url() const { return url_; }
  bool authenticated() const { return auth_.has_value(); }

 private:
  struct Sub {
    Handler handler;
    const std::optional<bus_auth::Authenticator>* auth;
    std::int64_t* rejected;
    std::string channel;  // the pattern as given, and as a regex when it is not a plain
    std::optional<std::regex> pattern;  // name: to route the parts of a bundle
    bool as_received = false;  // SubscribeAsReceived: the trailer is handed on too
    bool Matches(std::string_view ch) const {
      return pattern ? std::regex_match(ch.begin(), ch.end(), *pattern) : ch == channel;
    }
    void On(const lcm::ReceiveBuffer* rb, const std::string& channel);
    void Deliver(const std::string& channel, const void* data, int size);
  };
  void AddSubscription(const std::string& channel, Handler handler, bool as_received);
  /// Appends one part to the open bundle, flushing first what would pass kMaxBytes.
  bool AppendPart(const std::string& channel, const void* data, int size, int trailer);
  /// Signs (with a key) and publishes one message.
  bool PublishSigned(const std::string& channel, const void* data, int size);
  /// The bundle being flushed, signed where it lies: its trailer is appended to bundle_
  /// (whose capacity holds it) rather than the bundle copied next to one. The channel
  /// emulator sends a bundle to every vehicle each window, and a copy of each is lines
  /// that pass through the caches the vehicles share.
  bool PublishBundleSigned();
  /// A bundle received: verified as one message, then each part to the subscriptions whose
  /// pattern matches its channel, in order.
  void OnBundle(const lcm::ReceiveBuffer* rb, const std::string& channel);
  void OnBundleBytes(std::string_view channel, const unsigned char* p, int size);
  /// A message received in the caller, to the subscriptions LCM would hand it to.
  void Dispatch(std::string_view channel, const unsigned char* data, int size);
  /// The subscriptions whose pattern matches `channel` (a bundle part's), remembered per
  /// channel: a regular expression is matched once per channel, not once per part.
  const std::vector<Sub*>& SubsFor(std::string_view channel);
  bool FlushBundle();
  /// Sends one datagram's worth: into the batch while it is active, else through LCM.
  bool Send(const std::string& channel, const void* data, int size);
  std::string url_;
  lcm::LCM lcm_;
  UdpmBatch* batch_ = nullptr;  // SendThrough
  UdpmAddress address_;         // this bus's group, port and TTL (udpm only)
  std::unique_ptr<UdpmReceiver> receiver_;  // receiving in the caller; null: LCM's thread
  std::optional<bus_auth::Authenticator> auth_;
  std::int64_t rejected_ = 0;
  std::int64_t sent_ = 0;
  std::vector<unsigned char> signed_;  // a message and its trailer, reused
  std::vector<std::unique_ptr<Sub>> subs_;
  bool receiving_ = false;  // subscribed, and LCM's receive socket is open
  bool bundling_ = false;   // between BeginBundle and EndBundle
  bool recordable_ = false;  // the open bundle's parts are signed each (kMagicRecordable)
  int bundle_depth_ = 0;    // BeginBundle calls not yet ended
  int bundle_parts_ = 0;
  // bundle_wire::kMagic, then the parts (bundle_wire below); its capacity holds a trailer
  // more
  std::vector<unsigned char> bundle_;
  std::map<std::string, std::vector<Sub*>, std::less<>> routes_;  // SubsFor's memory
};

/// A bundle's channel and wire format: the 4-byte magic, then per part its channel's length
/// (1 byte, 1..kMaxChannel), the channel, the part's size (4 bytes, big-endian) and its
/// bytes. kMagic: authenticated as one message (the parts carry no trailer). kMagicRecordable:
/// each part is a message as it would go out alone, its own trailer included, and the bundle
/// has none (runtime/lcm_queue_shim.c parses this form too, in C: keep the two in step). A
/// bundle is cut before it would pass kMaxBytes, well under what LCM sends in one datagram (a
/// part larger than that goes alone).
namespace bundle_wire {
constexpr const char* kChannel = "SHOAL_BUNDLE";
constexpr unsigned char kMagic[4] = {'S', 'H', 'B', '1'};
constexpr unsigned char kMagicRecordable[4] = {'S', 'H', 'B', '2'};
constexpr int kMaxChannel = 63;  // LCM's longest channel name
constexpr int kMaxBytes = 60000;
/// Calls part(channel, data, size) for each part, in order; false (having called it for
/// none) if the bytes are not a well-formed bundle (either magic).
bool ForEachPart(const unsigned char* p, int size,
                 const std::function<void(std::string_view, const unsigned char*, int)>& part);
/// Whether the bytes start with kMagicRecordable.
bool Recordable(const unsigned char* p, int size);
}  // namespace bundle_wire

/// Whether the array counts a message declares fit its size. LCM 1.3.1's generated
/// decoders size each variable array by the count read from the message, in an `int`,
/// and resize the vector before checking that the bytes are there: a forged or damaged
/// count overflows that product (and reads out of bounds) or allocates gigabytes. Every
/// type with a variable array is checked here before it is decoded.
template <typename Msg>
bool ArrayCountsFit(const unsigned char* /*p*/, int /*size*/) {
  return true;  // no variable arrays
}
template <>
inline bool ArrayCountsFit<clock_window_t>(const unsigned char* p, int size) {
  constexpr int kFixed = 8 + 8 + 4 + 4 + 8 + 4 + 8 + 1 + 4;  // hash .. n_deliveries
  constexpr std::int64_t kPerDelivery = 8 + 4 + 4 + 4 + 8;
  if (size < kFixed) return false;
  const std::int64_t n = wire::I32(p + kFixed - 4);
  return n >= 0 && size - kFixed == n * kPerDelivery;
}
template <>
inline bool ArrayCountsFit<clock_tick_t>(const unsigned char* p, int size) {
  constexpr int kFixed = 8 + 8 + 4 + 4 + 8 + 8 + 1 + 4;  // hash .. n_deliveries
  constexpr std::int64_t kPerDelivery = 4 + 4 + 4 + 8;
  if (size < kFixed) return false;
  const std::int64_t n = wire::I32(p + kFixed - 4);
  return n >= 0 && size - kFixed == n * kPerDelivery;
}
template <>
inline bool ArrayCountsFit<channel_events_t>(const unsigned char* p, int size) {
  constexpr int kFixed = 8 + 8 + 4 + 4 + 4;  // hash .. n_events
  constexpr int kMinEvent = 8 + 4 + 4 + 4 + 4 + 4 + 8 + 8 + 8 + 1 + 4 + 1;  // reason ""
  if (size < kFixed) return false;
  const std::int64_t n = wire::I32(p + kFixed - 4);
  return n >= 0 && n <= (size - kFixed) / kMinEvent;
}

/// Whether every string a message declares has a length LCM 1.3.1's generated decoder can
/// take: it reads the length (the NUL included) as an `int`, checks only that it is not
/// more than the bytes left, and copies length - 1 bytes; a length of INT_MIN overflows
/// that subtraction (in practice a 2 GB read past the message). A length must be in
/// [1, bytes left]. Called after ArrayCountsFit (array counts are sane).
namespace wire_check {
/// Skips the string at *pos; false if its length is out of range or its bytes are not
/// what LCM's encoder writes: the text without NUL, then one NUL. The generated decoder
/// keeps an embedded NUL and drops the last byte unseen, so a damaged or forged string
/// would otherwise reach the analysis as text that C functions and TOML read differently.
inline bool SkipString(const unsigned char* p, int size, std::int64_t* pos) {
  if (*pos + 4 > size) return false;
  const std::int64_t len = wire::I32(p + *pos);
  *pos += 4;
  if (len < 1 || len > size - *pos) return false;
  const unsigned char* s = p + *pos;
  if (s[len - 1] != 0 || std::memchr(s, 0, static_cast<std::size_t>(len - 1)) != nullptr) {
    return false;
  }
  *pos += len;
  return true;
}
/// channel_event_t's fields before its string `reason` (utime .. status).
constexpr int kEventBeforeReason = 8 + 4 * 5 + 8 * 3 + 1;
}  // namespace wire_check
template <typename Msg>
bool StringLengthsFit(const unsigned char* /*p*/, int /*size*/) {
  return true;  // no strings
}
template <>
inline bool StringLengthsFit<run_status_t>(const unsigned char* p, int size) {
  std::int64_t pos = 8 + 8 + 4 + 4;  // hash .. seq
  for (int k = 0; k < 3; ++k) {      // state, scenario_name, scenario_toml
    if (!wire_check::SkipString(p, size, &pos)) return false;
  }
  pos += 8 + 4;  // seed, followers
  return wire_check::SkipString(p, size, &pos);  // message
}
template <>
inline bool StringLengthsFit<channel_event_t>(const unsigned char* p, int size) {
  std::int64_t pos = 8 + wire_check::kEventBeforeReason;
  return wire_check::SkipString(p, size, &pos);
}
template <>
inline bool StringLengthsFit<channel_events_t>(const unsigned char* p, int size) {
  std::int64_t pos = 8 + 8 + 4 + 4 + 4;  // hash .. n_events
  const std::int64_t n = wire::I32(p + pos - 4);
  for (std::int64_t k = 0; k < n; ++k) {
    pos += wire_check::kEventBeforeReason;
    if (!wire_check::SkipString(p, size, &pos)) return false;
  }
  return true;
}

/// Decodes an LCM message; false (never an exception, never an out-of-bounds read) on a
/// truncated message, a wrong fingerprint, an array count or a string length that does not
/// fit, or garbage.
template <typename Msg>
bool Decode(const void* data, int size, Msg* out) {
  if (data == nullptr || size < 8) return false;
  const auto* bytes = static_cast<const unsigned char*>(data);
  if constexpr (std::is_same_v<Msg, vehicle_state_t>) {
    return state_wire::Decode(bytes, size, out);
  } else {
    if (!ArrayCountsFit<Msg>(bytes, size) || !StringLengthsFit<Msg>(bytes, size)) return false;
    // The checks above refuse the string lengths <= 0 on which LCM's generated decoder
    // throws std::length_error; the catch keeps any exception they do not foresee (an
    // allocation failure) from terminating a process inside its LCM handler.
    try {
      return out->decode(data, 0, size) == size;
    } catch (...) {
      return false;
    }
  }
}

/// FNV-1a, 64 bits, of a message's bytes (a checkpoint's checksum).
inline std::int64_t Digest64(const void* data, int size) {
  std::uint64_t h = 14695981039346656037ULL;
  const auto* p = static_cast<const unsigned char*>(data);
  for (int k = 0; k < size; ++k) h = (h ^ p[k]) * 1099511628211ULL;
  return static_cast<std::int64_t>(h);
}

/// Identifies a delivery in a lockstep clock window: FNV-1a's step over the message's
/// 64-bit little-endian words (the last one zero-padded), then its length. Each step is a
/// bijection of the running value, so any one changed word changes the digest; the
/// messages are authenticated already, and this only ties each to the clock that lists
/// it. A byte at a time (Digest64) cost a vehicle 7 % of its CPU at 64 followers.
inline std::int64_t DeliveryDigest(const void* data, int size) {
  constexpr std::uint64_t kPrime = 1099511628211ULL;
  std::uint64_t h = 14695981039346656037ULL;
  const auto* p = static_cast<const unsigned char*>(data);
  int k = 0;
  for (; k + 8 <= size; k += 8) {
    std::uint64_t w;
    std::memcpy(&w, p + k, sizeof(w));
#if __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
    w = __builtin_bswap64(w);
#endif
    h = (h ^ w) * kPrime;
  }
  std::uint64_t tail = 0;
  for (int j = 0; k + j < size; ++j) tail |= static_cast<std::uint64_t>(p[k + j]) << (8 * j);
  h = (h ^ tail) * kPrime;
  h = (h ^ static_cast<std::uint64_t>(size > 0 ? size : 0)) * kPrime;
  return static_cast<std::int64_t>(h);
}

/// The LCM URL of a private run: multicast group, own port, ttl=0 (never leaves the host).
std::string PrivateLcmUrl(int port, const std::string& group = "239.255.76.67");

/// A random port for a private run with `followers` followers: the first of a block of
/// followers + 3 ports (the shared bus, one per vehicle, the uplink), aligned to its size, so
/// that two runs with as many followers get the same block or disjoint ones (runs of
/// different sizes can overlap; any two runs collide with a small probability, as two
/// random ports can), at or above kPrivatePortLow and below the kernel's ephemeral port
/// range (/proc/sys/net/ipv4/ip_local_port_range), where a sending socket anywhere on the
/// host could take one of them. A block some socket already holds is not chosen (up to 64
/// draws).
int RandomPrivatePort(int followers);
constexpr int kPrivatePortLow = 10000;

/// The URL on which each vehicle 0..followers receives in a private run on `port`: a
/// port and a group of its own. The port is what isolates: LCM binds its receive socket
/// to INADDR_ANY:port, and Linux delivers to such a socket the datagrams of every group
/// joined on the host for that port (IP_MULTICAST_ALL), so vehicles on one port and
/// different groups would still receive -- and wake up for -- each other's traffic.
/// Groups 239.255.77-82.x (up to 1200 vehicles), never the shared 239.255.76.67.
std::vector<std::string> PerVehicleLcmUrls(int port, int followers);

/// The URL on which the vehicles and the leader of a private run on `port` publish when
/// only the channel emulator is to hear them (ChannelEmulatorApp::SetUplink): the last port
/// of the run's block, on a group of its own.
std::string UplinkLcmUrl(int port, int followers);

/// Makes sure multicast on the private groups stays on loopback (adds the route as
/// root). False with the reason and the command to run in `err` otherwise.
bool EnsureLoopbackMulticast(std::string* err);

}  // namespace shoal
