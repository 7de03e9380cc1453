// Deterministic random numbers, identical on every platform and library version
// (std:: distributions are implementation-defined, so they are not used).
#pragma once

#include <cmath>
#include <cstdint>

namespace shoal {

/// SplitMix64 step (Steele, Lea, Flood 2014); used for seeding and stream derivation.
inline std::uint64_t SplitMix64(std::uint64_t* state) {
  std::uint64_t z = (*state += 0x9E3779B97F4A7C15ULL);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

/// xoshiro256** (Blackman & Vigna 2018) with independent streams derived from
/// (seed, stream ids), so that every link or vehicle draws its own sequence whatever
/// order the others are processed in.
class Rng {
 public:
  explicit Rng(std::uint64_t seed = 1, std::uint64_t stream_a = 0, std::uint64_t stream_b = 0) {
    std::uint64_t sm = seed ^ (stream_a * 0xD1B54A32D192ED03ULL) ^
                       (stream_b * 0x8CB92BA72F3D8DD7ULL) ^ 0x5DEECE66DULL;
    for (auto& w : s_) w = SplitMix64(&sm);
  }

  std::uint64_t Next() {
    const std::uint64_t result = Rotl(s_[1] * 5, 7) * 9;
    const std::uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = Rotl(s_[3], 45);
    return result;
  }

  /// Uniform in [0, 1) with 53 random bits.
  double Uniform() { return static_cast<double>(Next() >> 11) * 0x1.0p-53; }

  /// Standard normal (Box-Muller, one value per call).
  double Normal() {
    const double u1 = 1.0 - Uniform();  // (0, 1]
    const double u2 = Uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
  }

 private:
  static std::uint64_t Rotl(std::uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  std::uint64_t s_[4];
};

}  // namespace shoal
