// Fuzz target: the LCM log reader (runtime/log_reader.h) and the log loader built on it
// (analysis/run_data.h's LoadRunLog: every Shoal channel decoded into RunData, the
// scenario text of a status parsed). The bytes are the log file, held in a memfd so that
// the reader opens a real path without touching the disk. Reading a finished log, following
// it as a growing one, and loading it must each end (with warnings if damaged), never crash.
#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "analysis/run_data.h"
#include "runtime/log_reader.h"

namespace {

// One memfd for the whole run, rewritten for each input.
const std::string& LogPath(const std::uint8_t* data, std::size_t size) {
  static const int fd = memfd_create("fuzz_log", MFD_CLOEXEC);
  static const std::string path = "/proc/self/fd/" + std::to_string(fd);
  if (fd < 0 || ftruncate(fd, 0) != 0) std::abort();
  std::size_t done = 0;
  while (done < size) {
    const ssize_t w = pwrite(fd, data + done, size - done, static_cast<off_t>(done));
    if (w <= 0) std::abort();
    done += static_cast<std::size_t>(w);
  }
  return path;
}

void ReadFinished(const std::string& path, std::size_t size) {
  shoal::LcmLogReader reader;
  std::string error;
  if (!reader.Open(path, &error)) return;
  shoal::LogEventView ev;
  std::int64_t last_offset = -1;
  while (reader.Next(&ev)) {
    // Every event lies inside the file, after the previous one.
    const std::int64_t end = ev.offset + shoal::LcmLogReader::kHeaderBytes +
                             static_cast<std::int64_t>(ev.channel.size()) + ev.size;
    if (ev.offset <= last_offset || ev.size < 0 || end > static_cast<std::int64_t>(size)) {
      std::abort();
    }
    last_offset = ev.offset;
  }
}

void ReadFollowed(const std::string& path) {
  shoal::LcmLogReader reader;
  if (!reader.OpenToFollow(path)) return;
  for (int k = 0; k < 2; ++k) {
    if (reader.ReadAppended([](std::string_view, const std::uint8_t*, int size) {
          if (size < 0) std::abort();
        }) < 0) {
      break;
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > (1u << 20)) return 0;
  const std::string& path = LogPath(data, size);
  ReadFinished(path, size);
  ReadFollowed(path);
  shoal::RunData run;
  std::string error;
  shoal::LoadRunLog(path, shoal::LoadOptions{}, &run, &error);
  return 0;
}
