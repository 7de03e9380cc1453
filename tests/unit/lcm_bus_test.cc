// Tests of runtime/lcm_bus: one call of Handle() dispatches a bounded number of messages;
// Decode refuses strings LCM's encoder cannot have written; bundles reach subscribers as
// their parts, in order, and only whole and authenticated.
#include "runtime/lcm_bus.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
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


bus_auth::Key TestKey(unsigned char fill) {
  bus_auth::Key k;
  k.fill(fill);
  return k;
}

struct Received {
  std::string channel;
  std::string bytes;
};

// Given messages published between BeginBundle and EndBundle on an authenticated bus, when
// the receiver handles the bus, then each subscriber gets exactly the parts on its
// channels, in publication order and byte for byte, as if they had been sent one by one,
// and it is one message on the bus.
TEST(LcmBus, ABundleReachesEachSubscriberAsItsPartsInOrder) {
  LcmBus bus("memq://", TestKey(7));
  std::vector<Received> rx, clock;
  bus.Subscribe("SHOAL_RX_[0-9]+", [&](const std::string& ch, const void* d, int n) {
    rx.push_back({ch, std::string(static_cast<const char*>(d), static_cast<std::size_t>(n))});
  });
  bus.Subscribe("SHOAL_CLOCK", [&](const std::string& ch, const void* d, int n) {
    clock.push_back({ch, std::string(static_cast<const char*>(d), static_cast<std::size_t>(n))});
  });
  bus.BeginBundle();
  ASSERT_TRUE(bus.PublishRaw("SHOAL_RX_3", "first", 5));
  ASSERT_TRUE(bus.PublishRaw("SHOAL_RX_3", "second", 6));
  ASSERT_TRUE(bus.PublishRaw("OTHER", "x", 1));  // nobody listens: dropped, not misrouted
  ASSERT_TRUE(bus.PublishRaw("SHOAL_CLOCK", "tick", 4));
  ASSERT_TRUE(bus.EndBundle());
  EXPECT_EQ(bus.Handle(0), 1);  // one message on the bus
  ASSERT_EQ(rx.size(), 2u);
  EXPECT_EQ(rx[0].channel, "SHOAL_RX_3");
  EXPECT_EQ(rx[0].bytes, "first");
  EXPECT_EQ(rx[1].bytes, "second");
  ASSERT_EQ(clock.size(), 1u);
  EXPECT_EQ(clock[0].bytes, "tick");
  EXPECT_EQ(bus.rejected(), 0);
  // A single message goes out as it is; after EndBundle, messages go out one by one.
  bus.BeginBundle();
  ASSERT_TRUE(bus.PublishRaw("SHOAL_CLOCK", "alone", 5));
  ASSERT_TRUE(bus.EndBundle());
  ASSERT_TRUE(bus.PublishRaw("SHOAL_CLOCK", "after", 5));
  EXPECT_EQ(bus.Handle(0), 2);
  ASSERT_EQ(clock.size(), 3u);
  EXPECT_EQ(clock[1].bytes, "alone");
  EXPECT_EQ(clock[2].bytes, "after");
}

// Given a subscriber that passes messages on as they came (the channel emulator's uplink),
// when plain messages, a recordable bundle and a bundle signed whole arrive, then it gets
// every message, bundled or not, with the trailer it would have had alone: what it passes
// on verifies for any reader with the run's key, byte for byte as the sender's bus signs.
TEST(LcmBus, AsReceivedSubscribersGetEachMessageWithItsOwnTrailer) {
  const bus_auth::Key key = TestKey(9);
  LcmBus bus("memq://", key);
  std::vector<Received> got;
  bus.SubscribeAsReceived("SHOAL_.*", [&](const std::string& ch, const void* d, int n) {
    got.push_back({ch, std::string(static_cast<const char*>(d), static_cast<std::size_t>(n))});
  });
  ASSERT_TRUE(bus.PublishRaw("SHOAL_STATUS", "alone", 5));
  bus.BeginBundle(/*recordable=*/true);
  ASSERT_TRUE(bus.PublishRaw("SHOAL_STATE_1", "r1", 2));
  ASSERT_TRUE(bus.PublishRaw("SHOAL_STATE_2", "r2", 2));
  ASSERT_TRUE(bus.EndBundle());
  bus.BeginBundle();
  ASSERT_TRUE(bus.PublishRaw("SHOAL_RX_1", "w1", 2));
  ASSERT_TRUE(bus.PublishRaw("SHOAL_CLOCK", "w2", 2));
  ASSERT_TRUE(bus.EndBundle());
  while (bus.Handle(0) > 0) {
  }
  ASSERT_EQ(got.size(), 5u);
  const std::vector<std::pair<std::string, std::string>> want = {
      {"SHOAL_STATUS", "alone"}, {"SHOAL_STATE_1", "r1"}, {"SHOAL_STATE_2", "r2"},
      {"SHOAL_RX_1", "w1"}, {"SHOAL_CLOCK", "w2"}};
  for (std::size_t k = 0; k < want.size(); ++k) {
    EXPECT_EQ(got[k].channel, want[k].first);
    const std::string& b = got[k].bytes;
    ASSERT_EQ(b.size(), want[k].second.size() + bus_auth::kTrailerBytes) << k;
    EXPECT_EQ(bus_auth::Verify(key, got[k].channel, b.data(), static_cast<int>(b.size())),
              static_cast<int>(want[k].second.size()))
        << k;
    EXPECT_EQ(b.substr(0, want[k].second.size()), want[k].second);
  }
  EXPECT_EQ(bus.rejected(), 0);
}

