// Follows an LCM event log while another process (lcm-logger) appends to it: each Poll()
// hands over the complete events written since the last one. `shoal run` takes its
// progress from the log this way instead of listening on the bus, so that watching a run
// adds no receiver to its multicast group (every receiver costs every message a copy and
// two thread wake-ups).
#pragma once

#include <cstdint>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

namespace shoal {

class LogTail {
 public:
  using Handler = std::function<void(const std::string& channel, const void* data, int size)>;

  explicit LogTail(std::string path) : path_(std::move(path)) {}
  ~LogTail();
  LogTail(const LogTail&) = delete;
  LogTail& operator=(const LogTail&) = delete;

  /// Reads what was appended and calls `on` for every complete event. An incomplete event
  /// at the end is kept for the next call. Returns the number of events handled; -1 once
  /// the file is found damaged (bad sync word or impossible lengths), after which it
  /// stops reading.
  int Poll(const Handler& on);

  std::int64_t events() const { return events_; }
  bool damaged() const { return damaged_; }

 private:
  std::string path_;
  std::FILE* f_ = nullptr;
  std::vector<unsigned char> buf_;  // bytes read but not yet consumed
  std::int64_t events_ = 0;
  bool damaged_ = false;
};

}  // namespace shoal
