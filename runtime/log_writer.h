// Writes LCM messages into a standard LCM event log (readable by lcm-logplayer),
// timestamped with the message's own utime so that the same run gives the same bytes.
#pragma once

#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <lcm/eventlog.h>

namespace shoal {

class LogWriter {
 public:
  /// Opens `path` for writing; throws std::runtime_error with the reason on failure.
  explicit LogWriter(const std::string& path);
  ~LogWriter();
  LogWriter(const LogWriter&) = delete;
  LogWriter& operator=(const LogWriter&) = delete;

  /// Encodes and appends one message.
  template <typename Msg>
  void Write(const std::string& channel, std::int64_t utime, const Msg& msg) {
    const int size = msg.getEncodedSize();
    if (static_cast<int>(buf_.size()) < size) buf_.resize(size);
    msg.encode(buf_.data(), 0, size);
    WriteRaw(channel, utime, buf_.data(), size);
  }

  /// Appends one event; throws std::runtime_error if the file cannot take it (a full disk
  /// shows here or at Flush/Close, when the buffer is written).
  void WriteRaw(const std::string& channel, std::int64_t utime, const void* data, int size);
  /// Writes the buffered events to the file; throws std::runtime_error on failure.
  void Flush();
  /// Flushes and closes; throws std::runtime_error if the flush or close failed. Further
  /// writes are errors. The destructor closes too, without throwing.
  void Close();
  std::int64_t events() const { return events_; }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  lcm_eventlog_t* log_ = nullptr;
  std::vector<unsigned char> buf_;
  std::int64_t events_ = 0;
};

}  // namespace shoal
