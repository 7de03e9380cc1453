#include "runtime/udpm_receiver.h"

#include <arpa/inet.h>
#include <linux/sock_diag.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <iterator>

namespace shoal {

namespace {

constexpr std::uint32_t kMagicShort = 0x4c433032;  // "LC02"
constexpr std::uint32_t kMagicLong = 0x4c433033;   // "LC03"
constexpr int kShortHeader = 8;
constexpr int kLongHeader = 20;
constexpr int kMaxChannel = 63;  // LCM_MAX_CHANNEL_NAME_LENGTH

std::uint32_t Be32(const unsigned char* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) |
         std::uint32_t{p[3]};
}
std::uint16_t Be16(const unsigned char* p) {
  return static_cast<std::uint16_t>((p[0] << 8) | p[1]);
}

// The channel at p (at most `size` bytes): its length, or -1 if it has no NUL within
// LCM's longest name.
int ChannelLength(const unsigned char* p, int size) {
  const int limit = std::min(size, kMaxChannel + 1);
  const void* nul = std::memchr(p, 0, static_cast<std::size_t>(std::max(limit, 0)));
  return nul == nullptr ? -1 : static_cast<int>(static_cast<const unsigned char*>(nul) - p);
}

// A whole number in [lo, hi] from `text`; false if it is not one.
bool ParseInt(const std::string& text, long lo, long hi, int* out) {
  if (text.empty()) return false;
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(text.c_str(), &end, 0);
  if (errno != 0 || *end != '\0' || v < lo || v > hi) return false;
  *out = static_cast<int>(v);
  return true;
}

std::int64_t NsOf(const timespec& t) {
  return static_cast<std::int64_t>(t.tv_sec) * 1000000000 + t.tv_nsec;
}

// The moment datagrams were read, on both clocks.
struct ReadTime {
  std::int64_t mono_ns = 0;
  std::int64_t wall_minus_mono_ns = 0;
};
ReadTime ReadTimeNow() {
  timespec wall{}, mono{};
  clock_gettime(CLOCK_REALTIME, &wall);
  clock_gettime(CLOCK_MONOTONIC, &mono);
  return {NsOf(mono), NsOf(wall) - NsOf(mono)};
}

// The datagram's SCM_TIMESTAMPNS on the monotonic clock, or -1 if it has none. Never after
// the read: a wall clock set back between arrival and read must not hold a message for
// that long.
std::int64_t ArrivalOf(const msghdr& h, const ReadTime& read) {
  if ((h.msg_flags & MSG_CTRUNC) != 0) return -1;
  for (const cmsghdr* c = CMSG_FIRSTHDR(&h); c != nullptr;
       c = CMSG_NXTHDR(const_cast<msghdr*>(&h), const_cast<cmsghdr*>(c))) {
    if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMPNS &&
        c->cmsg_len >= CMSG_LEN(sizeof(timespec))) {
      timespec t{};
      std::memcpy(&t, CMSG_DATA(c), sizeof(t));
      return std::min(NsOf(t) - read.wall_minus_mono_ns, read.mono_ns);
    }
  }
  return -1;
}

}  // namespace

bool ParseUdpmUrl(const std::string& url, UdpmAddress* out) {
  const std::string scheme = "udpm://";
  if (url.compare(0, scheme.size(), scheme) != 0) return false;
  std::string rest = url.substr(scheme.size());
  std::string query;
  if (const std::size_t q = rest.find('?'); q != std::string::npos) {
    query = rest.substr(q + 1);
    rest.resize(q);
  }
  UdpmAddress a;
  std::string group = rest.empty() ? "239.255.76.67" : rest;
  a.port = 7667;  // LCM's defaults
  if (const std::size_t colon = rest.find(':'); colon != std::string::npos) {
    group = rest.substr(0, colon);
    if (!ParseInt(rest.substr(colon + 1), 0, 65535, &a.port)) return false;
  }
  if (inet_aton(group.c_str(), &a.group) == 0) return false;
  for (std::size_t pos = 0; pos < query.size();) {
    std::size_t amp = query.find('&', pos);
    if (amp == std::string::npos) amp = query.size();
    const std::string item = query.substr(pos, amp - pos);
    const std::size_t eq = item.find('=');
    if (eq != std::string::npos && item.compare(0, eq, "recv_buf_size") == 0 &&
        !ParseInt(item.substr(eq + 1), 0, 1L << 30, &a.recv_buf_size)) {
      return false;
    }
    if (eq != std::string::npos && item.compare(0, eq, "ttl") == 0 &&
        !ParseInt(item.substr(eq + 1), 0, 255, &a.ttl)) {
      return false;
    }
    pos = amp + 1;
  }
  *out = a;
  return true;
}

