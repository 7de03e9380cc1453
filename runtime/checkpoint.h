// A clocked process's checkpoint file (shoal run --restart on-failure): after every state
// it publishes, the process writes what it needs to go on from there, so that a process
// restarted in its place resumes at that state (docs/reliability.md).
//
// The file holds two slots of a fixed size; write k goes to slot k % 2 with one pwrite
// and no fsync (the file outlives the process, not the machine). Each slot carries a
// generation counter and a checksum over the rest, so a write torn by the process's death
// leaves the other slot, one tick older, as the newest valid one.
#pragma once

#include <cstdint>
#include <cstring>
#include <string>
#include <type_traits>
#include <vector>

namespace shoal {

/// The app's part of a checkpoint: scalars packed in order, read back in the same order.
class CheckpointPayload {
 public:
  static constexpr std::size_t kMaxBytes = 1024;

  template <typename T>
  void Put(const T& v) {
    static_assert(std::is_arithmetic<T>::value, "scalars only");
    const std::size_t at = bytes_.size();
    bytes_.resize(at + sizeof(T));
    std::memcpy(bytes_.data() + at, &v, sizeof(T));
  }
  /// False (and *v untouched) past the end.
  template <typename T>
  bool Get(T* v) {
    static_assert(std::is_arithmetic<T>::value, "scalars only");
    if (read_ + sizeof(T) > bytes_.size()) return false;
    std::memcpy(v, bytes_.data() + read_, sizeof(T));
    read_ += sizeof(T);
    return true;
  }
  void Clear() {
    bytes_.clear();
    read_ = 0;
  }
  std::vector<unsigned char>& bytes() { return bytes_; }
  const std::vector<unsigned char>& bytes() const { return bytes_; }

 private:
  std::vector<unsigned char> bytes_;
  std::size_t read_ = 0;
};

struct CheckpointRecord {
  std::int32_t process_id = 0;  // vehicle id (0 leader)
  std::int64_t tick = -1;       // the last tick stepped and published
  std::uint64_t generation = 0;
  CheckpointPayload payload;
};

class CheckpointFile {
 public:
  CheckpointFile() = default;
  ~CheckpointFile();
  CheckpointFile(const CheckpointFile&) = delete;
  CheckpointFile& operator=(const CheckpointFile&) = delete;

  /// Opens (creating, never truncating) `path` for writing; the next write's generation
  /// is `next_generation`. False with *error if it cannot.
  bool Open(const std::string& path, std::uint64_t next_generation, std::string* error);
  /// Writes the record of `tick`; false if the write failed (the run goes on: a process
  /// that cannot checkpoint can still run, it only cannot be resumed).
  bool Write(std::int32_t process_id, std::int64_t tick, const CheckpointPayload& payload);
  bool is_open() const { return fd_ >= 0; }

 private:
  int fd_ = -1;
  std::uint64_t generation_ = 0;
  std::vector<unsigned char> buf_;  // one slot, reused
};

/// The newest valid record of `path` written by process `process_id`. False with *error
/// if the file is missing, or neither slot is a valid record of that process.
bool ReadCheckpoint(const std::string& path, std::int32_t process_id, CheckpointRecord* out,
                    std::string* error);

}  // namespace shoal
