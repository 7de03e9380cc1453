// LCM's wire format, read by hand where the generated decoders are not enough: the array
// counts a message declares are checked against its size before the generated decoder
// trusts them (runtime/lcm_bus.h Decode), and analysis reads its hot message types
// (channel events) without the generated decoder's string allocations.
// LCM encodes every integer and double big-endian.
#pragma once

#include <cstdint>
#include <cstring>

namespace shoal {
namespace wire {

inline std::uint64_t U64(const unsigned char* p) {
  std::uint64_t v;
  std::memcpy(&v, p, 8);
  return __builtin_bswap64(v);
}
inline std::uint32_t U32(const unsigned char* p) {
  std::uint32_t v;
  std::memcpy(&v, p, 4);
  return __builtin_bswap32(v);
}
inline std::int64_t I64(const unsigned char* p) { return static_cast<std::int64_t>(U64(p)); }
inline std::int32_t I32(const unsigned char* p) { return static_cast<std::int32_t>(U32(p)); }
inline double F64(const unsigned char* p) {
  const std::uint64_t u = U64(p);
  double d;
  std::memcpy(&d, &u, 8);
  return d;
}

}  // namespace wire
}  // namespace shoal
