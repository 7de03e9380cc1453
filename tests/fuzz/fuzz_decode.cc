// Fuzz target: runtime/lcm_bus.h's Decode for every message type of the bus. The first
// byte chooses the type, the rest is the message. Decode must return false on anything
// it cannot read (never throw, never read out of bounds, never allocate without bound),
// and a message it accepts must encode again to exactly `size` bytes that decode too --
// unless a string holds a NUL byte: LCM's decoder keeps the string's bytes as they are,
// its encoder writes them up to the first NUL (strlen), so such a message re-encodes
// shorter (and encode() returns less than getEncodedSize()). The same bytes are also read
// as a bundle (BundleParts), and as LCM udpm datagrams as a process's own socket reader
// takes them (runtime/udpm_receiver.h: short messages and fragments, Datagrams).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>
#include <vector>

#include <shoal/channel_event_t.hpp>
#include <shoal/channel_events_t.hpp>
#include <shoal/clock_tick_t.hpp>
#include <shoal/clock_window_t.hpp>
#include <shoal/health2_t.hpp>
#include <shoal/health_t.hpp>
#include <shoal/run_status_t.hpp>
#include <shoal/vehicle_state_t.hpp>

#include "runtime/lcm_bus.h"
#include "runtime/udpm_receiver.h"

namespace {

bool HasNul(const std::string& s) { return s.find('\0') != std::string::npos; }

template <typename Msg>
bool StringsWithoutNul(const Msg&) {
  return true;  // no strings
}
bool StringsWithoutNul(const shoal::run_status_t& m) {
  return !HasNul(m.state) && !HasNul(m.scenario_name) && !HasNul(m.scenario_toml) &&
         !HasNul(m.message);
}
bool StringsWithoutNul(const shoal::channel_event_t& m) { return !HasNul(m.reason); }
bool StringsWithoutNul(const shoal::channel_events_t& m) {
  for (const shoal::channel_event_t& e : m.events) {
    if (HasNul(e.reason)) return false;
  }
  return true;
}

template <typename Msg>
void DecodeOne(const std::uint8_t* data, int size) {
  Msg msg;
  if (!shoal::Decode(data, size, &msg) || !StringsWithoutNul(msg)) return;
  // Accepted: the message is whole, so it re-encodes to as many bytes (strings may differ
  // from the input only in bytes after an embedded NUL) and decodes again.
  const int encoded_size = msg.getEncodedSize();
  if (encoded_size != size) std::abort();
  std::vector<std::uint8_t> buf(encoded_size);
  if (msg.encode(buf.data(), 0, encoded_size) != encoded_size) std::abort();
  Msg again;
  if (!shoal::Decode(buf.data(), encoded_size, &again)) std::abort();
}

// The same bytes as a bundle (either form, bundle_wire in runtime/lcm_bus.h): every part
// it hands on lies inside the bundle, with a channel of 1..kMaxChannel characters, and the
// parts with their headers cover the bundle exactly; a bundle it refuses hands on nothing.
void BundleParts(const std::uint8_t* p, int size) {
  std::int64_t covered = sizeof(shoal::bundle_wire::kMagic);
  int parts = 0;
  const bool ok = shoal::bundle_wire::ForEachPart(
      p, size, [&](std::string_view ch, const unsigned char* d, int n) {
        if (ch.empty() || ch.size() > static_cast<std::size_t>(shoal::bundle_wire::kMaxChannel) ||
            n < 0 || d < p || d + n > p + size) {
          std::abort();
        }
        covered += 1 + static_cast<std::int64_t>(ch.size()) + 4 + n;
        ++parts;
      });
  if (!ok && parts != 0) std::abort();
  if (ok && covered != size) std::abort();
}

// The bytes as datagrams to one receiver: cut at each "|||" (so that fragments of one
// message can follow each other), the odd pieces from a second sender. What it hands on must
// lie inside the message it assembled, with a channel of at most 63 characters; what it
// cannot read is counted, never handed on.
void Datagrams(const std::uint8_t* data, int size) {
  shoal::UdpmAddress address;
  shoal::UdpmReceiver rx(address);
  sockaddr_in from[2] = {};
  from[1].sin_port = 1;
  const std::string_view all(reinterpret_cast<const char*>(data), static_cast<std::size_t>(size));
  std::size_t start = 0;
  for (int k = 0; start <= all.size(); ++k) {
    std::size_t end = all.find("|||", start);
    if (end == std::string_view::npos) end = all.size();
    rx.OnDatagram(data + start, static_cast<int>(end - start), from[k % 2],
                  [](std::string_view ch, const unsigned char* d, int n) {
                    if (ch.size() > 63 || n < 0 || (n > 0 && d == nullptr)) std::abort();
                    volatile unsigned char sink = 0;
                    for (int i = 0; i < n; ++i) sink = sink ^ d[i];  // every byte readable
                  });
    start = end + 3;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1 || size > (1u << 20)) return 0;
  const std::uint8_t* msg = data + 1;
  const int n = static_cast<int>(size - 1);
  switch (data[0] % 7) {
    case 0: DecodeOne<shoal::vehicle_state_t>(msg, n); break;
    case 1: DecodeOne<shoal::clock_window_t>(msg, n); break;
    case 2: DecodeOne<shoal::clock_tick_t>(msg, n); break;
    case 3: DecodeOne<shoal::channel_events_t>(msg, n); break;
    case 4:  // both health layouts: the selector's meaning stays that of the saved inputs
      DecodeOne<shoal::health_t>(msg, n);
      DecodeOne<shoal::health2_t>(msg, n);
      break;
    case 5: DecodeOne<shoal::run_status_t>(msg, n); break;
    case 6: DecodeOne<shoal::channel_event_t>(msg, n); break;
  }
  BundleParts(msg, n);
  Datagrams(msg, n);
  return 0;
}
