#include "runtime/siphash.h"

#include <cstring>

namespace shoal {
namespace {

std::uint64_t Rotl(std::uint64_t x, int b) { return (x << b) | (x >> (64 - b)); }

std::uint64_t Load64(const unsigned char* p) {  // little-endian on any host
  std::uint64_t v;
  std::memcpy(&v, p, sizeof(v));
#if __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
  v = __builtin_bswap64(v);
#endif
  return v;
}

void Store64(std::uint64_t v, unsigned char* p) {
  for (int k = 0; k < 8; ++k) p[k] = static_cast<unsigned char>(v >> (8 * k));
}

void Round(std::uint64_t& v0, std::uint64_t& v1, std::uint64_t& v2, std::uint64_t& v3) {
  v0 += v1;
  v1 = Rotl(v1, 13);
  v1 ^= v0;
  v0 = Rotl(v0, 32);
  v2 += v3;
  v3 = Rotl(v3, 16);
  v3 ^= v2;
  v0 += v3;
  v3 = Rotl(v3, 21);
  v3 ^= v0;
  v2 += v1;
  v1 = Rotl(v1, 17);
  v1 ^= v2;
  v2 = Rotl(v2, 32);
}

}  // namespace

SipHash128::SipHash128(const unsigned char* key) {
  const std::uint64_t k0 = Load64(key), k1 = Load64(key + 8);
  v0_ = 0x736f6d6570736575ULL ^ k0;
  v1_ = 0x646f72616e646f6dULL ^ k1 ^ 0xee;  // 0xee: the 128-bit output variant
  v2_ = 0x6c7967656e657261ULL ^ k0;
  v3_ = 0x7465646279746573ULL ^ k1;
}

void SipHash128::Compress(std::uint64_t m) {
  v3_ ^= m;
  Round(v0_, v1_, v2_, v3_);  // c = 2 compression rounds
  Round(v0_, v1_, v2_, v3_);
  v0_ ^= m;
}

void SipHash128::Update(const unsigned char* data, std::size_t size) {
  total_ += size;
  std::size_t k = 0;
  while (tail_bytes_ > 0 && k < size) {  // complete the block begun by the last update
    tail_ |= static_cast<std::uint64_t>(data[k++]) << (8 * tail_bytes_);
    if (++tail_bytes_ == 8) {
      Compress(tail_);
      tail_ = 0;
      tail_bytes_ = 0;
    }
  }
  for (; k + 8 <= size; k += 8) Compress(Load64(data + k));
  for (; k < size; ++k) tail_ |= static_cast<std::uint64_t>(data[k]) << (8 * tail_bytes_++);
}

void SipHash128::Final(unsigned char* out) {
  Compress(tail_ | (total_ << 56));  // the last block holds the length modulo 256
  v2_ ^= 0xee;
  for (int r = 0; r < 4; ++r) Round(v0_, v1_, v2_, v3_);  // d = 4 finalisation rounds
  Store64(v0_ ^ v1_ ^ v2_ ^ v3_, out);
  v1_ ^= 0xdd;
  for (int r = 0; r < 4; ++r) Round(v0_, v1_, v2_, v3_);
  Store64(v0_ ^ v1_ ^ v2_ ^ v3_, out + 8);
}

}  // namespace shoal