// Given a bundle larger than one datagram should carry, when it is sent, then it goes out
// as several bundles, cut between parts, and every part arrives once, in order.
TEST(LcmBus, ALargeBundleIsCutBetweenPartsAndLosesNone) {
  LcmBus bus("memq://", TestKey(7));
  std::vector<int> seen;
  bus.Subscribe("SHOAL_RX_1", [&](const std::string&, const void* d, int n) {
    ASSERT_EQ(n, 1000);
    int v;
    std::memcpy(&v, d, sizeof(v));
    seen.push_back(v);
  });
  std::vector<unsigned char> part(1000, 0);
  bus.BeginBundle();
  for (int i = 0; i < 150; ++i) {  // 150 kB: three bundles of at most 60 kB
    std::memcpy(part.data(), &i, sizeof(i));
    ASSERT_TRUE(bus.PublishRaw("SHOAL_RX_1", part.data(), static_cast<int>(part.size())));
  }
  ASSERT_TRUE(bus.EndBundle());
  EXPECT_EQ(bus.Handle(0), 3);
  ASSERT_EQ(seen.size(), 150u);
  for (int i = 0; i < 150; ++i) EXPECT_EQ(seen[i], i);
}

// Given a well-signed bundle whose part lengths do not fit, or without the magic, when it
// arrives, then no part of it reaches any subscriber (a bundle is taken whole or not at
// all) and it is counted as rejected.
TEST(LcmBus, AMalformedBundleDeliversNothing) {
  LcmBus bus("memq://", TestKey(2));
  std::vector<std::string> got;
  bus.Subscribe("SHOAL_RX_1", [&](const std::string&, const void* d, int n) {
    got.emplace_back(static_cast<const char*>(d), static_cast<std::size_t>(n));
  });
  std::vector<unsigned char> b(std::begin(bundle_wire::kMagic), std::end(bundle_wire::kMagic));
  auto add = [&](const std::string& payload, std::uint32_t declared) {
    const std::string ch = "SHOAL_RX_1";
    b.push_back(static_cast<unsigned char>(ch.size()));
    b.insert(b.end(), ch.begin(), ch.end());
    for (int shift = 24; shift >= 0; shift -= 8) {
      b.push_back(static_cast<unsigned char>(declared >> shift));
    }
    b.insert(b.end(), payload.begin(), payload.end());
  };
  add("good", 4);
  add("bad", 300);  // claims more than the bundle holds
  // PublishRaw signs it with the bus's own key: it authenticates, and is still refused.
  ASSERT_TRUE(bus.PublishRaw(bundle_wire::kChannel, b.data(), static_cast<int>(b.size())));
  EXPECT_EQ(bus.Handle(0), 1);
  EXPECT_TRUE(got.empty());
  EXPECT_EQ(bus.rejected(), 1);
  b.resize(b.size() - 3 - 4 - 10 - 1);  // only the good part is left
  const std::vector<unsigned char> no_magic(b.begin() + 4, b.end());
  ASSERT_TRUE(bus.PublishRaw(bundle_wire::kChannel, no_magic.data(),
                             static_cast<int>(no_magic.size())));
  EXPECT_EQ(bus.Handle(0), 1);
  EXPECT_TRUE(got.empty());
  EXPECT_EQ(bus.rejected(), 2);
  ASSERT_TRUE(bus.PublishRaw(bundle_wire::kChannel, b.data(), static_cast<int>(b.size())));
  EXPECT_EQ(bus.Handle(0), 1);
  ASSERT_EQ(got.size(), 1u);  // the same bytes, well formed: taken
  EXPECT_EQ(got[0], "good");
}

