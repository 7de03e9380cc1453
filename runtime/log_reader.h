// The reader of LCM event logs (the format of lcm-logger, lcm-logplayer and
// runtime/log_writer): big buffered reads, no per-event allocation, and damage reported
// instead of fatal. It reads a finished log (Open, Next: shoal analyze, compare, render)
// or follows one that another process is still appending to (LogTail: shoal run takes its
// progress from the log this way instead of listening on the bus, so that watching a run
// adds no receiver to its multicast group -- every receiver costs every message a copy
// and two thread wake-ups).
//
// Event layout (all big-endian), LCM's eventlog format:
//   uint32 sync = 0xEDA1DA01, int64 event number, int64 timestamp [us],
//   int32 channel length, int32 data length, channel bytes, data bytes.
//
// Damage handling:
//   - a file that is empty, unreadable, or in which no event can be found is an error
//     (Open() returns false with the reason);
//   - a bad sync word or an implausible header in the middle: the reader scans forward
//     for the next plausible event header and resumes there, with a warning that says
//     where and how many bytes were skipped ("resynchronised"); if none follows, it stops
//     with a warning ("stopped");
//   - an event cut short by the end of the file (truncated log): the reader stops with a
//     warning that names the offset.
// A followed log is written as it is read: an event cut short by the end of the file is
// not complete yet, and damage stops the reading (no resynchronisation).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

namespace shoal {

/// One event as read; channel and data point into the reader's buffer and stay valid
/// until the next call to Next().
struct LogEventView {
  std::int64_t eventnum = 0;
  std::int64_t timestamp = 0;  // [us] as recorded (wall clock by lcm-logger, sim time by shoal sim)
  std::string_view channel;
  const std::uint8_t* data = nullptr;
  std::int32_t size = 0;
  std::int64_t offset = 0;  // [byte] of the event's sync word in the file
};

class LcmLogReader {
 public:
  static constexpr std::uint32_t kSync = 0xEDA1DA01u;
  static constexpr int kHeaderBytes = 4 + 8 + 8 + 4 + 4;
  /// Plausibility limits of a header (LCM channel names are at most 63 characters).
  static constexpr std::int32_t kMaxChannel = 256;
  static constexpr std::int32_t kMaxData = 256 << 20;

  LcmLogReader() = default;
  ~LcmLogReader();
  LcmLogReader(const LcmLogReader&) = delete;
  LcmLogReader& operator=(const LcmLogReader&) = delete;

  /// Opens `path`. False, with a user-facing reason in *error, if the file cannot be read,
  /// is empty, or contains no plausible LCM event at all (not an LCM log).
  bool Open(const std::string& path, std::string* error);

  /// The next event; false at the end of the file or at damage it cannot read past.
  bool Next(LogEventView* ev);

  /// Follows `path`, a log another process is still appending to. False if it cannot be
  /// opened (yet): not an error, it may not have been created yet.
  bool OpenToFollow(const std::string& path);
  using EventHandler =
      std::function<void(std::string_view channel, const std::uint8_t* data, int size)>;
  /// Following: calls `on` for every complete event appended since the last call, in
  /// order; an event not complete yet waits for the next call. Returns the number of
  /// events handled, or -1 once the log is found damaged (a bad sync word or impossible
  /// lengths; a warning says where), after which it reads no more.
  int ReadAppended(const EventHandler& on);

  /// Damage found so far, one user-facing sentence each.
  const std::vector<std::string>& warnings() const { return warnings_; }
  /// True if the reader stopped before the end of the file (truncated or unreadable rest).
  bool stopped_early() const { return stopped_early_; }
  std::int64_t events() const { return events_; }
  std::int64_t skipped_bytes() const { return skipped_bytes_; }
  /// Damaged places found (each one a warning, the first kMaxWarnings spelled out).
  std::int64_t damaged_regions() const { return damaged_regions_; }
  static constexpr int kMaxWarnings = 20;
  std::int64_t file_size() const { return file_size_; }

 private:
  enum class Check { kValid, kBadSync, kBadHeader, kCutShort, kNotFollowed };
  /// Makes at least `n` bytes available from pos_ (fewer only at the end of the file).
  bool Ensure(std::size_t n);
  std::size_t Available() const { return end_ - pos_; }
  std::int64_t FileOffset() const { return buf_offset_ + static_cast<std::int64_t>(pos_); }
  /// Is there a complete, plausible event at pos_, followed by another sync word or by the
  /// end of the file? (May refill the buffer; pos_'s file offset does not change.)
  Check CheckEventAt();
  /// Scans forward from pos_ + 1 (at most limit bytes, < 0: no limit) for a valid event;
  /// true if found (pos_ moves there), false at the end of the file.
  bool Resync(std::int64_t limit);
  void Warn(const std::string& w);

  std::string path_;
  int fd_ = -1;
  std::vector<std::uint8_t> buf_;
  std::size_t pos_ = 0, end_ = 0;
  std::int64_t buf_offset_ = 0;  // file offset of buf_[0]
  std::int64_t file_size_ = 0;
  bool eof_ = false;
  bool done_ = false;
  bool stopped_early_ = false;
  std::int64_t events_ = 0;
  std::int64_t skipped_bytes_ = 0;
  std::int64_t damaged_regions_ = 0;
  std::vector<std::string> warnings_;
};

/// Follows the LCM log at `path` while another process (lcm-logger) appends to it: each
/// Poll() hands over the complete events written since the last one.
class LogTail {
 public:
  using Handler = std::function<void(const std::string& channel, const void* data, int size)>;

  explicit LogTail(std::string path) : path_(std::move(path)) {}

  /// Calls `on` for every complete event appended since the last call. Returns the number
  /// of events handled (0 while the file does not exist); -1 once the file is found
  /// damaged, after which it stops reading.
  int Poll(const Handler& on);

  std::int64_t events() const { return reader_.events(); }
  bool damaged() const { return damaged_; }

 private:
  std::string path_;
  LcmLogReader reader_;
  bool open_ = false;
  bool damaged_ = false;
  std::string channel_;  // the current event's channel, for Handler
};

}  // namespace shoal
