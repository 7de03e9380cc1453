// Receiving an LCM udpm bus on the caller's own thread. LCM 1.3.1 receives on a thread of
// its own that hands each datagram to the handling thread through a pipe: two thread
// wake-ups per message, where the process itself needs one. At scale those wake-ups are
// most of a vehicle's CPU (docs/benchmarks.md, "shoal run at scale"); this reads the same
// multicast group and port with recvmmsg in the thread that handles the messages, so a
// process sleeps in one poll and wakes once for all that arrived meanwhile.
//
// The wire format is LCM's (lcm/udpm_util.h): a datagram is either a short message,
// "LC02", a sequence number, the channel name with its NUL, then the payload; or one
// fragment of a long one, "LC03", sequence number, message size, fragment offset,
// fragment number and count (network byte order), the channel after the header of
// fragment 0 only. What is not that is dropped and counted.
#pragma once

#include <netinet/in.h>

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace shoal {

/// What a udpm URL names: udpm://GROUP:PORT?ttl=N&recv_buf_size=B.
struct UdpmAddress {
  in_addr group{};
  int port = 0;
  int ttl = 0;            // LCM's default: the host only
  int recv_buf_size = 0;  // 0: not given
};

/// Parses an LCM udpm URL; false for any other provider or a malformed URL.
bool ParseUdpmUrl(const std::string& url, UdpmAddress* out);

class UdpmReceiver {
 public:
  using Handler = std::function<void(std::string_view channel, const unsigned char* data, int size)>;
  /// The kernel receive buffer asked for when the URL names none: the socket is the only
  /// queue between a sender and this process, so it must hold what arrives while the
  /// process steps a window or sleeps to its next period.
  static constexpr int kDefaultRecvBufBytes = 4 << 20;

  explicit UdpmReceiver(const UdpmAddress& address) : address_(address) {}
  ~UdpmReceiver();
  UdpmReceiver(const UdpmReceiver&) = delete;
  UdpmReceiver& operator=(const UdpmReceiver&) = delete;

  /// Opens the socket, shared with every other receiver of the group and port (LCM's
  /// SO_REUSEADDR), and joins the group. False with the reason in `error`.
  bool Open(std::string* error);
  int fd() const { return fd_; }

  /// Waits at most timeout_ms for a datagram (0: not at all; -1: without limit), then hands
  /// each complete message to `handler`, in arrival order, at most max_messages of them; the
  /// rest stays in the socket. Returns the number handed on, or -1 if the socket failed.
  int Receive(int timeout_ms, int max_messages, const Handler& handler);

  /// One datagram as it came from `from`, without a socket (what Receive does with each;
  /// also the fuzz target's entry): hands on the message it completes, if any, and says
  /// whether it did.
  bool OnDatagram(const unsigned char* p, int size, const sockaddr_in& from, const Handler& handler);

  /// From now on, notes when each datagram reached the socket (the kernel's receive time,
  /// SO_TIMESTAMPNS), for arrival_ns. False if the socket refuses; may come before Open.
  /// The kernel starts stamping a moment later (datagrams read before then carry the time
  /// they were read): ask at start, before the run's traffic.
  bool RecordArrivals();
  /// While `handler` runs: when the datagram that completed its message reached the
  /// socket, on CLOCK_MONOTONIC in ns; -1 if arrivals are not recorded or the kernel gave
  /// no time.
  std::int64_t arrival_ns() const { return arrival_ns_; }

  /// Datagrams that were not LCM's (a bad magic, too short, a channel without its NUL or
  /// longer than LCM allows, a fragment that does not fit its message).
  std::int64_t malformed() const { return malformed_; }
  /// Datagrams the kernel dropped because the socket's buffer was full, up to now
  /// (SO_MEMINFO's drop count).
  std::int64_t overflowed() const;
  /// The receive buffer the kernel gave (bytes; it doubles what is asked for).
  int recv_buf_bytes() const { return recv_buf_bytes_; }

 private:
  /// A long message being put together, per sender (LCM sends a message's fragments in
  /// order, one message at a time per sender). It holds the fragments that came, not a
  /// buffer of the size its header declares: a header may declare megabytes that never
  /// come. The fragments may not overlap; the message is put together and handed on once
  /// they cover every byte of it.
  struct Partial {
    std::uint32_t seqno = 0;
    std::uint32_t size = 0;
    bool named = false;  // fragment 0, which carries the channel, has come
    std::string channel;
    std::map<std::uint32_t, std::vector<unsigned char>> pieces;  // by offset
    std::uint32_t bytes = 0;                                      // their lengths summed
    std::size_t charged = 0;  // what they take in memory, as partial_bytes_ counts it
  };
  static constexpr int kBatch = 8;
  static constexpr int kDatagramBytes = 65536;
  /// Bounds on messages being put together, LCM's own: a message of at most 16 MB, 1000
  /// messages at once, and 16 MB in all, counted here as memory taken by the fragments
  /// received (with what keeping each one costs, so that a flood of one-byte fragments is
  /// bounded too), not as sizes declared.
  static constexpr std::size_t kMaxMessageBytes = std::size_t{1} << 24;
  static constexpr std::size_t kPieceOverhead = 128;
  static constexpr std::size_t kMaxPartialBytes = kMaxMessageBytes + 65536 * kPieceOverhead;
  static constexpr std::size_t kMaxPartials = 1000;

  bool OnFragment(const unsigned char* p, int size, const sockaddr_in& from, const Handler& handler);
  void DropPartial(std::map<std::uint64_t, Partial>::iterator it);
  /// Keeps a fragment's n bytes at `offset` in the message `it` points to; false if they
  /// overlap bytes another fragment gave, or if keeping them would pass kMaxPartialBytes
  /// even once every other message has given way.
  bool Keep(std::map<std::uint64_t, Partial>::iterator it, std::uint32_t offset,
            const unsigned char* data, std::uint32_t n);

  UdpmAddress address_;
  /// Bounds recvmmsg's wait for a first datagram (SO_RCVTIMEO) to timeout_ms; false if
  /// the socket refused.
  bool SetWait(int timeout_ms);

  int fd_ = -1;
  int wait_ms_ = -1;  // the socket's SO_RCVTIMEO (-1: without limit, as opened)
  int recv_buf_bytes_ = 0;
  bool record_arrivals_ = false;
  std::int64_t arrival_ns_ = -1;
  std::int64_t malformed_ = 0;
  // kBatch datagrams of kDatagramBytes, not zero-filled: recvmmsg writes what is read, and
  // a process touches only the pages its datagrams reach (a vehicle's bundles: the first).
  std::unique_ptr<unsigned char[]> buffers_;
  std::map<std::uint64_t, Partial> partials_;  // by sender address and port
  std::size_t partial_bytes_ = 0;
  std::vector<unsigned char> whole_;  // a long message put together
};

}  // namespace shoal