// Given a bundle signed with another run's key, when it arrives over udpm, then nothing of
// it is delivered and it is counted as rejected, as a single forged message would be.
TEST(LcmBus, ABundleWithAnotherKeyDeliversNothing) {
  const std::string url = PrivateLcmUrl(RandomPrivatePort(1));
  LcmBus forger(url, TestKey(1));
  LcmBus receiver(url, TestKey(2));
  int got = 0;
  receiver.Subscribe("SHOAL_RX_1", [&](const std::string&, const void*, int) { ++got; });
  forger.BeginBundle();
  ASSERT_TRUE(forger.PublishRaw("SHOAL_RX_1", "a", 1));
  ASSERT_TRUE(forger.PublishRaw("SHOAL_RX_1", "b", 1));
  ASSERT_TRUE(forger.EndBundle());
  EXPECT_EQ(receiver.Handle(2000), 1);
  EXPECT_EQ(got, 0);
  EXPECT_EQ(receiver.rejected(), 1);
}

// Given two receivers that share one bus, each opening its own bundle on it (the channel
// emulator in real time, with --vehicle-urls naming one group twice), when both are
// closed, then every part of both arrives: a second BeginBundle drops nothing.
TEST(LcmBus, NestedBundlesOnOneBusLoseNoPart) {
  LcmBus bus("memq://", TestKey(7));
  int rx1 = 0, rx2 = 0;
  bus.Subscribe("SHOAL_RX_1", [&](const std::string&, const void*, int) { ++rx1; });
  bus.Subscribe("SHOAL_RX_2", [&](const std::string&, const void*, int) { ++rx2; });
  bus.BeginBundle();
  ASSERT_TRUE(bus.PublishRaw("SHOAL_RX_1", "a", 1));
  bus.BeginBundle();
  ASSERT_TRUE(bus.PublishRaw("SHOAL_RX_2", "b", 1));
  ASSERT_TRUE(bus.EndBundle());
  EXPECT_EQ(bus.Handle(0), 0);  // nothing out until the outer bundle closes
  ASSERT_TRUE(bus.EndBundle());
  EXPECT_EQ(bus.Handle(0), 1);
  EXPECT_EQ(rx1, 1);
  EXPECT_EQ(rx2, 1);
  EXPECT_TRUE(bus.EndBundle());  // an unmatched end sends nothing and breaks nothing
}

// Given a well-signed bundle with a part on the bundle channel itself, when it arrives,
// then nothing of it reaches a subscriber whose pattern matches that channel (no bundle
// rides inside another past the subscribers' exclusion of the bundle channel).
TEST(LcmBus, ABundleInsideABundleIsRefused) {
  LcmBus bus("memq://", TestKey(3));
  int got = 0;
  bus.Subscribe("SHOAL_.*", [&](const std::string&, const void*, int) { ++got; });
  std::vector<unsigned char> b(std::begin(bundle_wire::kMagic), std::end(bundle_wire::kMagic));
  const std::string ch = bundle_wire::kChannel;
  b.push_back(static_cast<unsigned char>(ch.size()));
  b.insert(b.end(), ch.begin(), ch.end());
  b.insert(b.end(), {0, 0, 0, 1, 'x'});
  ASSERT_TRUE(bus.PublishRaw(bundle_wire::kChannel, b.data(), static_cast<int>(b.size())));
  EXPECT_EQ(bus.Handle(0), 1);
  EXPECT_EQ(got, 0);
  EXPECT_EQ(bus.rejected(), 1);
}

