// Tests of runtime/bus_auth and the authenticated LcmBus: a message verifies only with its
// run's key, on its channel, with every bit as sent.
#include "runtime/bus_auth.h"

#include <gtest/gtest.h>
#include <sodium.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "runtime/lcm_bus.h"
#include "runtime/siphash.h"

namespace shoal::bus_auth {
namespace {

std::vector<unsigned char> Signed(const Key& k, const std::string& channel,
                                  const std::string& payload) {
  std::vector<unsigned char> b(payload.begin(), payload.end());
  b.resize(payload.size() + kTrailerBytes);
  Sign(k, channel, payload.data(), static_cast<int>(payload.size()), b.data() + payload.size());
  return b;
}

int VerifyBytes(const Key& k, const std::string& channel, const std::vector<unsigned char>& b) {
  return Verify(k, channel, b.data(), static_cast<int>(b.size()));
}

TEST(BusAuth, SignedMessageVerifiesWithItsKeyAndChannelOnly) {
  const Key k = NewKey(), other = NewKey();
  ASSERT_NE(k, other);
  const std::string payload = "a vehicle state's bytes";
  const auto b = Signed(k, "SHOAL_STATE_1", payload);
  EXPECT_EQ(VerifyBytes(k, "SHOAL_STATE_1", b), static_cast<int>(payload.size()));
  EXPECT_TRUE(HasTrailer(b.data(), static_cast<int>(b.size())));
  EXPECT_EQ(VerifyBytes(other, "SHOAL_STATE_1", b), -1);  // another run's key
  EXPECT_EQ(VerifyBytes(k, "SHOAL_STATE_2", b), -1);      // moved to another channel
  EXPECT_EQ(VerifyBytes(k, "SHOAL_STATE_1X", b), -1);
  // Channel and payload are separated: "A" + "Bx" is not "AB" + "x".
  EXPECT_EQ(VerifyBytes(k, "SHOAL_STATE_", Signed(k, "SHOAL_STATE_1", "x")), -1);
  EXPECT_EQ(VerifyBytes(k, "", Signed(k, "", "")), 0);  // an empty message is fine
}

TEST(BusAuth, AnyChangedBitOrTruncationFails) {
  const Key k = NewKey();
  const auto b = Signed(k, "SHOAL_CLOCK", "tick 42, deliveries ...");
  for (std::size_t byte = 0; byte < b.size(); ++byte) {
    for (int bit = 0; bit < 8; ++bit) {
      auto f = b;
      f[byte] ^= static_cast<unsigned char>(1 << bit);
      ASSERT_EQ(VerifyBytes(k, "SHOAL_CLOCK", f), -1) << byte << ":" << bit;
    }
  }
  for (std::size_t cut = 1; cut <= b.size(); ++cut) {
    const std::vector<unsigned char> t(b.begin(), b.end() - static_cast<std::ptrdiff_t>(cut));
    ASSERT_EQ(VerifyBytes(k, "SHOAL_CLOCK", t), -1) << cut;
  }
  // Unsigned bytes, and a plain message with no trailer.
  EXPECT_EQ(Verify(k, "SHOAL_CLOCK", nullptr, 0), -1);
  const std::string plain(100, 'x');
  EXPECT_EQ(Verify(k, "SHOAL_CLOCK", plain.data(), 100), -1);
  EXPECT_FALSE(HasTrailer(plain.data(), 100));
}

// SipHash-2-4-128 computed in pieces equals libsodium's crypto_shorthash_siphashx24 of the
// whole, for every length up to 300 bytes and a few long ones, split anywhere.
TEST(SipHash128, EqualsLibsodiumForAnyLengthAndAnySplit) {
  ASSERT_GE(sodium_init(), 0);
  std::mt19937_64 rng(7);
  auto bytes = [&](std::size_t n) {
    std::vector<unsigned char> b(n);
    for (unsigned char& c : b) c = static_cast<unsigned char>(rng());
    return b;
  };
  // The reference vector of the empty message under the key 00 01 ... 0f.
  std::vector<unsigned char> key(16);
  for (int k = 0; k < 16; ++k) key[static_cast<std::size_t>(k)] = static_cast<unsigned char>(k);
  unsigned char got[16], want[16];
  SipHash128 empty(key.data());
  empty.Final(got);
  const unsigned char reference[16] = {0xa3, 0x81, 0x7f, 0x04, 0xba, 0x25, 0xa8, 0xe6,
                                       0x6d, 0xf6, 0x72, 0x14, 0xc7, 0x55, 0x02, 0x93};
  EXPECT_EQ(std::memcmp(got, reference, 16), 0);
  std::vector<std::size_t> lengths;
  for (std::size_t n = 0; n <= 300; ++n) lengths.push_back(n);
  for (std::size_t n : {1000, 4093, 60000}) lengths.push_back(n);
  for (std::size_t n : lengths) {
    key = bytes(16);
    const std::vector<unsigned char> m = bytes(n);
    crypto_shorthash_siphashx24(want, m.data(), m.size(), key.data());
    for (int trial = 0; trial < 4; ++trial) {
      SipHash128 h(key.data());
      std::size_t at = 0;
      while (at < n) {  // pieces of 0 to 19 bytes, then the rest
        const std::size_t piece = trial == 0 ? n : std::min<std::size_t>(rng() % 20, n - at);
        h.Update(m.data() + at, piece);
        at += piece;
      }
      h.Final(got);
      ASSERT_EQ(std::memcmp(got, want, 16), 0) << "length " << n << ", trial " << trial;
    }
  }
}

// A message of a log written before SipHash (trailer "SHOALMAC" and HMAC-SHA-512/256 under
// the run's key, 40 bytes) still verifies with that key, and only unchanged.
TEST(BusAuth, OlderHmacTrailerStillVerifies) {
  const Key k = NewKey();
  const std::string channel = "SHOAL_STATE_3", payload = "a state of an older log";
  std::vector<unsigned char> b(payload.begin(), payload.end());
  const std::string magic = "SHOALMAC";
  b.insert(b.end(), magic.begin(), magic.end());
  std::string covered = channel + std::string(1, '\0') + payload;
  unsigned char mac[crypto_auth_hmacsha512256_BYTES];
  crypto_auth_hmacsha512256(mac, reinterpret_cast<const unsigned char*>(covered.data()),
                            covered.size(), k.data());
  b.insert(b.end(), mac, mac + kHmacMacBytes);
  ASSERT_EQ(static_cast<int>(b.size()), static_cast<int>(payload.size()) + kHmacTrailerBytes);
  EXPECT_EQ(TrailerBytes(b.data(), static_cast<int>(b.size())), kHmacTrailerBytes);
  EXPECT_EQ(VerifyBytes(k, channel, b), static_cast<int>(payload.size()));
  EXPECT_EQ(VerifyBytes(k, "SHOAL_STATE_4", b), -1);
  EXPECT_EQ(VerifyBytes(NewKey(), channel, b), -1);
  for (std::size_t byte = 0; byte < b.size(); ++byte) {
    auto f = b;
    f[byte] ^= 0x10;
    ASSERT_EQ(VerifyBytes(k, channel, f), -1) << byte;
  }
  // What Sign writes now is the shorter trailer.
  const auto now = Signed(k, channel, payload);
  EXPECT_EQ(TrailerBytes(now.data(), static_cast<int>(now.size())), kTrailerBytes);
  EXPECT_EQ(std::string(now.end() - kTrailerBytes, now.end() - kMacBytes), "SHOALSIP");
}

TEST(BusAuth, KeysParseFromHexOnly) {
  const Key k = NewKey();
  Key got{};
  std::string err;
  ASSERT_TRUE(ParseKey(ToHex(k), &got, &err)) << err;
  EXPECT_EQ(got, k);
  ASSERT_TRUE(ParseKey("  " + ToHex(k) + "\n", &got, &err)) << err;
  EXPECT_EQ(got, k);
  EXPECT_FALSE(ParseKey("", &got, &err));
  EXPECT_NE(err.find("empty"), std::string::npos) << err;
  EXPECT_FALSE(ParseKey(ToHex(k).substr(2), &got, &err));           // too short
  EXPECT_FALSE(ParseKey(ToHex(k) + "00", &got, &err));              // too long
  EXPECT_FALSE(ParseKey("zz" + ToHex(k).substr(2), &got, &err));    // not hex
  EXPECT_FALSE(ParseKey(ToHex(k).substr(0, 30) + " " + ToHex(k).substr(31), &got, &err));
}

TEST(BusAuth, KeyFileIsPrivateAndReadBack) {
  const std::string path = ::testing::TempDir() + "/bus_auth_test.key";
  const Key k = NewKey();
  std::string err;
  { std::ofstream(path) << "stale"; }
  ASSERT_TRUE(WriteKeyFile(path, k, &err)) << err;  // replaces an existing file
  struct stat st {};
  ASSERT_EQ(stat(path.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  Key got{};
  ASSERT_TRUE(ReadKeyFile(path, &got, &err)) << err;
  EXPECT_EQ(got, k);
  { std::ofstream(path, std::ios::trunc); }  // empty
  EXPECT_FALSE(ReadKeyFile(path, &got, &err));
  EXPECT_NE(err.find(path), std::string::npos) << err;
  { std::ofstream(path, std::ios::trunc) << "not hex at all\n"; }
  EXPECT_FALSE(ReadKeyFile(path, &got, &err));
  unlink(path.c_str());
  EXPECT_FALSE(ReadKeyFile(path, &got, &err));  // missing
}

// A FIFO, a device or a directory named as the key (or found as <log>.key) is refused at
// once: never waited on (a FIFO without a writer), never read without end (/dev/zero).
TEST(BusAuth, KeyFileThatIsNotARegularFileIsRefusedWithoutWaiting) {
  const std::string fifo = ::testing::TempDir() + "/bus_auth_test.fifo";
  unlink(fifo.c_str());
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  Key got{};
  std::string err;
  for (const std::string& path : {fifo, std::string("/dev/zero"), ::testing::TempDir()}) {
    err.clear();
    EXPECT_FALSE(ReadKeyFile(path, &got, &err)) << path;
    EXPECT_NE(err.find("not a regular file"), std::string::npos) << path << ": " << err;
  }
  unlink(fifo.c_str());
  const std::string big = ::testing::TempDir() + "/bus_auth_test_big.key";
  { std::ofstream(big) << std::string(5000, 'a'); }
  EXPECT_FALSE(ReadKeyFile(big, &got, &err));
  EXPECT_NE(err.find("not a key file"), std::string::npos) << err;
  unlink(big.c_str());
}

TEST(BusAuth, ProcessNeedsAKeyOrInsecure) {
  Setting s;
  std::string err;
  unsetenv(kKeyEnv);
  EXPECT_FALSE(SettingFromEnvironment(false, &s, &err));
  EXPECT_NE(err.find(kKeyEnv), std::string::npos) << err;
  EXPECT_NE(err.find("--insecure"), std::string::npos) << err;
  ASSERT_TRUE(SettingFromEnvironment(true, &s, &err));
  EXPECT_TRUE(s.insecure);
  EXPECT_FALSE(s.key.has_value());
  setenv(kKeyEnv, "1234", 1);
  EXPECT_FALSE(SettingFromEnvironment(false, &s, &err));
  const Key k = NewKey();
  setenv(kKeyEnv, ToHex(k).c_str(), 1);
  ASSERT_TRUE(SettingFromEnvironment(false, &s, &err)) << err;
  EXPECT_EQ(s.key, k);
  unsetenv(kKeyEnv);
}

// The bus (real LCM over UDP multicast on loopback, private port, ttl=0): a handler gets
// only what verifies, without its trailer; the rest is dropped and counted.
TEST(BusAuth, AuthenticatedBusDropsAndCountsWhatDoesNotVerify) {
  std::string err;
  ASSERT_TRUE(EnsureLoopbackMulticast(&err)) << err;
  const std::string url = PrivateLcmUrl(31391);
  const Key k = NewKey();
  LcmBus bus(url, k), same_run(url, k), other_run(url, NewKey()), insecure(url);
  lcm::LCM forger(url);
  ASSERT_TRUE(forger.good());
  std::vector<std::string> seen;
  bus.Subscribe("CH.*", [&](const std::string& ch, const void* d, int n) {
    seen.push_back(ch + ":" + std::string(static_cast<const char*>(d), static_cast<std::size_t>(n)));
  });
  ASSERT_TRUE(same_run.PublishRaw("CH1", "hello", 5));
  ASSERT_TRUE(other_run.PublishRaw("CH1", "other run", 9));
  ASSERT_TRUE(insecure.PublishRaw("CH1", "no trailer", 10));
  const auto moved = Signed(k, "CH1", "moved");  // signed for CH1, sent on CH2
  forger.publish("CH2", moved.data(), static_cast<unsigned>(moved.size()));
  auto flipped = Signed(k, "CH1", "flipped");
  flipped[2] ^= 1;
  forger.publish("CH1", flipped.data(), static_cast<unsigned>(flipped.size()));
  const auto cut = Signed(k, "CH1", "cut");
  forger.publish("CH1", cut.data(), static_cast<unsigned>(cut.size() - 1));
  ASSERT_TRUE(same_run.PublishRaw("CH3", "bye", 3));
  for (int k2 = 0; k2 < 40 && seen.size() + bus.rejected() < 7; ++k2) bus.Handle(50);
  ASSERT_EQ(seen.size(), 2u);
  EXPECT_EQ(seen[0], "CH1:hello");
  EXPECT_EQ(seen[1], "CH3:bye");
  EXPECT_EQ(bus.rejected(), 5);
}

// A datagram that two subscriptions match (the channel emulator's uplink has a pattern for
// every SHOAL_ channel and one for the states) is verified once: a forgery counts once.
TEST(BusAuth, AForgeryMatchedByTwoSubscriptionsCountsOnce) {
  std::string err;
  ASSERT_TRUE(EnsureLoopbackMulticast(&err)) << err;
  const std::string url = PrivateLcmUrl(31393);
  const Key k = NewKey();
  LcmBus bus(url, k), same_run(url, k), other_run(url, NewKey());
  int all = 0, states = 0;
  bus.Subscribe("CH.*", [&](const std::string&, const void*, int) { ++all; });
  bus.Subscribe("CH1", [&](const std::string&, const void*, int) { ++states; });
  ASSERT_TRUE(other_run.PublishRaw("CH1", "forged", 6));
  ASSERT_TRUE(other_run.PublishRaw("CH1", "forged", 6));
  ASSERT_TRUE(same_run.PublishRaw("CH1", "hello", 5));
  for (int k2 = 0; k2 < 40 && states + bus.rejected() < 3; ++k2) bus.Handle(50);
  EXPECT_EQ(all, 1);
  EXPECT_EQ(states, 1);
  EXPECT_EQ(bus.rejected(), 2);
}

}  // namespace
}  // namespace shoal::bus_auth
