// Tests of runtime/lcm_bus: one call of Handle() dispatches a bounded number of messages;
// Decode refuses strings LCM's encoder cannot have written.
#include "runtime/lcm_bus.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

namespace shoal {
namespace {

// Given a flood already queued on the bus, when a process handles the bus, then one call
// dispatches at most kMaxMessagesPerHandle of it and the rest follows, in order, on the
// next calls: what the process buffers between two calls stays bounded.
TEST(LcmBus, OneHandleDispatchesABoundedNumberOfMessagesInOrder) {
  LcmBus bus("memq://");
  std::vector<int> seen;
  bus.Subscribe("FLOOD", [&](const std::string&, const void* d, int n) {
    ASSERT_EQ(n, static_cast<int>(sizeof(int)));
    seen.push_back(*static_cast<const int*>(d));
  });
  const int total = 2 * Bus::kMaxMessagesPerHandle + 10;
  for (int i = 0; i < total; ++i) ASSERT_TRUE(bus.PublishRaw("FLOOD", &i, sizeof(i)));
  EXPECT_EQ(bus.Handle(0), Bus::kMaxMessagesPerHandle);
  EXPECT_EQ(static_cast<int>(seen.size()), Bus::kMaxMessagesPerHandle);
  EXPECT_EQ(bus.Handle(0), Bus::kMaxMessagesPerHandle);
  EXPECT_EQ(bus.Handle(0), 10);
  EXPECT_EQ(bus.Handle(0), 0);
  ASSERT_EQ(static_cast<int>(seen.size()), total);
  for (int i = 0; i < total; ++i) ASSERT_EQ(seen[i], i);
}

// Given a status whose text LCM's encoder wrote (text, then one NUL), when a byte of the
// text becomes NUL or the closing NUL becomes text, then Decode refuses the message: such
// a string comes only from damage or forgery, and its C++ and C readings differ.
TEST(LcmBus, DecodeRefusesStringsWithANulInsideOrNoClosingNul) {
  run_status_t st{};
  st.state = "running";
  st.scenario_name = "abc";
  st.scenario_toml = "";
  st.message = "";
  std::vector<std::uint8_t> good(static_cast<std::size_t>(st.getEncodedSize()));
  ASSERT_EQ(st.encode(good.data(), 0, static_cast<int>(good.size())),
            static_cast<int>(good.size()));
  run_status_t out;
  ASSERT_TRUE(Decode(good.data(), static_cast<int>(good.size()), &out));
  EXPECT_EQ(out.state, "running");
  const std::size_t text = 8 + 8 + 4 + 4 + 4;  // hash .. seq, then state's length
  for (std::size_t k = 0; k < 7; ++k) {
    std::vector<std::uint8_t> bad = good;
    bad[text + k] = 0;  // a NUL inside "running"
    EXPECT_FALSE(Decode(bad.data(), static_cast<int>(bad.size()), &out)) << k;
  }
  std::vector<std::uint8_t> open = good;
  open[text + 7] = 'x';  // the closing NUL replaced
  EXPECT_FALSE(Decode(open.data(), static_cast<int>(open.size()), &out));
}

}  // namespace
}  // namespace shoal