UdpmReceiver::~UdpmReceiver() {
  if (fd_ >= 0) close(fd_);
}

bool UdpmReceiver::Open(std::string* error) {
  if (fd_ >= 0) return true;
  const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) {
    *error = std::string("cannot open a UDP socket (") + std::strerror(errno) + ")";
    return false;
  }
  const int one = 1;
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  // Bound to the group, not to any address: the socket then takes only this group's
  // datagrams, even where another group on the host uses the same port.
  addr.sin_addr = address_.group;
  addr.sin_port = htons(static_cast<std::uint16_t>(address_.port));
  ip_mreq join{};
  join.imr_multiaddr = address_.group;
  join.imr_interface.s_addr = htonl(INADDR_ANY);
  const char* step = nullptr;
  if (setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one)) < 0) {
    step = "SO_REUSEADDR";
  } else if (bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) < 0) {
    step = "bind";
  } else if (setsockopt(fd, IPPROTO_IP, IP_ADD_MEMBERSHIP, &join, sizeof(join)) < 0) {
    step = "joining the multicast group";
  }
  if (step != nullptr) {
    *error = std::string(step) + " failed for port " + std::to_string(address_.port) + " (" +
             std::strerror(errno) + ")";
    close(fd);
    return false;
  }
  // As much as asked (or the default), past net.core.rmem_max where the process may
  // (SO_RCVBUFFORCE needs CAP_NET_ADMIN); otherwise up to that limit.
  const int want = address_.recv_buf_size > 0 ? address_.recv_buf_size : kDefaultRecvBufBytes;
  if (setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &want, sizeof(want)) < 0) {
    setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &want, sizeof(want));
  }
  socklen_t len = sizeof(recv_buf_bytes_);
  getsockopt(fd, SOL_SOCKET, SO_RCVBUF, &recv_buf_bytes_, &len);
  fd_ = fd;
  if (record_arrivals_ && !RecordArrivals()) record_arrivals_ = false;
  buffers_.reset(new unsigned char[static_cast<std::size_t>(kBatch) * kDatagramBytes]);
  return true;
}

bool UdpmReceiver::RecordArrivals() {
  record_arrivals_ = true;
  if (fd_ < 0) return true;  // Open asks the kernel
  const int one = 1;
  if (setsockopt(fd_, SOL_SOCKET, SO_TIMESTAMPNS, &one, sizeof(one)) == 0) return true;
  record_arrivals_ = false;
  return false;
}

bool UdpmReceiver::SetWait(int timeout_ms) {
  if (timeout_ms == wait_ms_) return true;
  timeval tv{};
  if (timeout_ms > 0) {
    tv.tv_sec = timeout_ms / 1000;
    tv.tv_usec = static_cast<suseconds_t>(timeout_ms % 1000) * 1000;
  }
  if (setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof(tv)) != 0) return false;
  wait_ms_ = timeout_ms < 0 ? -1 : timeout_ms;
  return true;
}

