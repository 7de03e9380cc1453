// Sending LCM short messages to many udpm groups in one system call. A process that
// releases a burst — the channel emulator sending each vehicle its bundle at one instant
// — pays the kernel's entry, and on a paravirtualised machine the hypervisor's, once for
// the burst instead of once per datagram (sendmmsg: 64 datagrams in about a third of the
// time of 64 sendto calls on the 2-vCPU VM of docs/benchmarks.md). The datagrams are LCM's
// own (runtime/udpm_receiver.h): "LC02", a sequence number, the channel and its NUL, the
// message; every LCM reader takes them.
#pragma once

#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/uio.h>

#include <cstdint>
#include <map>
#include <string_view>
#include <vector>

#include "runtime/udpm_receiver.h"

namespace shoal {

class UdpmBatch {
 public:
  /// The longest datagram kept (LCM sends a longer message in fragments).
  static constexpr int kMaxDatagramBytes = 65000;
  /// What a batch holds before it sends what it has and goes on: its memory is taken once,
  /// when it is made, and never grows (a soak judges a process's memory by its growth).
  static constexpr std::size_t kMaxBatchBytes = 256 * 1024;
  static constexpr std::size_t kMaxBatchDatagrams = 256;

  UdpmBatch();
  ~UdpmBatch();
  UdpmBatch(const UdpmBatch&) = delete;
  UdpmBatch& operator=(const UdpmBatch&) = delete;

  /// From Begin to Flush, Add keeps what it is given; otherwise it keeps nothing.
  void Begin() { active_ = true; }
  bool active() const { return active_; }
  /// Keeps one message for `to` (its group, port and TTL). False if it was not kept — the
  /// batch is not active, the datagram would be longer than kMaxDatagramBytes, or no
  /// socket could be opened: the caller then sends it itself.
  bool Add(const UdpmAddress& to, std::string_view channel, const void* data, int size);
  /// Sends what was kept, in the order it was added, and ends the batch. False if a
  /// datagram of the batch could not be sent (each is tried).
  bool Flush();

 private:
  struct Kept {
    sockaddr_in to;
    int fd;
    std::size_t offset, size;
  };
  int SocketFor(int ttl);
  /// Sends what is kept (the batch stays active); false if a datagram could not go.
  bool SendKept();

  bool active_ = false;
  bool failed_ = false;  // a datagram of this batch could not be sent
  std::uint32_t seqno_ = 0;
  std::vector<unsigned char> bytes_;  // the datagrams kept, back to back
  std::vector<Kept> kept_;
  std::vector<iovec> iov_;      // Flush's, kept for reuse
  std::vector<mmsghdr> msgs_;
  std::map<int, int> fds_;  // a sending socket per multicast TTL
};

}  // namespace shoal
