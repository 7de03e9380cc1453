// vehicle_state_t by hand (runtime/state_wire.h) against LCM's generated code: the same
// bytes out, and the same messages taken or refused, with the same fields, bit for bit.
#include "runtime/state_wire.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "runtime/lcm_bus.h"

namespace shoal {
namespace {

vehicle_state_t RandomState(std::mt19937_64& rng) {
  vehicle_state_t m{};
  std::uniform_real_distribution<double> u(-1e4, 1e4);
  m.utime = static_cast<std::int64_t>(rng());
  m.vehicle_id = static_cast<std::int32_t>(rng());
  m.seq = static_cast<std::int32_t>(rng());
  for (auto* a : {&m.eta, &m.nu, &m.eta_dot, &m.accel_cmd, &m.tau}) {
    for (double& x : *a) x = u(rng);
  }
  m.flags = static_cast<std::int32_t>(rng());
  return m;
}

std::vector<unsigned char> Generated(const vehicle_state_t& m) {
  std::vector<unsigned char> out(static_cast<std::size_t>(m.getEncodedSize()));
  EXPECT_EQ(m.encode(out.data(), 0, static_cast<int>(out.size())), static_cast<int>(out.size()));
  return out;
}

std::vector<unsigned char> ByHand(const vehicle_state_t& m) {
  std::vector<unsigned char> out(state_wire::kBytes);
  state_wire::Encode(m, out.data());
  return out;
}

// What Decode takes with the generated decoder: the whole message and nothing more.
bool GeneratedDecode(const std::vector<unsigned char>& b, vehicle_state_t* m) {
  return b.size() >= 8 && m->decode(b.data(), 0, static_cast<int>(b.size())) ==
                              static_cast<int>(b.size());
}

void ExpectSameBits(const vehicle_state_t& a, const vehicle_state_t& b) {
  EXPECT_EQ(a.utime, b.utime);
  EXPECT_EQ(a.vehicle_id, b.vehicle_id);
  EXPECT_EQ(a.seq, b.seq);
  EXPECT_EQ(a.flags, b.flags);
  EXPECT_EQ(std::memcmp(a.eta, b.eta, sizeof(a.eta)), 0);
  EXPECT_EQ(std::memcmp(a.nu, b.nu, sizeof(a.nu)), 0);
  EXPECT_EQ(std::memcmp(a.eta_dot, b.eta_dot, sizeof(a.eta_dot)), 0);
  EXPECT_EQ(std::memcmp(a.accel_cmd, b.accel_cmd, sizeof(a.accel_cmd)), 0);
  EXPECT_EQ(std::memcmp(a.tau, b.tau, sizeof(a.tau)), 0);
}

TEST(StateWire, WritesWhatTheGeneratedEncoderWrites) {
  std::mt19937_64 rng(7);
  EXPECT_EQ(vehicle_state_t{}.getEncodedSize(), state_wire::kBytes);
  for (int k = 0; k < 1000; ++k) {
    vehicle_state_t m = RandomState(rng);
    if (k == 0) {  // what the generated code must carry unchanged too
      m.eta[0] = std::numeric_limits<double>::quiet_NaN();
      m.nu[1] = -std::numeric_limits<double>::infinity();
      m.tau[4] = -0.0;
      m.accel_cmd[2] = std::numeric_limits<double>::denorm_min();
    }
    ASSERT_EQ(ByHand(m), Generated(m)) << k;
  }
}

TEST(StateWire, TakesAndRefusesWhatTheGeneratedDecoderDid) {
  std::mt19937_64 rng(11);
  int taken = 0;
  for (int k = 0; k < 4000; ++k) {
    std::vector<unsigned char> b = Generated(RandomState(rng));
    switch (k % 5) {
      case 0: break;                                          // as sent
      case 1: b[rng() % b.size()] ^= 1u << (rng() % 8); break;  // a bit flipped anywhere
      case 2: b.resize(rng() % b.size()); break;              // cut short
      case 3: b.push_back(static_cast<unsigned char>(rng())); break;  // a byte more
      case 4: for (auto& c : b) c = static_cast<unsigned char>(rng()); break;  // garbage
    }
    vehicle_state_t hand{}, generated{};
    const bool by_hand = Decode(b.data(), static_cast<int>(b.size()), &hand);
    ASSERT_EQ(by_hand, GeneratedDecode(b, &generated)) << k;
    if (by_hand) {
      ++taken;
      ExpectSameBits(hand, generated);
    }
  }
  // As sent, and most single flipped bits (all but those in the fingerprint).
  EXPECT_GT(taken, 1400);
  vehicle_state_t m{};
  EXPECT_FALSE(state_wire::Decode(nullptr, state_wire::kBytes, &m));
}

TEST(StateWire, ABusPublishesWhatTheGeneratedEncoderWrites) {
  // In process, without a key: the bytes as they are.
  LcmBus bus("memq://");
  std::vector<unsigned char> got;
  bus.Subscribe("SHOAL_STATE_3", [&](const std::string&, const void* d, int n) {
    got.assign(static_cast<const unsigned char*>(d), static_cast<const unsigned char*>(d) + n);
  });
  std::mt19937_64 rng(3);
  const vehicle_state_t m = RandomState(rng);
  ASSERT_TRUE(bus.Publish("SHOAL_STATE_3", m));
  bus.Handle(100);
  EXPECT_EQ(got, Generated(m));
}

}  // namespace
}  // namespace shoal
