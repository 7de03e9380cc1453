#include "runtime/log_reader.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "scenario/regular_file.h"

namespace shoal {
namespace {

constexpr std::size_t kChunk = 8u << 20;  // bytes per read(): few system calls, small RSS
constexpr std::uint8_t kSyncBytes[4] = {0xED, 0xA1, 0xDA, 0x01};

std::uint32_t U32(const std::uint8_t* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) |
         std::uint32_t{p[3]};
}
std::int64_t I64(const std::uint8_t* p) {
  return static_cast<std::int64_t>((std::uint64_t{U32(p)} << 32) | std::uint64_t{U32(p + 4)});
}
std::int32_t I32(const std::uint8_t* p) { return static_cast<std::int32_t>(U32(p)); }

std::string Num(std::int64_t v) { return std::to_string(v); }

/// A sync word with sane lengths and a printable channel (as far as `avail` bytes go).
bool PlausibleHeader(const std::uint8_t* h, std::size_t avail) {
  if (avail < static_cast<std::size_t>(LcmLogReader::kHeaderBytes) || U32(h) != LcmLogReader::kSync) {
    return false;
  }
  const std::int32_t cl = I32(h + 20), dl = I32(h + 24);
  if (cl < 1 || cl > LcmLogReader::kMaxChannel || dl < 0 || dl > LcmLogReader::kMaxData) return false;
  const std::size_t n = std::min<std::size_t>(static_cast<std::size_t>(cl), avail - LcmLogReader::kHeaderBytes);
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint8_t c = h[LcmLogReader::kHeaderBytes + k];
    if (c < 0x20 || c > 0x7E) return false;
  }
  return true;
}

}  // namespace

LcmLogReader::~LcmLogReader() {
  if (fd_ >= 0) close(fd_);
}

bool LcmLogReader::Open(const std::string& path, std::string* error) {
  path_ = path;
  // A FIFO or a device is refused, never read (it would block or never end).
  fd_ = OpenRegularFile(path, "log", -1, error, &file_size_);
  if (fd_ < 0) return false;
  if (file_size_ == 0) {
    *error = path + ": empty file (0 bytes), not an LCM log";
    return false;
  }
  posix_fadvise(fd_, 0, 0, POSIX_FADV_SEQUENTIAL);
  if (file_size_ < kHeaderBytes) {
    *error = path + ": " + Num(file_size_) + " bytes, too short to hold one LCM log event (" +
             Num(kHeaderBytes) + "-byte header); not an LCM log";
    return false;
  }
  const Check c = CheckEventAt();
  if (c == Check::kValid || c == Check::kCutShort) return true;  // a short file is truncated
  // Not an event at byte 0: a damaged start, or not an LCM log at all. Look for an event
  // in the first megabyte; a file without one is not an LCM log.
  constexpr std::int64_t kScan = 1 << 20;
  if (Resync(kScan)) {
    Warn("the file does not start with an LCM event (damaged start): skipped " +
         Num(FileOffset()) + " bytes to the first event, at byte " + Num(FileOffset()));
    return true;
  }
  *error = path + ": not an LCM log (no LCM event header with sync word 0xEDA1DA01 in its first " +
           Num(std::min<std::int64_t>(kScan, file_size_)) + " bytes)";
  return false;
}

void LcmLogReader::Warn(const std::string& w) {
  ++damaged_regions_;
  if (damaged_regions_ <= kMaxWarnings) {
    warnings_.push_back(path_ + ": " + w);
  } else if (damaged_regions_ == kMaxWarnings + 1) {
    warnings_.push_back(path_ + ": more damaged places follow (only the first " +
                        Num(kMaxWarnings) + " are listed)");
  }
}