int UdpmReceiver::Receive(int timeout_ms, int max_messages, const Handler& handler) {
  if (fd_ < 0) return -1;
  // The wait for the first datagram is recvmmsg's own (MSG_WAITFORONE, bounded by
  // SO_RCVTIMEO): one system call per wake-up where poll and then recvmmsg took two. A
  // lockstep vehicle wakes once a window, and on a machine with page-table isolation and
  // no PCID every system call also empties the TLB.
  bool wait = timeout_ms != 0;
  if (wait && !SetWait(timeout_ms)) {
    pollfd pfd{fd_, POLLIN, 0};  // as the kernel would not bound the wait, poll does
    const int r = poll(&pfd, 1, timeout_ms);
    if (r < 0) return errno == EINTR ? 0 : -1;  // a signal: the caller looks why
    if (r == 0) return 0;
    wait = false;
  }
  mmsghdr msgs[kBatch];
  iovec iov[kBatch];
  sockaddr_in from[kBatch];
  // The kernel's receive times (CLOCK_REALTIME), with record_arrivals_.
  alignas(cmsghdr) unsigned char control[kBatch][CMSG_SPACE(sizeof(timespec))];
  int handed = 0;
  while (handed < max_messages) {
    const int want = std::min(kBatch, max_messages - handed);
    for (int k = 0; k < want; ++k) {
      iov[k] = {buffers_.get() + static_cast<std::size_t>(k) * kDatagramBytes, kDatagramBytes};
      msgs[k].msg_hdr = {};
      msgs[k].msg_hdr.msg_name = &from[k];
      msgs[k].msg_hdr.msg_namelen = sizeof(from[k]);
      msgs[k].msg_hdr.msg_iov = &iov[k];
      msgs[k].msg_hdr.msg_iovlen = 1;
      if (record_arrivals_) {
        msgs[k].msg_hdr.msg_control = control[k];
        msgs[k].msg_hdr.msg_controllen = sizeof(control[k]);
      }
      msgs[k].msg_len = 0;
    }
    const int n = recvmmsg(fd_, msgs, static_cast<unsigned>(want),
                           wait ? MSG_WAITFORONE : MSG_DONTWAIT, nullptr);
    if (n < 0 && wait && errno == EINTR) return handed;  // a signal: the caller looks why
    wait = false;
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno == EAGAIN || errno == EWOULDBLOCK) break;  // nothing (more), or timed out
      arrival_ns_ = -1;
      return handed > 0 ? handed : -1;
    }
    // The stamps are on the wall clock, the loops' deadlines on the monotonic one: the
    // offset between them now converts them (off by a clock step between the datagram's
    // arrival and this read, if one happened).
    const ReadTime read = record_arrivals_ ? ReadTimeNow() : ReadTime{};
    for (int k = 0; k < n; ++k) {
      arrival_ns_ = record_arrivals_ ? ArrivalOf(msgs[k].msg_hdr, read) : -1;
      if ((msgs[k].msg_hdr.msg_flags & MSG_TRUNC) != 0) {  // larger than a datagram can be: not LCM's
        ++malformed_;
        continue;
      }
      const auto* p = static_cast<const unsigned char*>(iov[k].iov_base);
      if (OnDatagram(p, static_cast<int>(msgs[k].msg_len), from[k], handler)) ++handed;
    }
    if (n < want) break;
  }
  arrival_ns_ = -1;
  return handed;
}

std::int64_t UdpmReceiver::overflowed() const {
  if (fd_ < 0) return 0;
  std::uint32_t info[SK_MEMINFO_VARS] = {};
  socklen_t len = sizeof(info);
  if (getsockopt(fd_, SOL_SOCKET, SO_MEMINFO, info, &len) != 0 ||
      len <= static_cast<socklen_t>(SK_MEMINFO_DROPS * sizeof(info[0]))) {
    return 0;  // a kernel without it (before 4.6): not known
  }
  return info[SK_MEMINFO_DROPS];
}

bool UdpmReceiver::OnDatagram(const unsigned char* p, int size, const sockaddr_in& from,
                              const Handler& handler) {
  if (size < kShortHeader) {
    ++malformed_;
    return false;
  }
  const std::uint32_t magic = Be32(p);
  if (magic == kMagicLong) return OnFragment(p, size, from, handler);
  if (magic != kMagicShort) {
    ++malformed_;
    return false;
  }
  const unsigned char* ch = p + kShortHeader;
  const int len = ChannelLength(ch, size - kShortHeader);
  if (len < 0) {
    ++malformed_;
    return false;
  }
  const int offset = kShortHeader + len + 1;
  handler(std::string_view(reinterpret_cast<const char*>(ch), static_cast<std::size_t>(len)),
          p + offset, size - offset);
  return true;
}

