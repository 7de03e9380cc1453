// Fuzz target: runtime/lcm_bus.h's Decode for every message type of the bus. The first
// byte chooses the type, the rest is the message. Decode must return false on anything
// it cannot read (never throw, never read out of bounds, never allocate without bound),
// and a message it accepts must encode again to exactly `size` bytes that decode too.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include <shoal/channel_event_t.hpp>
#include <shoal/channel_events_t.hpp>
#include <shoal/clock_tick_t.hpp>
#include <shoal/clock_window_t.hpp>
#include <shoal/health_t.hpp>
#include <shoal/run_status_t.hpp>
#include <shoal/vehicle_state_t.hpp>

#include "runtime/lcm_bus.h"

namespace {

template <typename Msg>
void DecodeOne(const std::uint8_t* data, int size) {
  Msg msg;
  if (!shoal::Decode(data, size, &msg)) return;
  // Accepted: the message is whole, so it re-encodes to as many bytes (strings may differ
  // from the input only in bytes after an embedded NUL) and decodes again.
  const int encoded_size = msg.getEncodedSize();
  if (encoded_size != size) std::abort();
  std::vector<std::uint8_t> buf(encoded_size);
  if (msg.encode(buf.data(), 0, encoded_size) != encoded_size) std::abort();
  Msg again;
  if (!shoal::Decode(buf.data(), encoded_size, &again)) std::abort();
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
    case 4: DecodeOne<shoal::health_t>(msg, n); break;
    case 5: DecodeOne<shoal::run_status_t>(msg, n); break;
    case 6: DecodeOne<shoal::channel_event_t>(msg, n); break;
  }
  return 0;
}
