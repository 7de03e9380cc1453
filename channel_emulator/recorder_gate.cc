#include "channel_emulator/recorder_gate.h"

#include <dirent.h>
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "runtime/clock.h"
#include "runtime/lcm_queue_shim.h"

namespace shoal {

RecorderGate::RecorderGate(pid_t pid) : pid_(pid) {
  if (pid_ > 0 && !Scan()) pid_ = 0;
}

RecorderGate::~RecorderGate() {
  for (int fd : fds_) close(fd);
  if (process_fd_ >= 0) close(process_fd_);
}

namespace {
// The state letter of a /proc stat line ("pid (comm) S ..."; comm may hold anything) and,
// when `threads` is given, field 20 (num_threads). False if the line does not parse.
bool ParseStat(int fd, char* state, long* threads) {
  char buf[1024];
  const ssize_t n = pread(fd, buf, sizeof(buf) - 1, 0);
  if (n <= 0) return false;
  buf[n] = '\0';
  const char* p = std::strrchr(buf, ')');
  if (p == nullptr || p[1] != ' ' || p[2] == '\0') return false;
  *state = p[2];
  if (threads == nullptr) return true;
  // Fields 3 (state) .. 20 (num_threads): skip 17 separators after the state.
  p += 2;
  for (int k = 0; k < 17; ++k) {
    p = std::strchr(p, ' ');
    if (p == nullptr) return false;
    ++p;
  }
  char* end = nullptr;
  *threads = std::strtol(p, &end, 10);
  return end != p;
}
}  // namespace

bool RecorderGate::Scan() {
  for (int fd : fds_) close(fd);
  fds_.clear();
  if (process_fd_ < 0) {
    process_fd_ = open(("/proc/" + std::to_string(pid_) + "/stat").c_str(), O_RDONLY | O_CLOEXEC);
    if (process_fd_ < 0) return false;
  }
  const std::string dir = "/proc/" + std::to_string(pid_) + "/task";
  DIR* d = opendir(dir.c_str());
  if (d == nullptr) return false;
  while (const dirent* e = readdir(d)) {
    if (e->d_name[0] < '0' || e->d_name[0] > '9') continue;
    const int fd = open((dir + "/" + e->d_name + "/stat").c_str(), O_RDONLY | O_CLOEXEC);
    if (fd >= 0) fds_.push_back(fd);
  }
  closedir(d);
  return !fds_.empty();
}

int RecorderGate::Idle() {
  char state = 0;
  long threads = 0;
  if (!ParseStat(process_fd_, &state, &threads) || state == 'Z' || state == 'X') return -1;
  if (threads != static_cast<long>(fds_.size()) && !Scan()) return -1;
  for (int fd : fds_) {
    if (!ParseStat(fd, &state, nullptr)) return -1;  // a thread ended: list them again
    if (state != 'S') return 0;
  }
  return 1;
}

void RecorderGate::Wait(std::int64_t max_wait_ns) {
  if (pid_ <= 0) return;
  int idle = Idle();
  if (idle < 0) {
    // A thread ended (or started): list them again; if the recorder is gone, stop.
    if (!Scan() || (idle = Idle()) < 0) {
      pid_ = 0;
      return;
    }
  }
  if (idle == 1) return;
  ++waits_;
  const std::int64_t t0 = MonotonicNs();
  for (;;) {
    const timespec nap = {0, 20000};
    nanosleep(&nap, nullptr);
    idle = Idle();
    const std::int64_t waited = MonotonicNs() - t0;
    if (idle != 0 || waited > max_wait_ns) {
      waited_ns_ += waited;
      if (idle == 0) ++timeouts_;
      return;
    }
  }
}

namespace {
const ShoalLoggerProgress* Progress(const void* map) {
  return static_cast<const ShoalLoggerProgress*>(map);
}
}  // namespace

RecorderProgress::~RecorderProgress() {
  if (map_ != nullptr) munmap(const_cast<void*>(map_), sizeof(ShoalLoggerProgress));
}

bool RecorderProgress::Attach() {
  if (map_ != nullptr) return true;
  if (pid_ <= 0) return false;
  char name[64];
  std::snprintf(name, sizeof(name), SHOAL_LOGGER_PROGRESS_NAME, static_cast<long>(pid_));
  const int fd = shm_open(name, O_RDONLY, 0);
  if (fd < 0) return false;
  struct stat st {};
  void* m = MAP_FAILED;
  if (fstat(fd, &st) == 0 && st.st_size >= static_cast<off_t>(sizeof(ShoalLoggerProgress))) {
    m = mmap(nullptr, sizeof(ShoalLoggerProgress), PROT_READ, MAP_SHARED, fd, 0);
  }
  close(fd);
  if (m == MAP_FAILED) return false;
  if (__atomic_load_n(&Progress(m)->magic, __ATOMIC_ACQUIRE) != SHOAL_LOGGER_PROGRESS_MAGIC) {
    munmap(m, sizeof(ShoalLoggerProgress));  // made, not yet started: look again later
    return false;
  }
  map_ = m;
  shm_unlink(name);
  return true;
}

std::uint64_t RecorderProgress::handled() const {
  return map_ == nullptr ? 0 : __atomic_load_n(&Progress(map_)->handled, __ATOMIC_ACQUIRE);
}

std::uint64_t RecorderProgress::queued() const {
  return map_ == nullptr ? 0 : __atomic_load_n(&Progress(map_)->queued, __ATOMIC_ACQUIRE);
}

std::uint64_t RecorderProgress::written() const {
  return map_ == nullptr ? 0 : __atomic_load_n(&Progress(map_)->written, __ATOMIC_ACQUIRE);
}

bool RecorderProgress::WaitForWritten(std::int64_t max_wait_ns) {
  if (map_ == nullptr) return false;
  const std::int64_t t0 = MonotonicNs();
  for (;;) {
    const std::uint64_t q = queued();  // before `written`: it only grows
    if (written() >= q) return true;
    if (MonotonicNs() - t0 > max_wait_ns) return false;
    const timespec nap = {0, 50000};
    nanosleep(&nap, nullptr);
  }
}

bool RecorderProgress::WaitForWrittenUpTo(std::uint64_t target, std::int64_t max_wait_ns) {
  if (map_ == nullptr) return false;
  if (written() >= target) return true;
  ++waits_;
  const std::int64_t t0 = MonotonicNs();
  for (;;) {
    const timespec nap = {0, 20000};
    nanosleep(&nap, nullptr);
    const bool done = written() >= target;
    const std::int64_t waited = MonotonicNs() - t0;
    if (done || waited > max_wait_ns) {
      waited_ns_ += waited;
      if (!done) ++timeouts_;
      return true;
    }
  }
}

bool RecorderProgress::WaitFor(std::uint64_t target, std::int64_t max_wait_ns) {
  if (map_ == nullptr) return false;
  target = target > lost_ ? target - lost_ : 0;
  const std::uint64_t before = handled();
  if (before >= target) return true;
  ++waits_;
  const std::int64_t t0 = MonotonicNs();
  for (;;) {
    const timespec nap = {0, 20000};
    nanosleep(&nap, nullptr);
    const std::uint64_t now = handled();
    const std::int64_t waited = MonotonicNs() - t0;
    if (now >= target || waited > max_wait_ns) {
      waited_ns_ += waited;
      if (now >= target) return true;
      ++timeouts_;
      const std::uint64_t pending = queued();  // before `written`: it only grows
      if (now == before && written() >= pending) lost_ += target - now;
      return true;
    }
  }
}

std::uint64_t RecorderProgress::lost(std::uint64_t sent) {
  const std::uint64_t h = handled();
  lost_ = std::min(lost_, sent > h ? sent - h : 0);
  return lost_;
}

}  // namespace shoal
