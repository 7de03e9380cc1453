#include "runtime/lcm_bus.h"

#include <stdexcept>

namespace shoal {

LcmBus::LcmBus(const std::string& url) : url_(url), lcm_(url) {
  if (!lcm_.good()) {
    throw std::runtime_error("cannot open LCM at '" + url +
                             "' (for udpm on loopback, multicast must be routed to lo: "
                             "ip link set lo multicast on && ip route add 239.255.0.0/16 dev lo)");
  }
}

bool LcmBus::PublishRaw(const std::string& channel, const void* data, int size) {
  return lcm_.publish(channel, data, static_cast<unsigned int>(size)) == 0;
}

void LcmBus::Subscribe(const std::string& channel, Handler handler) {
  subs_.push_back(std::make_unique<Sub>(Sub{std::move(handler)}));
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
    r = lcm_.handleTimeout(0);
  }
  return r < 0 ? -1 : n;
}

std::string PrivateLcmUrl(int port, const std::string& group) {
  return "udpm://" + group + ":" + std::to_string(port) + "?ttl=0";
}

}  // namespace shoal
