#include "runtime/recorder_gate.h"

#include <dirent.h>
#include <fcntl.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "runtime/clock.h"

namespace shoal {

RecorderGate::RecorderGate(pid_t pid) : pid_(pid) {
  if (pid_ > 0 && !Scan()) pid_ = 0;
}

RecorderGate::~RecorderGate() {
  for (int fd : fds_) close(fd);
}

bool RecorderGate::Scan() {
  for (int fd : fds_) close(fd);
  fds_.clear();
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
  char buf[512];
  for (int fd : fds_) {
    const ssize_t n = pread(fd, buf, sizeof(buf) - 1, 0);
    if (n <= 0) return -1;  // the thread (or the whole recorder) is gone
    buf[n] = '\0';
    // "tid (comm) S ...": the state follows the last ')' (comm may contain anything).
    const char* close_paren = std::strrchr(buf, ')');
    if (close_paren == nullptr || close_paren[1] != ' ') return -1;
    const char state = close_paren[2];
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

}  // namespace shoal