// Given a recordable bundle published on an authenticated bus, when a receiver with the
// run's key and one without any key (shoal live, which verifies by itself) handle the bus,
// then the keyed one gets each part without its trailer, and the unkeyed one gets each
// part exactly as the message would have come alone: its bytes and its own trailer.
TEST(LcmBus, ARecordableBundleArrivesAsItsMessagesWouldAlone) {
  const std::string url = PrivateLcmUrl(RandomPrivatePort(1));
  LcmBus sender(url, TestKey(5));
  LcmBus keyed(url, TestKey(5));
  LcmBus open(url);
  std::vector<Received> got_keyed, got_open;
  keyed.Subscribe("SHOAL_STATE_[0-9]+", [&](const std::string& ch, const void* d, int n) {
    got_keyed.push_back({ch, std::string(static_cast<const char*>(d), static_cast<std::size_t>(n))});
  });
  open.Subscribe("SHOAL_.*", [&](const std::string& ch, const void* d, int n) {
    got_open.push_back({ch, std::string(static_cast<const char*>(d), static_cast<std::size_t>(n))});
  });
  sender.BeginBundle(/*recordable=*/true);
  ASSERT_TRUE(sender.PublishRaw("SHOAL_STATE_4", "tick0", 5));
  ASSERT_TRUE(sender.PublishRaw("SHOAL_STATE_4", "tick1", 5));
  ASSERT_TRUE(sender.PublishRaw("SHOAL_HEALTH_4", "health", 6));
  ASSERT_TRUE(sender.EndBundle());
  EXPECT_EQ(keyed.Handle(2000), 1);  // one datagram
  EXPECT_EQ(open.Handle(2000), 1);
  ASSERT_EQ(got_keyed.size(), 2u);
  EXPECT_EQ(got_keyed[0].bytes, "tick0");
  EXPECT_EQ(got_keyed[1].bytes, "tick1");
  EXPECT_EQ(keyed.rejected(), 0);
  ASSERT_EQ(got_open.size(), 3u);
  const char* texts[] = {"tick0", "tick1", "health"};
  for (int k = 0; k < 3; ++k) {
    const std::string text = texts[k];
    std::string alone = text + std::string(bus_auth::kTrailerBytes, '\0');
    bus_auth::Sign(TestKey(5), got_open[k].channel, text.data(), static_cast<int>(text.size()),
                   reinterpret_cast<unsigned char*>(&alone[text.size()]));
    EXPECT_EQ(got_open[k].bytes, alone) << k;
  }
  EXPECT_EQ(got_open[2].channel, "SHOAL_HEALTH_4");
}

// Given a recordable bundle one of whose parts is signed with another key, when it
// arrives, then none of its parts is delivered and it counts as one rejection.
TEST(LcmBus, ARecordableBundleWithOneForgedPartDeliversNothing) {
  const std::string url = PrivateLcmUrl(RandomPrivatePort(1));
  LcmBus sender(url);  // builds the bundle by hand
  LcmBus receiver(url, TestKey(6));
  int got = 0;
  receiver.Subscribe("SHOAL_STATE_1", [&](const std::string&, const void*, int) { ++got; });
  std::vector<unsigned char> b(std::begin(bundle_wire::kMagicRecordable),
                               std::end(bundle_wire::kMagicRecordable));
  auto add = [&](const bus_auth::Key& key, const std::string& text) {
    const std::string ch = "SHOAL_STATE_1";
    std::vector<unsigned char> m(text.begin(), text.end());
    m.resize(text.size() + bus_auth::kTrailerBytes);
    bus_auth::Sign(key, ch, text.data(), static_cast<int>(text.size()), m.data() + text.size());
    b.push_back(static_cast<unsigned char>(ch.size()));
    b.insert(b.end(), ch.begin(), ch.end());
    for (int shift = 24; shift >= 0; shift -= 8) {
      b.push_back(static_cast<unsigned char>(m.size() >> shift));
    }
    b.insert(b.end(), m.begin(), m.end());
  };
  add(TestKey(6), "good");
  add(TestKey(9), "forged");
  ASSERT_TRUE(sender.PublishRaw(bundle_wire::kChannel, b.data(), static_cast<int>(b.size())));
  EXPECT_EQ(receiver.Handle(2000), 1);
  EXPECT_EQ(got, 0);
  EXPECT_EQ(receiver.rejected(), 1);
}

}  // namespace
}  // namespace shoal

namespace shoal {
namespace {

// A delivery's digest changes with any one changed byte, and with the length (a message
// and the same bytes with a zero appended differ).
TEST(DeliveryDigest, AnyChangedByteOrLengthChangesIt) {
  std::vector<unsigned char> m(228);
  for (std::size_t k = 0; k < m.size(); ++k) m[k] = static_cast<unsigned char>(k * 7 + 1);
  const std::int64_t d = DeliveryDigest(m.data(), static_cast<int>(m.size()));
  EXPECT_EQ(d, DeliveryDigest(m.data(), static_cast<int>(m.size())));
  for (std::size_t k = 0; k < m.size(); ++k) {
    for (int bit = 0; bit < 8; ++bit) {
      auto f = m;
      f[k] ^= static_cast<unsigned char>(1 << bit);
      ASSERT_NE(DeliveryDigest(f.data(), static_cast<int>(f.size())), d) << k << ":" << bit;
    }
  }
  auto longer = m;
  longer.push_back(0);
  EXPECT_NE(DeliveryDigest(longer.data(), static_cast<int>(longer.size())), d);
  EXPECT_NE(DeliveryDigest(m.data(), 227), d);
  EXPECT_NE(DeliveryDigest(nullptr, 0), DeliveryDigest(m.data(), 1));
}

}  // namespace
}  // namespace shoal
