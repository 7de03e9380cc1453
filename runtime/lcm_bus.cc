#include "runtime/lcm_bus.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>

#include <cstdio>
#include <cstring>
#include <cstdlib>
#include <random>
#include <stdexcept>

namespace shoal {

LcmBus::LcmBus(const std::string& url, std::optional<bus_auth::Key> key, Receiving receiving)
    : url_(url), lcm_(url) {
  if (key) auth_.emplace(*key);
  UdpmAddress address;
  if (receiving == Receiving::kInCaller && ParseUdpmUrl(url, &address)) {
    receiver_ = std::make_unique<UdpmReceiver>(address);
  }
  if (!lcm_.good()) {
    throw std::runtime_error("cannot open LCM at '" + url +
                             "' (udpm needs a route for the group: on one machine, through "
                             "loopback: ip link set lo multicast on && ip route add "
                             "239.255.0.0/16 dev lo; across hosts, through the interface of "
                             "the network they share: ip route add 224.0.0.0/4 dev <interface>)");
  }
}

bool LcmBus::PublishRaw(const std::string& channel, const void* data, int size) {
  if (!bundling_ || size < 0 || channel.empty() ||
      channel.size() > static_cast<std::size_t>(bundle_wire::kMaxChannel)) {
    return PublishSigned(channel, data, size);
  }
  if (size > 0 && data == nullptr) return false;
  // A recordable bundle's part is the message as it would go out alone: with its trailer.
  return AppendPart(channel, data, size, recordable_ && auth_ ? bus_auth::kTrailerBytes : 0);
}

bool LcmBus::PublishAsReceived(const std::string& channel, const void* data, int size) {
  if (size < 0 || (size > 0 && data == nullptr)) return false;
  if (bundling_ && recordable_ && !channel.empty() &&
      channel.size() <= static_cast<std::size_t>(bundle_wire::kMaxChannel)) {
    return AppendPart(channel, data, size, 0);
  }
  return Send(channel, data, size);
}

bool LcmBus::Send(const std::string& channel, const void* data, int size) {
  if (batch_ != nullptr && batch_->Add(address_, channel, data, size)) {
    ++sent_;
    return true;
  }
  const bool ok = lcm_.publish(channel, data, static_cast<unsigned int>(size)) == 0;
  sent_ += ok;
  return ok;
}

void LcmBus::SendThrough(UdpmBatch* batch) {
  batch_ = ParseUdpmUrl(url_, &address_) ? batch : nullptr;
}

bool LcmBus::AppendPart(const std::string& channel, const void* data, int size, int trailer) {
  const std::size_t bytes = static_cast<std::size_t>(size) + static_cast<std::size_t>(trailer);
  const std::size_t part = 1 + channel.size() + 4 + bytes;
  bool ok = true;
  if (bundle_parts_ > 0 && bundle_.size() + part > bundle_wire::kMaxBytes) ok = FlushBundle();
  bundle_.push_back(static_cast<unsigned char>(channel.size()));
  bundle_.insert(bundle_.end(), channel.begin(), channel.end());
  for (int shift = 24; shift >= 0; shift -= 8) {
    bundle_.push_back(static_cast<unsigned char>(static_cast<std::uint32_t>(bytes) >> shift));
  }
  const auto* in = static_cast<const unsigned char*>(data);
  if (size > 0) bundle_.insert(bundle_.end(), in, in + size);
  if (trailer > 0) {
    bundle_.resize(bundle_.size() + static_cast<std::size_t>(trailer));
    auth_->Sign(channel, data, size, bundle_.data() + bundle_.size() - trailer);
  }
  ++bundle_parts_;
  return ok;
}

void LcmBus::PrepareBundles() {
  const std::size_t signed_max = static_cast<std::size_t>(bundle_wire::kMaxBytes) +
                                 bus_auth::kTrailerBytes;
  if (bundle_.capacity() >= signed_max) return;
  // The largest bundle's buffers, written once: as windows grow with the channel's delay,
  // buffers that grew with them would show as memory growth late in a long run (a soak's
  // verdict), though nothing leaks. A bundle is signed in place (PublishBundleSigned).
  bundle_.assign(signed_max, 0);
  signed_.assign(static_cast<std::size_t>(bundle_wire::kMaxBytes) + bus_auth::kTrailerBytes, 0);
}

void LcmBus::BeginBundle(bool recordable) {
  // Nested: receivers that share one bus each open a bundle on it; what they queued goes
  // out together when the outermost closes, none of it dropped by a later Begin.
  if (bundle_depth_++ > 0) return;
  recordable_ = recordable;
  PrepareBundles();
  bundling_ = true;
  bundle_parts_ = 0;
  if (recordable) {
    bundle_.assign(std::begin(bundle_wire::kMagicRecordable),
                   std::end(bundle_wire::kMagicRecordable));
  } else {
    bundle_.assign(std::begin(bundle_wire::kMagic), std::end(bundle_wire::kMagic));
  }
}

bool LcmBus::EndBundle() {
  if (bundle_depth_ == 0) return true;
  if (--bundle_depth_ > 0) return true;
  const bool ok = FlushBundle();
  bundling_ = false;
  return ok;
}

bool LcmBus::FlushBundle() {
  bool ok = true;
  if (bundle_parts_ == 1) {  // alone: as it is, no bundle around it
    bundle_wire::ForEachPart(bundle_.data(), static_cast<int>(bundle_.size()),
                             [&](std::string_view ch, const unsigned char* d, int n) {
                               const std::string name(ch);
                               // A recordable part is signed already.
                               ok = recordable_ ? Send(name, d, n) : PublishSigned(name, d, n);
                             });
  } else if (bundle_parts_ > 1 && recordable_) {
    ok = Send(bundle_wire::kChannel, bundle_.data(), static_cast<int>(bundle_.size()));
  } else if (bundle_parts_ > 1) {
    ok = PublishBundleSigned();
  }
  bundle_parts_ = 0;
  bundle_.resize(sizeof(bundle_wire::kMagic));
  return ok;
}

bool LcmBus::PublishSigned(const std::string& channel, const void* data, int size) {
  if (!auth_) return Send(channel, data, size);
  if (size < 0 || (size > 0 && data == nullptr)) return false;
  signed_.resize(static_cast<std::size_t>(size) + bus_auth::kTrailerBytes);
  if (size > 0) std::memcpy(signed_.data(), data, static_cast<std::size_t>(size));
  auth_->Sign(channel, data, size, signed_.data() + size);
  return Send(channel, signed_.data(), static_cast<int>(signed_.size()));
}

bool LcmBus::PublishBundleSigned() {
  const std::size_t size = bundle_.size();
  if (!auth_) return Send(bundle_wire::kChannel, bundle_.data(), static_cast<int>(size));
  bundle_.resize(size + bus_auth::kTrailerBytes);  // within its capacity: no copy
  auth_->Sign(bundle_wire::kChannel, bundle_.data(), static_cast<int>(size),
              bundle_.data() + size);
  return Send(bundle_wire::kChannel, bundle_.data(), static_cast<int>(bundle_.size()));
}

void LcmBus::Sub::On(const lcm::ReceiveBuffer* rb, const std::string& channel) {
  if (channel == bundle_wire::kChannel) return;  // its parts come through OnBundle
  Deliver(channel, rb->data, static_cast<int>(rb->data_size));
}

void LcmBus::Sub::Deliver(const std::string& channel, const void* data, int size) {
  if (!auth->has_value()) {
    handler(channel, data, size);
    return;
  }
  const int payload = (*auth)->Verify(channel, data, size);
  if (payload < 0) {
    ++*rejected;  // forged, from another run, damaged, or without a trailer
    return;
  }
  handler(channel, data, as_received ? size : payload);
}

void LcmBus::Dispatch(std::string_view channel, const unsigned char* data, int size) {
  if (channel == bundle_wire::kChannel) {
    OnBundleBytes(channel, data, size);
    return;
  }
  const std::vector<Sub*>& subs = SubsFor(channel);
  if (subs.empty()) return;  // LCM drops what no subscription matches, uncounted
  const std::string name(channel);
  const unsigned char* bytes = size > 0 ? data : nullptr;
  if (!auth_) {
    for (Sub* sub : subs) sub->handler(name, bytes, size);
    return;
  }
  // Verified once, whichever subscriptions match: a forgery is one rejected datagram.
  const int payload = auth_->Verify(name, bytes, size);
  if (payload < 0) {
    ++rejected_;
    return;
  }
  for (Sub* sub : subs) {
    const int n = sub->as_received ? size : payload;
    sub->handler(name, n > 0 ? bytes : nullptr, n);
  }
}

void LcmBus::Subscribe(const std::string& channel, Handler handler) {
  AddSubscription(channel, std::move(handler), false);
}

void LcmBus::SubscribeAsReceived(const std::string& channel, Handler handler) {
  AddSubscription(channel, std::move(handler), true);
}

void LcmBus::AddSubscription(const std::string& channel, Handler handler, bool as_received) {
  std::string error;
  if (receiver_ && !receiver_->Open(&error)) {
    throw std::runtime_error("cannot receive on LCM URL '" + url_ + "': " + error);
  }
  // LCM opens its receive socket here. If it cannot (the port is held by a socket bound
  // without SO_REUSEADDR), LCM 1.3.1 returns a subscription without its C half (setting
  // its queue then crashes) and later passes descriptor -1 to select() in handleTimeout,
  // which glibc aborts on. Say it plainly instead.
  if (!receiver_ && lcm_.getFileno() < 0) {
    throw std::runtime_error("cannot receive on LCM URL '" + url_ +
                             "': its port is in use by a program that does not share it "
                             "(the \"bind\" line above)");
  }
  // LCM matches a pattern as ^pattern$; so does regex_match.
  std::optional<std::regex> pattern;
  if (channel.find_first_of(".[]()*+?{}|^$\\") != std::string::npos) {
    pattern.emplace(channel, std::regex::extended);
  }
  routes_.clear();  // a bundle's parts may match the new subscription too
  subs_.push_back(std::make_unique<Sub>(
      Sub{std::move(handler), &auth_, &rejected_, channel, std::move(pattern), as_received}));
  if (receiver_) {
    receiving_ = true;
    return;
  }
  lcm::Subscription* s = lcm_.subscribe(channel, &Sub::On, subs_.back().get());
  // Lockstep bursts (a tick's deliveries) must never be dropped by LCM's default
  // 30-message queue; real-time consumers read the newest anyway.
  if (s != nullptr) s->setQueueCapacity(10000);
  if (!receiving_) {
    lcm::Subscription* b = lcm_.subscribe(bundle_wire::kChannel, &LcmBus::OnBundle, this);
    if (b != nullptr) b->setQueueCapacity(10000);
  }
  receiving_ = true;
}

void LcmBus::OnBundle(const lcm::ReceiveBuffer* rb, const std::string& channel) {
  OnBundleBytes(channel, static_cast<const unsigned char*>(rb->data),
                static_cast<int>(rb->data_size));
}

void LcmBus::OnBundleBytes(std::string_view channel, const unsigned char* p, int size) {
  const bool recordable = bundle_wire::Recordable(p, size);
  if (auth_ && !recordable) size = auth_->Verify(channel, p, size);
  bool ok = size >= 0;
  if (ok && recordable && auth_) {
    // Each part verified as the message it would be alone; the bundle is taken entire or
    // not at all.
    ok = bundle_wire::ForEachPart(p, size, [&](std::string_view ch, const unsigned char* d, int n) {
      ok = ok && auth_->Verify(ch, d, n) >= 0;
    }) && ok;
  }
  ok = ok && bundle_wire::ForEachPart(p, size, [&](std::string_view ch, const unsigned char* d, int n) {
    // Verified above; the trailer goes only to those who pass the part on as it came.
    const int payload = recordable && auth_ ? n - bus_auth::TrailerBytes(d, n) : n;
    for (Sub* sub : SubsFor(ch)) {
      if (sub->as_received && auth_ && !recordable) {
        // A part of a bundle signed whole has no trailer of its own: it is handed on as
        // it would have come alone, signed (the same bytes its sender's bus would sign).
        static thread_local std::vector<unsigned char> alone;
        alone.assign(d, d + n);
        alone.resize(static_cast<std::size_t>(n) + bus_auth::kTrailerBytes);
        auth_->Sign(ch, d, n, alone.data() + n);
        sub->handler(std::string(ch), alone.data(), static_cast<int>(alone.size()));
        continue;
      }
      const int size = sub->as_received ? n : payload;
      sub->handler(std::string(ch), size > 0 ? d : nullptr, size);
    }
  });
  if (!ok) ++rejected_;  // forged, damaged, or not a bundle
}

const std::vector<LcmBus::Sub*>& LcmBus::SubsFor(std::string_view channel) {
  auto found = routes_.find(channel);
  if (found != routes_.end()) return found->second;
  // Bounded: a flood of forged bundles naming ever new channels must not grow it.
  if (routes_.size() >= 4096) routes_.clear();
  std::vector<Sub*>& subs = routes_[std::string(channel)];
  for (const std::unique_ptr<Sub>& sub : subs_) {
    if (sub->Matches(channel)) subs.push_back(sub.get());
  }
  return subs;
}

namespace bundle_wire {
bool Recordable(const unsigned char* p, int size) {
  return p != nullptr && size >= static_cast<int>(sizeof(kMagicRecordable)) &&
         std::memcmp(p, kMagicRecordable, sizeof(kMagicRecordable)) == 0;
}

bool ForEachPart(const unsigned char* p, int size,
                 const std::function<void(std::string_view, const unsigned char*, int)>& part) {
  const int magic = static_cast<int>(sizeof(kMagic));
  if (p == nullptr || size < magic ||
      (std::memcmp(p, kMagic, sizeof(kMagic)) != 0 && !Recordable(p, size))) {
    return false;
  }
  // Checked whole before any part is handed on: a bundle is taken entire or not at all.
  for (int pass = 0; pass < 2; ++pass) {
    for (int pos = magic; pos < size;) {
      const int len = p[pos];
      if (len < 1 || len > kMaxChannel || size - pos - 1 < len + 4) return false;
      // A bundle inside a bundle is never sent: its parts would bypass the subscribers'
      // exclusion of the bundle channel.
      if (static_cast<std::size_t>(len) == std::strlen(kChannel) &&
          std::memcmp(p + pos + 1, kChannel, static_cast<std::size_t>(len)) == 0) {
        return false;
      }
      const unsigned char* n = p + pos + 1 + len;
      const std::uint32_t bytes = (std::uint32_t{n[0]} << 24) | (std::uint32_t{n[1]} << 16) |
                                  (std::uint32_t{n[2]} << 8) | std::uint32_t{n[3]};
      if (bytes > static_cast<std::uint32_t>(size - pos - 1 - len - 4)) return false;
      if (pass == 1) {
        part(std::string_view(reinterpret_cast<const char*>(p + pos + 1),
                              static_cast<std::size_t>(len)),
             n + 4, static_cast<int>(bytes));
      }
      pos += 1 + len + 4 + static_cast<int>(bytes);
    }
  }
  return true;
}
}  // namespace bundle_wire

int LcmBus::Handle(int timeout_ms) {
  if (!receiving_) {
    // Nothing subscribed: LCM would open a receive socket and thread for nothing (and
    // abort if it could not). Wait as asked, then report nothing handled.
    if (timeout_ms > 0) usleep(static_cast<useconds_t>(timeout_ms) * 1000);
    return 0;
  }
  if (receiver_) {
    return receiver_->Receive(timeout_ms, kMaxMessagesPerHandle,
                              [this](std::string_view ch, const unsigned char* d, int size) {
                                Dispatch(ch, d, size);
                              });
  }
  int n = 0;
  int r = lcm_.handleTimeout(timeout_ms);
  while (r > 0) {  // drain whatever else is already queued, without waiting
    ++n;
    if (n >= kMaxMessagesPerHandle) break;
    r = lcm_.handleTimeout(0);
  }
  return r < 0 ? -1 : n;
}

std::string PrivateLcmUrl(int port, const std::string& group) {
  return "udpm://" + group + ":" + std::to_string(port) + "?ttl=0";
}

namespace {

// The first port the kernel hands out to sockets that send without binding (their
// "ephemeral" port, bound without SO_REUSEADDR): a run's receive port in that range can be
// taken by any sender on the host, and LCM then cannot bind it.
int EphemeralPortLow() {
  int low = 32768, high = 60999;
  if (FILE* f = std::fopen("/proc/sys/net/ipv4/ip_local_port_range", "r")) {
    if (std::fscanf(f, "%d %d", &low, &high) != 2) low = 32768;
    std::fclose(f);
  }
  return std::max(kPrivatePortLow + 1, std::min(low, 65536));
}

// True if nobody holds `port` for UDP: a bind without SO_REUSEADDR fails if any socket
// has it, shared (another run's LCM receive socket) or not.
bool UdpPortFree(int port) {
  const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return true;  // cannot tell: let LCM try (and say so if it fails)
  sockaddr_in a {};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_ANY);
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  const bool free_port = bind(fd, reinterpret_cast<const sockaddr*>(&a), sizeof(a)) == 0;
  close(fd);
  return free_port;
}

}  // namespace

