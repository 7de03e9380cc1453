#include "runtime/log_tail.h"

#include <cstring>

namespace shoal {
namespace {

constexpr std::uint32_t kSync = 0xEDA1DA01u;  // LCM event log sync word (big endian)
constexpr std::size_t kHeader = 4 + 8 + 8 + 4 + 4;

std::uint32_t Be32(const unsigned char* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) |
         std::uint32_t{p[3]};
}

}  // namespace

LogTail::~LogTail() {
  if (f_) std::fclose(f_);
}

int LogTail::Poll(const Handler& on) {
  if (damaged_) return -1;
  if (!f_) {
    f_ = std::fopen(path_.c_str(), "rb");
    if (!f_) return 0;  // not created yet
  }
  unsigned char chunk[1 << 16];
  for (;;) {
    const std::size_t got = std::fread(chunk, 1, sizeof chunk, f_);
    buf_.insert(buf_.end(), chunk, chunk + got);
    if (got < sizeof chunk) break;
  }
  std::clearerr(f_);  // at EOF now; later calls read what is appended
  int handled = 0;
  std::size_t pos = 0;
  std::string channel;
  while (buf_.size() - pos >= kHeader) {
    const unsigned char* h = buf_.data() + pos;
    const std::uint32_t chan_len = Be32(h + 20), data_len = Be32(h + 24);
    if (Be32(h) != kSync || chan_len > 1000 || data_len > (1u << 28)) {
      damaged_ = true;
      buf_.clear();
      return -1;
    }
    const std::size_t total = kHeader + chan_len + data_len;
    if (buf_.size() - pos < total) break;
    channel.assign(reinterpret_cast<const char*>(h + kHeader), chan_len);
    on(channel, h + kHeader + chan_len, static_cast<int>(data_len));
    pos += total;
    ++handled;
  }
  buf_.erase(buf_.begin(), buf_.begin() + static_cast<std::ptrdiff_t>(pos));
  events_ += handled;
  return handled;
}

}  // namespace shoal