bool LcmLogReader::Ensure(std::size_t n) {
  if (Available() >= n) return true;
  if (eof_) return false;
  // Keep the unread tail, move it to the front, and fill the rest with whole reads.
  if (pos_ > 0) {
    std::memmove(buf_.data(), buf_.data() + pos_, Available());
    buf_offset_ += static_cast<std::int64_t>(pos_);
    end_ -= pos_;
    pos_ = 0;
  }
  // A small file needs no more than its own size (and no 8 MB buffer to clear).
  const std::size_t want =
      std::max(n, std::min(kChunk, static_cast<std::size_t>(file_size_ - buf_offset_) + 16));
  if (buf_.size() < want) buf_.resize(want);
  while (end_ < buf_.size() && !eof_) {
    const ssize_t r = read(fd_, buf_.data() + end_, buf_.size() - end_);
    if (r < 0) {
      if (errno == EINTR) continue;
      Warn("read error at byte " + Num(buf_offset_ + static_cast<std::int64_t>(end_)) + " (" +
           std::strerror(errno) + "); the rest of the file is not analysed");
      stopped_early_ = true;
      eof_ = true;
      break;
    }
    if (r == 0) {
      eof_ = true;
      break;
    }
    end_ += static_cast<std::size_t>(r);
    if (end_ - pos_ >= n && end_ >= kChunk) break;
  }
  return Available() >= n;
}

LcmLogReader::Check LcmLogReader::CheckEventAt() {
  if (!Ensure(kHeaderBytes)) {
    // A partial header: cut short if what is there starts like a header.
    const std::size_t a = Available();
    return std::memcmp(buf_.data() + pos_, kSyncBytes, std::min<std::size_t>(a, 4)) == 0
               ? Check::kCutShort
               : Check::kBadSync;
  }
  const std::uint8_t* h = buf_.data() + pos_;
  if (U32(h) != kSync) return Check::kBadSync;
  const std::int32_t cl = I32(h + 20), dl = I32(h + 24);
  if (cl < 1 || cl > kMaxChannel || dl < 0 || dl > kMaxData) return Check::kBadHeader;
  const std::size_t total = kHeaderBytes + static_cast<std::size_t>(cl) + static_cast<std::size_t>(dl);
  // Longer than the rest of the file: cut short (checked first, so that a damaged length
  // never makes the buffer grow to it).
  if (static_cast<std::int64_t>(total) > file_size_ - FileOffset()) {
    struct stat st {};
    if (fstat(fd_, &st) != 0 || static_cast<std::int64_t>(total) > st.st_size - FileOffset()) {
      return Check::kCutShort;
    }
    file_size_ = st.st_size;  // the file grew (a recorder still writing it): read on
    eof_ = stopped_early_;
  }
  if (!Ensure(total)) return Check::kCutShort;
  const std::uint8_t* c = buf_.data() + pos_ + kHeaderBytes;
  for (std::int32_t k = 0; k < cl; ++k) {
    if (c[k] < 0x20 || c[k] > 0x7E) return Check::kBadHeader;
  }
  // The next event should start right after this one (or the file ends). If it does not,
  // either this event's lengths are damaged (then it swallows the start of a real event:
  // reject it) or the next event is damaged (then this one is fine).
  if (Ensure(total + 4) &&
      std::memcmp(buf_.data() + pos_ + total, kSyncBytes, 4) != 0) {
    const std::uint8_t* b = buf_.data() + pos_;
    const std::size_t avail = Available();
    for (std::size_t k = 1; k < total; ++k) {
      const void* hit = memmem(b + k, total - k, kSyncBytes, 4);
      if (hit == nullptr) break;
      k = static_cast<std::size_t>(static_cast<const std::uint8_t*>(hit) - b);
      if (PlausibleHeader(b + k, avail - k)) return Check::kNotFollowed;
    }
  }
  return Check::kValid;
}

bool LcmLogReader::Resync(std::int64_t limit) {
  const std::int64_t start = FileOffset();
  pos_ += 1;
  for (;;) {
    if (limit >= 0 && FileOffset() - start >= limit) return false;
    if (!Ensure(4)) {
      skipped_bytes_ += FileOffset() - start + static_cast<std::int64_t>(Available());
      pos_ = end_;
      return false;
    }
    const void* hit = memmem(buf_.data() + pos_, Available(), kSyncBytes, 4);
    if (hit == nullptr) {
      pos_ = end_ - 3;  // a sync word may straddle the refill
      continue;
    }
    pos_ = static_cast<std::size_t>(static_cast<const std::uint8_t*>(hit) - buf_.data());
    // A buffer holds more than the limit: a sync word found beyond it is not accepted.
    if (limit >= 0 && FileOffset() - start >= limit) return false;
    if (CheckEventAt() == Check::kValid) {
      skipped_bytes_ += FileOffset() - start;
      return true;
    }
    pos_ += 1;
  }
}

