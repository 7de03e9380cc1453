#include "scenario/regular_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace shoal {

const char* KindOf(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a FIFO (named pipe)";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "a special file";
}

int OpenRegularFile(const std::string& path, const std::string& what, std::int64_t max_bytes,
                    std::string* error, std::int64_t* size_out) {
  const std::string cannot = path + ": cannot read " + what;
  // O_NONBLOCK: opening a FIFO without a writer returns at once instead of waiting for
  // one; the kind is checked on the open descriptor, so nothing can swap the file between
  // the check and the reads.
  const int fd = open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) {
    const int e = errno;
    struct stat st {};
    if (e == ENXIO && stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) {
      *error = cannot + ": it is " + KindOf(st.st_mode) + ", not a regular file";  // a socket
    } else {
      *error = cannot + " (" + std::strerror(e) + ")";
    }
    return -1;
  }
  struct stat st {};
  if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    *error = cannot + ": it is " + KindOf(st.st_mode) + ", not a regular file";
    close(fd);
    return -1;
  }
  if (max_bytes >= 0 && st.st_size > max_bytes) {
    *error = cannot + ": " + std::to_string(st.st_size) + " bytes, larger than the limit of " +
             std::to_string(max_bytes) + " bytes";
    close(fd);
    return -1;
  }
  // Regular files never block; clear the flag anyway so that reads behave as usual.
  fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) & ~O_NONBLOCK);
  if (size_out != nullptr) *size_out = st.st_size;
  return fd;
}

bool SameFile(const std::string& a, const std::string& b) {
  struct stat sa {}, sb {};
  return stat(a.c_str(), &sa) == 0 && stat(b.c_str(), &sb) == 0 && sa.st_dev == sb.st_dev &&
         sa.st_ino == sb.st_ino;
}

}  // namespace shoal