void UdpmReceiver::DropPartial(std::map<std::uint64_t, Partial>::iterator it) {
  partial_bytes_ -= it->second.charged;
  partials_.erase(it);
}

bool UdpmReceiver::OnFragment(const unsigned char* p, int size, const sockaddr_in& from,
                              const Handler& handler) {
  if (size < kLongHeader) {
    ++malformed_;
    return false;
  }
  const std::uint32_t seqno = Be32(p + 4);
  const std::uint32_t msg_size = Be32(p + 8);
  const std::uint32_t offset = Be32(p + 12);
  const std::uint16_t fragment = Be16(p + 16);
  const std::uint16_t fragments = Be16(p + 18);
  const unsigned char* data = p + kLongHeader;
  int n = size - kLongHeader;
  std::string_view channel;
  if (fragment == 0) {
    const int len = ChannelLength(data, n);
    if (len < 0) {
      ++malformed_;
      return false;
    }
    channel = std::string_view(reinterpret_cast<const char*>(data), static_cast<std::size_t>(len));
    data += len + 1;
    n -= len + 1;
  }
  if (fragments == 0 || fragment >= fragments || msg_size > kMaxMessageBytes ||
      offset > msg_size || static_cast<std::uint32_t>(n) > msg_size - offset) {
    ++malformed_;
    return false;
  }
  const std::uint64_t key = (std::uint64_t{ntohl(from.sin_addr.s_addr)} << 16) | ntohs(from.sin_port);
  auto it = partials_.find(key);
  if (it != partials_.end() && (it->second.seqno != seqno || it->second.size != msg_size)) {
    DropPartial(it);  // what is left of an earlier message of that sender: it lost a fragment
    it = partials_.end();
  }
  if (it == partials_.end()) {
    if (partials_.size() >= kMaxPartials) DropPartial(partials_.begin());
    Partial fresh;
    fresh.seqno = seqno;
    fresh.size = msg_size;
    it = partials_.emplace(key, std::move(fresh)).first;
  }
  if (it->second.pieces.size() >= fragments ||
      !Keep(it, offset, data, static_cast<std::uint32_t>(n))) {
    ++malformed_;  // more fragments than it has, or over bytes another gave: not LCM's
    return false;
  }
  Partial& m = it->second;
  if (fragment == 0) {
    m.named = true;
    m.channel.assign(channel);
  }
  if (!m.named || m.bytes < m.size) return false;
  // The pieces do not overlap and their lengths add up to the size: they cover it.
  whole_.clear();
  for (const auto& piece : m.pieces) whole_.insert(whole_.end(), piece.second.begin(), piece.second.end());
  const bool named = !m.channel.empty();
  if (named) handler(m.channel, whole_.data(), static_cast<int>(whole_.size()));
  else ++malformed_;
  DropPartial(it);
  return named;
}

bool UdpmReceiver::Keep(std::map<std::uint64_t, Partial>::iterator it, std::uint32_t offset,
                        const unsigned char* data, std::uint32_t n) {
  if (n == 0) return true;
  Partial& m = it->second;
  const std::uint32_t end = offset + n;  // within m.size, so no overflow
  auto next = m.pieces.lower_bound(offset);
  if (next != m.pieces.end() && next->first < end) return false;
  if (next != m.pieces.begin()) {
    const auto before = std::prev(next);
    if (before->first + before->second.size() > offset) return false;
  }
  // Room for it among all the messages being put together: the others give way, in the
  // order of their senders' addresses.
  const std::size_t charge = n + kPieceOverhead;
  for (auto other = partials_.begin();
       partial_bytes_ + charge > kMaxPartialBytes && other != partials_.end();) {
    if (other == it) {
      ++other;
      continue;
    }
    const auto gone = other++;
    DropPartial(gone);
  }
  if (partial_bytes_ + charge > kMaxPartialBytes) return false;
  m.pieces.emplace_hint(next, offset, std::vector<unsigned char>(data, data + n));
  m.bytes += n;
  m.charged += charge;
  partial_bytes_ += charge;
  return true;
}

}  // namespace shoal
