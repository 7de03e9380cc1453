// Large vectors of the analysis: reserved once and backed by transparent huge pages where
// the kernel offers them (THP "madvise" mode), so that filling hundreds of megabytes costs
// a few hundred page faults instead of a hundred thousand. Memory that is reserved but
// never written is never resident, so a generous reservation does not raise the RSS.
#pragma once

#include <sys/mman.h>

#include <cstdint>
#include <vector>

namespace shoal {

template <typename T>
void ReserveHuge(std::vector<T>* v, std::size_t n) {
  if (n <= v->capacity()) return;
  v->reserve(n);
  constexpr std::uintptr_t kHuge = 2u << 20;
  const std::size_t bytes = v->capacity() * sizeof(T);
  if (bytes < 2 * kHuge) return;
  const auto begin = reinterpret_cast<std::uintptr_t>(v->data());
  const std::uintptr_t lo = (begin + kHuge - 1) & ~(kHuge - 1);
  const std::uintptr_t hi = (begin + bytes) & ~(kHuge - 1);
  if (hi > lo) madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_HUGEPAGE);  // advisory only
}

}  // namespace shoal
