// vehicle_state_t on the wire, by hand. Every process writes its state each tick and
// reads its neighbours'; LCM's generated code moves the message's 25 doubles a byte at a
// time, about 30 instructions each: about 2,300 of a vehicle's 15,500 instructions a tick,
// and 9 % of the channel emulator's at 64 followers (callgrind, docs/benchmarks.md). These
// write exactly the bytes the generated encoder writes and take exactly the messages the
// generated decoder takes whole (tests/unit/state_wire_test.cc holds both to it).
#pragma once

#include <shoal/vehicle_state_t.hpp>

#include <cstdint>
#include <cstring>
#include <initializer_list>

#include "lcmtypes/wire.h"

namespace shoal {
namespace state_wire {

/// Fingerprint, utime, vehicle_id, seq, five arrays of five doubles, flags.
constexpr int kBytes = 8 + 8 + 4 + 4 + 5 * 5 * 8 + 4;
constexpr int kDoubles = 5;

inline void Put64(std::uint64_t v, unsigned char* p) {
  v = __builtin_bswap64(v);
  std::memcpy(p, &v, 8);
}
inline void Put32(std::uint32_t v, unsigned char* p) {
  v = __builtin_bswap32(v);
  std::memcpy(p, &v, 4);
}
inline void PutDoubles(const double (&a)[kDoubles], unsigned char* p) {
  for (int k = 0; k < kDoubles; ++k) {
    std::uint64_t u;
    std::memcpy(&u, &a[k], 8);
    Put64(u, p + 8 * k);
  }
}
inline void GetDoubles(const unsigned char* p, double (&a)[kDoubles]) {
  for (int k = 0; k < kDoubles; ++k) a[k] = wire::F64(p + 8 * k);
}

/// Writes the kBytes of `m` to out[0, kBytes).
inline void Encode(const vehicle_state_t& m, unsigned char* out) {
  Put64(static_cast<std::uint64_t>(vehicle_state_t::getHash()), out);
  Put64(static_cast<std::uint64_t>(m.utime), out + 8);
  Put32(static_cast<std::uint32_t>(m.vehicle_id), out + 16);
  Put32(static_cast<std::uint32_t>(m.seq), out + 20);
  unsigned char* p = out + 24;
  for (const auto* a : {&m.eta, &m.nu, &m.eta_dot, &m.accel_cmd, &m.tau}) {
    PutDoubles(*a, p);
    p += 8 * kDoubles;
  }
  Put32(static_cast<std::uint32_t>(m.flags), p);
}

/// False unless `p` is exactly one vehicle_state_t (its size and fingerprint).
inline bool Decode(const unsigned char* p, int size, vehicle_state_t* m) {
  if (p == nullptr || size != kBytes || wire::I64(p) != vehicle_state_t::getHash()) return false;
  m->utime = wire::I64(p + 8);
  m->vehicle_id = wire::I32(p + 16);
  m->seq = wire::I32(p + 20);
  const unsigned char* q = p + 24;
  for (auto* a : {&m->eta, &m->nu, &m->eta_dot, &m->accel_cmd, &m->tau}) {
    GetDoubles(q, *a);
    q += 8 * kDoubles;
  }
  m->flags = wire::I32(q);
  return true;
}

}  // namespace state_wire
}  // namespace shoal
