#include "runtime/checkpoint.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>

#include "runtime/lcm_bus.h"

namespace shoal {
namespace {

constexpr std::uint32_t kMagic = 0x4b434853;  // "SHCK"
constexpr std::uint32_t kVersion = 1;
// magic, version, process id, payload size (4 each), generation, tick (8 each), payload,
// checksum (8).
constexpr std::size_t kHeaderBytes = 4 * 4 + 2 * 8;
constexpr std::size_t kSlotBytes = kHeaderBytes + CheckpointPayload::kMaxBytes + 8;

template <typename T>
void PutAt(std::vector<unsigned char>* b, std::size_t at, T v) {
  std::memcpy(b->data() + at, &v, sizeof(T));
}
template <typename T>
T GetAt(const unsigned char* b, std::size_t at) {
  T v;
  std::memcpy(&v, b + at, sizeof(T));
  return v;
}

std::int64_t Checksum(const unsigned char* slot) {
  return Digest64(slot, static_cast<int>(kSlotBytes - 8));
}

/// The record in one slot, if valid and of `process_id`.
bool ParseSlot(const unsigned char* s, std::int32_t process_id, CheckpointRecord* r) {
  const auto size = GetAt<std::uint32_t>(s, 12);
  if (GetAt<std::uint32_t>(s, 0) != kMagic || GetAt<std::uint32_t>(s, 4) != kVersion ||
      GetAt<std::int32_t>(s, 8) != process_id || size > CheckpointPayload::kMaxBytes ||
      GetAt<std::int64_t>(s, kSlotBytes - 8) != Checksum(s)) {
    return false;
  }
  r->process_id = process_id;
  r->generation = GetAt<std::uint64_t>(s, 16);
  r->tick = GetAt<std::int64_t>(s, 24);
  r->payload.Clear();
  r->payload.bytes().assign(s + kHeaderBytes, s + kHeaderBytes + size);
  return true;
}

}  // namespace

CheckpointFile::~CheckpointFile() {
  if (fd_ >= 0) close(fd_);
}

bool CheckpointFile::Open(const std::string& path, std::uint64_t next_generation,
                          std::string* error) {
  fd_ = open(path.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0) {
    *error = path + ": cannot open the checkpoint file (" + std::strerror(errno) + ")";
    return false;
  }
  generation_ = next_generation;
  buf_.assign(kSlotBytes, 0);
  return true;
}

bool CheckpointFile::Write(std::int32_t process_id, std::int64_t tick,
                           const CheckpointPayload& payload) {
  const std::vector<unsigned char>& p = payload.bytes();
  if (fd_ < 0 || p.size() > CheckpointPayload::kMaxBytes) return false;
  std::fill(buf_.begin(), buf_.end(), 0);
  PutAt(&buf_, 0, kMagic);
  PutAt(&buf_, 4, kVersion);
  PutAt(&buf_, 8, process_id);
  PutAt(&buf_, 12, static_cast<std::uint32_t>(p.size()));
  PutAt(&buf_, 16, generation_);
  PutAt(&buf_, 24, tick);
  std::copy(p.begin(), p.end(), buf_.begin() + kHeaderBytes);
  PutAt(&buf_, kSlotBytes - 8, Checksum(buf_.data()));
  const auto offset = static_cast<off_t>((generation_ % 2) * kSlotBytes);
  ++generation_;
  return pwrite(fd_, buf_.data(), kSlotBytes, offset) == static_cast<ssize_t>(kSlotBytes);
}

bool ReadCheckpoint(const std::string& path, std::int32_t process_id, CheckpointRecord* out,
                    std::string* error) {
  const int fd = open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    *error = path + ": no checkpoint (" + std::strerror(errno) + ")";
    return false;
  }
  std::vector<unsigned char> b(2 * kSlotBytes, 0);
  const ssize_t n = pread(fd, b.data(), b.size(), 0);
  close(fd);
  bool found = false;
  for (std::size_t k = 0; k < 2; ++k) {
    CheckpointRecord r;
    if (n < static_cast<ssize_t>((k + 1) * kSlotBytes) ||
        !ParseSlot(b.data() + k * kSlotBytes, process_id, &r)) {
      continue;
    }
    if (!found || r.generation > out->generation) *out = r;
    found = true;
  }
  if (!found) *error = path + ": no valid checkpoint of process " + std::to_string(process_id);
  return found;
}

}  // namespace shoal