bool LcmLogReader::Next(LogEventView* ev) {
  while (!done_) {
    if (!Ensure(1)) {  // clean end of file
      done_ = true;
      return false;
    }
    const std::int64_t at = FileOffset();
    const Check c = CheckEventAt();
    if (c == Check::kValid) {
      const std::uint8_t* h = buf_.data() + pos_;
      const std::int32_t cl = I32(h + 20), dl = I32(h + 24);
      ev->eventnum = I64(h + 4);
      ev->timestamp = I64(h + 12);
      ev->channel = std::string_view(reinterpret_cast<const char*>(h + kHeaderBytes),
                                     static_cast<std::size_t>(cl));
      ev->data = h + kHeaderBytes + cl;
      ev->size = dl;
      ev->offset = at;
      pos_ += kHeaderBytes + static_cast<std::size_t>(cl) + static_cast<std::size_t>(dl);
      ++events_;
      return true;
    }
    const char* what = c == Check::kBadSync     ? "no sync word"
                       : c == Check::kBadHeader ? "an implausible event header"
                       : c == Check::kCutShort  ? "an event cut short by the end of the file"
                                                : "an event whose lengths do not lead to the next event";
    const std::int64_t unread = file_size_ - at;
    if (Resync(-1)) {
      Warn("damaged at byte " + Num(at) + " (" + what + "): skipped " + Num(FileOffset() - at) +
           " bytes, resynchronised at the next valid event, at byte " + Num(FileOffset()));
      continue;
    }
    done_ = true;
    stopped_early_ = true;
    if (c == Check::kCutShort) {
      Warn("truncated: the last event, at byte " + Num(at) + ", is cut short by the end of the file (" +
           Num(unread) + " bytes left); analysed up to byte " + Num(at));
    } else {
      Warn("damaged at byte " + Num(at) + " (" + what +
           ") and no valid event follows; stopped there, " + Num(unread) + " bytes not analysed");
    }
    return false;
  }
  return false;
}

bool LcmLogReader::OpenToFollow(const std::string& path) {
  path_ = path;
  std::string error;  // not there yet, or not a file: nothing to follow
  fd_ = OpenRegularFile(path, "log", -1, &error);
  return fd_ >= 0;
}

int LcmLogReader::ReadAppended(const EventHandler& on) {
  if (done_ || fd_ < 0) return done_ ? -1 : 0;
  struct stat st {};
  if (fstat(fd_, &st) == 0) file_size_ = st.st_size;
  eof_ = false;  // read what was appended since the last call
  int handled = 0;
  while (Ensure(kHeaderBytes)) {
    const std::uint8_t* h = buf_.data() + pos_;
    const std::int32_t cl = I32(h + 20), dl = I32(h + 24);
    if (U32(h) != kSync || cl < 1 || cl > kMaxChannel || dl < 0 || dl > kMaxData) {
      Warn("damaged at byte " + Num(FileOffset()) + " (" +
           (U32(h) != kSync ? "no sync word" : "an implausible event header") +
           "); stopped following the log there");
      done_ = true;
      stopped_early_ = true;
      return -1;
    }
    const std::size_t total =
        kHeaderBytes + static_cast<std::size_t>(cl) + static_cast<std::size_t>(dl);
    // Not completely written yet. Checked against the file's size first, so that a damaged
    // or half-written length never makes the buffer grow to it (up to kMaxData).
    if (static_cast<std::int64_t>(total) > file_size_ - FileOffset() || !Ensure(total)) break;
    h = buf_.data() + pos_;     // Ensure may have moved the buffer
    on(std::string_view(reinterpret_cast<const char*>(h + kHeaderBytes),
                        static_cast<std::size_t>(cl)),
       h + kHeaderBytes + cl, dl);
    pos_ += total;
    ++events_;
    ++handled;
  }
  return handled;
}

int LogTail::Poll(const Handler& on) {
  if (damaged_) return -1;
  if (!open_) {
    open_ = reader_.OpenToFollow(path_);
    if (!open_) return 0;  // not created yet
  }
  const int handled =
      reader_.ReadAppended([&](std::string_view ch, const std::uint8_t* data, int size) {
        channel_.assign(ch.data(), ch.size());
        on(channel_, data, size);
      });
  damaged_ = handled < 0;
  return handled;
}

}  // namespace shoal
