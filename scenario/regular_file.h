// Opening an input file that must be a regular file: a scenario, an LCM log. A FIFO would
// block open() and read() forever, a device such as /dev/zero never ends, a directory or
// socket cannot be read as a file; each is refused with a message that says what it is.
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <string>

namespace shoal {

/// Opens `path` for reading (O_RDONLY | O_CLOEXEC) without ever blocking on it. Returns
/// the descriptor, or -1 with *error if it cannot be opened, is not a regular file (after
/// following symbolic links), or is larger than `max_bytes` (max_bytes < 0: no limit):
///   "<path>: cannot read <what> (No such file or directory)"
///   "<path>: cannot read <what>: it is a FIFO (named pipe), not a regular file"
/// *size_out, if given, receives the file's size.
int OpenRegularFile(const std::string& path, const std::string& what, std::int64_t max_bytes,
                    std::string* error, std::int64_t* size_out = nullptr);

/// What a file that is not a regular file is, for a message ("a directory", "a FIFO (named
/// pipe)", "a character device", ...).
const char* KindOf(mode_t mode);

/// Whether two paths name one existing file (the same device and inode, through any
/// links): an output that is an input would destroy it as it is written.
bool SameFile(const std::string& a, const std::string& b);

}  // namespace shoal
