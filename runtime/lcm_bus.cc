#include "runtime/lcm_bus.h"

#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <cstdlib>
#include <random>
#include <stdexcept>

namespace shoal {

LcmBus::LcmBus(const std::string& url, std::optional<bus_auth::Key> key)
    : url_(url), lcm_(url) {
  if (key) auth_.emplace(*key);
  if (!lcm_.good()) {
    throw std::runtime_error("cannot open LCM at '" + url +
                             "' (for udpm on loopback, multicast must be routed to lo: "
                             "ip link set lo multicast on && ip route add 239.255.0.0/16 dev lo)");
  }
}

bool LcmBus::PublishRaw(const std::string& channel, const void* data, int size) {
  if (!auth_) return lcm_.publish(channel, data, static_cast<unsigned int>(size)) == 0;
  if (size < 0 || (size > 0 && data == nullptr)) return false;
  signed_.resize(static_cast<std::size_t>(size) + bus_auth::kTrailerBytes);
  if (size > 0) std::memcpy(signed_.data(), data, static_cast<std::size_t>(size));
  auth_->Sign(channel, data, size, signed_.data() + size);
  return lcm_.publish(channel, signed_.data(), static_cast<unsigned int>(signed_.size())) == 0;
}

void LcmBus::Sub::On(const lcm::ReceiveBuffer* rb, const std::string& channel) {
  const int size = static_cast<int>(rb->data_size);
  if (!auth->has_value()) {
    handler(channel, rb->data, size);
    return;
  }
  const int payload = (*auth)->Verify(channel, rb->data, size);
  if (payload < 0) {
    ++*rejected;  // forged, from another run, damaged, or without a trailer
    return;
  }
  handler(channel, rb->data, payload);
}

void LcmBus::Subscribe(const std::string& channel, Handler handler) {
  subs_.push_back(std::make_unique<Sub>(Sub{std::move(handler), &auth_, &rejected_}));
  lcm::Subscription* s = lcm_.subscribe(channel, &Sub::On, subs_.back().get());
  // Lockstep bursts (a tick's deliveries) must never be dropped by LCM's default
  // 30-message queue; real-time consumers read the newest anyway.
  if (s != nullptr) s->setQueueCapacity(10000);
}

int LcmBus::Handle(int timeout_ms) {
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

int RandomPrivatePort(int followers) {
  std::random_device rd;
  const int block = followers + 2;
  return 20000 + static_cast<int>(rd() % static_cast<unsigned>(40000 / block)) * block;
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
