// SipHash-2-4 with a 128-bit output (Aumasson and Bernstein, "SipHash: a fast short-input
// PRF", 2012; the 128-bit variant of their reference code, which libsodium exposes as
// crypto_shorthash_siphashx24), computed incrementally: the bus authenticates a channel
// name and a message that lie in different buffers without copying them together.
#pragma once

#include <cstddef>
#include <cstdint>

namespace shoal {

class SipHash128 {
 public:
  static constexpr int kKeyBytes = 16;
  static constexpr int kOutBytes = 16;
  /// Keyed with key[0, 16), as libsodium's crypto_shorthash_siphashx24 is.
  explicit SipHash128(const unsigned char* key);
  void Update(const unsigned char* data, std::size_t size);
  /// Writes the 16-byte tag of everything updated so far to out; the object is spent.
  void Final(unsigned char* out);

 private:
  void Compress(std::uint64_t m);
  std::uint64_t v0_, v1_, v2_, v3_;
  std::uint64_t tail_ = 0;   // the bytes of the block being filled, little-endian
  int tail_bytes_ = 0;       // how many (0..7)
  std::uint64_t total_ = 0;  // bytes updated in all
};

}  // namespace shoal
