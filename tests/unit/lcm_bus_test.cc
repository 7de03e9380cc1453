// Tests of runtime/lcm_bus: one call of Handle() dispatches a bounded number of messages.
#include "runtime/lcm_bus.h"

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace shoal
