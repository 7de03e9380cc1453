#include "runtime/log_writer.h"

#include <cerrno>
#include <cstring>

namespace shoal {

LogWriter::LogWriter(const std::string& path) : path_(path), buf_(1024) {
  log_ = lcm_eventlog_create(path.c_str(), "w");
  if (log_ == nullptr) {
    throw std::runtime_error(path + ": cannot open log for writing (" + std::strerror(errno) +
                             ")");
  }
  // Larger stdio buffer: the simulator writes millions of small events.
  std::setvbuf(log_->f, nullptr, _IOFBF, 1 << 20);
}

LogWriter::~LogWriter() {
  try {
    Close();
  } catch (const std::runtime_error&) {
    // A log closed by the destructor is abandoned (an error path); its failure was or
    // will be reported by whoever stopped using it.
  }
}

void LogWriter::WriteRaw(const std::string& channel, std::int64_t utime, const void* data,
                         int size) {
  if (log_ == nullptr) throw std::runtime_error(path_ + ": write to a closed log");
  lcm_eventlog_event_t ev;
  ev.eventnum = events_;
  ev.timestamp = utime;
  ev.channellen = static_cast<std::int32_t>(channel.size());
  ev.datalen = size;
  ev.channel = const_cast<char*>(channel.c_str());
  ev.data = const_cast<void*>(data);
  if (lcm_eventlog_write_event(log_, &ev) != 0) {
    throw std::runtime_error(path_ + ": write failed (" + std::strerror(errno) + ")");
  }
  ++events_;
}

void LogWriter::Flush() {
  if (log_ == nullptr) throw std::runtime_error(path_ + ": write to a closed log");
  if (std::fflush(log_->f) != 0 || std::ferror(log_->f)) {
    throw std::runtime_error(path_ + ": write failed (" + std::strerror(errno) + ")");
  }
}

void LogWriter::Close() {
  if (log_ == nullptr) return;
  // lcm_eventlog_destroy ignores fclose's result: flush first and check, so that a full
  // disk is reported rather than a silently cut log.
  const bool flushed = std::fflush(log_->f) == 0 && !std::ferror(log_->f);
  const int flush_errno = errno;
  lcm_eventlog_destroy(log_);
  log_ = nullptr;
  if (!flushed) {
    throw std::runtime_error(path_ + ": write failed (" + std::strerror(flush_errno) + ")");
  }
}

}  // namespace shoal
