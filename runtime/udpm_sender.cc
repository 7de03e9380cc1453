#include "runtime/udpm_sender.h"

#include <arpa/inet.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace shoal {

UdpmBatch::UdpmBatch() {
  // Touched now, so that its pages are resident from the start, locked or not.
  bytes_.resize(kMaxBatchBytes + kMaxDatagramBytes);
  bytes_.clear();
  kept_.reserve(kMaxBatchDatagrams);
  iov_.reserve(kMaxBatchDatagrams);
  msgs_.reserve(kMaxBatchDatagrams);
}

UdpmBatch::~UdpmBatch() {
  for (const auto& [ttl, fd] : fds_) close(fd);
}

int UdpmBatch::SocketFor(int ttl) {
  if (const auto it = fds_.find(ttl); it != fds_.end()) return it->second;
  // As LCM's udpm sender: the URL's TTL, multicast loop on (the default).
  const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return -1;
  const unsigned char t = static_cast<unsigned char>(ttl);
  if (setsockopt(fd, IPPROTO_IP, IP_MULTICAST_TTL, &t, sizeof(t)) != 0) {
    close(fd);
    return -1;
  }
  fds_[ttl] = fd;
  return fd;
}

bool UdpmBatch::Add(const UdpmAddress& to, std::string_view channel, const void* data, int size) {
  if (!active_ || size < 0 || (size > 0 && data == nullptr)) return false;
  const std::size_t bytes = 8 + channel.size() + 1 + static_cast<std::size_t>(size);
  if (bytes > static_cast<std::size_t>(kMaxDatagramBytes)) return false;
  const int fd = SocketFor(to.ttl);
  if (fd < 0) return false;
  if (kept_.size() >= kMaxBatchDatagrams || bytes_.size() + bytes > kMaxBatchBytes) {
    failed_ = !SendKept() || failed_;
  }
  Kept k{};
  k.to.sin_family = AF_INET;
  k.to.sin_addr = to.group;
  k.to.sin_port = htons(static_cast<std::uint16_t>(to.port));
  k.fd = fd;
  k.offset = bytes_.size();
  k.size = bytes;
  const std::uint32_t seq = seqno_++;
  const unsigned char header[8] = {'L', 'C', '0', '2', static_cast<unsigned char>(seq >> 24),
                                   static_cast<unsigned char>(seq >> 16),
                                   static_cast<unsigned char>(seq >> 8),
                                   static_cast<unsigned char>(seq)};
  bytes_.insert(bytes_.end(), header, header + 8);
  bytes_.insert(bytes_.end(), channel.begin(), channel.end());
  bytes_.push_back(0);
  const auto* in = static_cast<const unsigned char*>(data);
  if (size > 0) bytes_.insert(bytes_.end(), in, in + size);
  kept_.push_back(k);
  return true;
}

bool UdpmBatch::Flush() {
  active_ = false;
  const bool ok = SendKept() && !failed_;
  failed_ = false;
  return ok;
}

bool UdpmBatch::SendKept() {
  bool ok = true;
  iov_.resize(kept_.size());
  msgs_.resize(kept_.size());
  std::vector<iovec>& iov = iov_;
  std::vector<mmsghdr>& msgs = msgs_;
  // Runs of datagrams on one socket (one TTL) go in one call each, in order.
  for (std::size_t first = 0; first < kept_.size();) {
    std::size_t end = first;
    while (end < kept_.size() && kept_[end].fd == kept_[first].fd) {
      Kept& k = kept_[end];
      iov[end] = {bytes_.data() + k.offset, k.size};
      msgs[end] = {};
      msgs[end].msg_hdr.msg_name = &k.to;
      msgs[end].msg_hdr.msg_namelen = sizeof(k.to);
      msgs[end].msg_hdr.msg_iov = &iov[end];
      msgs[end].msg_hdr.msg_iovlen = 1;
      ++end;
    }
    for (std::size_t at = first; at < end;) {
      const int sent = sendmmsg(kept_[first].fd, msgs.data() + at,
                                static_cast<unsigned int>(end - at), 0);
      if (sent > 0) {
        at += static_cast<std::size_t>(sent);
      } else if (sent < 0 && errno == EINTR) {
        continue;
      } else {
        ok = false;  // this datagram could not go: the rest are still tried
        ++at;
      }
    }
    first = end;
  }
  kept_.clear();
  bytes_.clear();
  return ok;
}

}  // namespace shoal