int RandomPrivatePort(int followers) {
  std::random_device rd;
  const int block = followers + 3;
  const int blocks = std::max(1, (EphemeralPortLow() - kPrivatePortLow) / block);
  int port = kPrivatePortLow;
  for (int attempt = 0; attempt < 64; ++attempt) {
    port = kPrivatePortLow + static_cast<int>(rd() % static_cast<unsigned>(blocks)) * block;
    bool all_free = true;
    for (int p = port; p < port + block && all_free; ++p) all_free = UdpPortFree(p);
    if (all_free) return port;
  }
  return port;  // every block tried was taken: the processes will say which port
}

std::vector<std::string> PerVehicleLcmUrls(int port, int followers) {
  std::vector<std::string> urls;
  for (int id = 0; id <= followers; ++id) {
    urls.push_back("udpm://239.255." + std::to_string(77 + id / 200) + "." +
                   std::to_string(20 + id % 200) + ":" + std::to_string(port + 1 + id) +
                   "?ttl=0&recv_buf_size=4194304");
  }
  return urls;
}

std::string UplinkLcmUrl(int port, int followers) {
  return "udpm://239.255.76.68:" + std::to_string(port + followers + 2) +
         "?ttl=0&recv_buf_size=4194304";
}

/// Makes sure multicast on the private group stays on loopback.
bool EnsureLoopbackMulticast(std::string* err) {
  FILE* p = popen("ip route get 239.255.76.67 2>/dev/null", "r");
  std::string out;
  if (p) {
    char buf[512];
    while (fgets(buf, sizeof(buf), p)) out += buf;
    pclose(p);
  }
  if (out.find(" dev lo") != std::string::npos) return true;
  const char* fix = "ip link set lo multicast on && ip route add 239.255.0.0/16 dev lo";
  if (geteuid() == 0) {
    if (std::system((std::string(fix) + " 2>/dev/null").c_str()) == 0) return true;
    *err = std::string("could not route multicast to loopback; run: ") + fix;
    return false;
  }
  *err = std::string("multicast is not routed to the loopback interface, so a run could "
                     "reach the network; as root run:\n  sudo sh -c '") + fix + "'";
  return false;
}

}  // namespace shoal
