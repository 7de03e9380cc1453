// Tests of runtime/udpm_receiver and udpm_sender: what LCM 1.3.1 publishes over udpm (a
// short message, a message of many fragments) arrives whole, in order, on the caller's
// thread; what is not an LCM datagram is dropped and counted, never handed on; one call
// hands on a bounded number of messages and leaves the rest in the socket; a batch sent in
// one system call reaches LCM's readers and this one as LCM's own messages.
#include "runtime/udpm_receiver.h"

#include <arpa/inet.h>
#include <lcm/lcm-cpp.hpp>
#include <netinet/in.h>
#include <pthread.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "runtime/clock.h"
#include "runtime/lcm_bus.h"
#include "runtime/udpm_sender.h"

namespace shoal {
namespace {

struct Message {
  std::string channel;
  std::vector<unsigned char> bytes;
};

class UdpmReceiverTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string err;
    ASSERT_TRUE(EnsureLoopbackMulticast(&err)) << err;
    port_ = RandomPrivatePort(2);  // the second for the batch test's other group
    url_ = PrivateLcmUrl(port_);
    ASSERT_TRUE(ParseUdpmUrl(url_, &address_));
    receiver_ = std::make_unique<UdpmReceiver>(address_);
    ASSERT_TRUE(receiver_->Open(&err)) << err;
  }
  // Everything that arrives within `wait_ms` of the last message.
  std::vector<Message> ReceiveAll(int wait_ms = 500) {
    std::vector<Message> got;
    while (receiver_->Receive(wait_ms, 1000, [&](std::string_view ch, const unsigned char* d, int n) {
      got.push_back({std::string(ch), std::vector<unsigned char>(d, d + n)});
    }) > 0) {
    }
    return got;
  }
  // Sends raw bytes to the group and port, as a foreign program could.
  void SendRaw(const std::vector<unsigned char>& bytes) {
    const int fd = socket(AF_INET, SOCK_DGRAM, 0);
    ASSERT_GE(fd, 0);
    const unsigned char ttl = 0;
    setsockopt(fd, IPPROTO_IP, IP_MULTICAST_TTL, &ttl, sizeof(ttl));
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_addr = address_.group;
    to.sin_port = htons(static_cast<std::uint16_t>(port_));
    ASSERT_EQ(sendto(fd, bytes.data(), bytes.size(), 0, reinterpret_cast<sockaddr*>(&to), sizeof(to)),
              static_cast<ssize_t>(bytes.size()));
    close(fd);
  }
  int port_ = 0;
  std::string url_;
  UdpmAddress address_;
  std::unique_ptr<UdpmReceiver> receiver_;
};

std::vector<unsigned char> Pattern(std::size_t n, unsigned seed) {
  std::vector<unsigned char> v(n);
  for (std::size_t k = 0; k < n; ++k) v[k] = static_cast<unsigned char>((k * 131 + seed) >> 3);
  return v;
}

// Given LCM publishing a short message, a message of 200 kB (four fragments) and another
// short one, when the receiver reads the bus, then it hands on the three, whole and in order.
TEST_F(UdpmReceiverTest, ShortAndFragmentedMessagesOfLcmArriveWholeInOrder) {
  lcm::LCM lcm(url_);
  ASSERT_TRUE(lcm.good());
  const auto a = Pattern(100, 1), big = Pattern(200000, 2), c = Pattern(0, 3);
  ASSERT_EQ(lcm.publish("SHORT_A", a.data(), static_cast<unsigned>(a.size())), 0);
  ASSERT_EQ(lcm.publish("LONG_B", big.data(), static_cast<unsigned>(big.size())), 0);
  ASSERT_EQ(lcm.publish("SHORT_C", c.data(), 0u), 0);
  const std::vector<Message> got = ReceiveAll();
  ASSERT_EQ(got.size(), 3u);
  EXPECT_EQ(got[0].channel, "SHORT_A");
  EXPECT_EQ(got[0].bytes, a);
  EXPECT_EQ(got[1].channel, "LONG_B");
  EXPECT_EQ(got[1].bytes, big);
  EXPECT_EQ(got[2].channel, "SHORT_C");
  EXPECT_TRUE(got[2].bytes.empty());
  EXPECT_EQ(receiver_->malformed(), 0);
  EXPECT_GE(receiver_->recv_buf_bytes(), UdpmReceiver::kDefaultRecvBufBytes / 2);
}

// Given a batch holding messages for two groups — this test's, read by the receiver, and
// another read by LCM's own reader — when it is flushed, then each arrives on its group
// whole and in the order added, as LCM's readers take it. A message the batch cannot
// hold (too long for one datagram, or added while it is not active) is refused, for the
// caller to send itself.
TEST_F(UdpmReceiverTest, ABatchReachesEachGroupAsLcmMessagesInOrder) {
  const int other_port = port_ + 1;
  const std::string other_url = PrivateLcmUrl(other_port);
  UdpmAddress other;
  ASSERT_TRUE(ParseUdpmUrl(other_url, &other));
  lcm::LCM reader(other_url);
  ASSERT_TRUE(reader.good());
  std::vector<Message> by_lcm;
  struct Keep {
    std::vector<Message>* into;
    void On(const lcm::ReceiveBuffer* rb, const std::string& ch) {
      const auto* d = static_cast<const unsigned char*>(rb->data);
      into->push_back({ch, std::vector<unsigned char>(d, d + rb->data_size)});
    }
  } keep{&by_lcm};
  reader.subscribe("OTHER_.*", &Keep::On, &keep);

  UdpmBatch batch;
  const auto a = Pattern(600, 1), b = Pattern(60000, 2), c = Pattern(0, 3);
  EXPECT_FALSE(batch.Add(address_, "EARLY", a.data(), 600));  // not active
  batch.Begin();
  ASSERT_TRUE(batch.Add(address_, "MINE_A", a.data(), static_cast<int>(a.size())));
  ASSERT_TRUE(batch.Add(other, "OTHER_B", b.data(), static_cast<int>(b.size())));
  ASSERT_TRUE(batch.Add(address_, "MINE_C", c.data(), 0));
  ASSERT_TRUE(batch.Add(other, "OTHER_A", a.data(), static_cast<int>(a.size())));
  const auto huge = Pattern(UdpmBatch::kMaxDatagramBytes, 4);
  EXPECT_FALSE(batch.Add(address_, "HUGE", huge.data(), static_cast<int>(huge.size())));
  ASSERT_TRUE(batch.Flush());
  EXPECT_FALSE(batch.active());

  const std::vector<Message> mine = ReceiveAll();
  ASSERT_EQ(mine.size(), 2u);
  EXPECT_EQ(mine[0].channel, "MINE_A");
  EXPECT_EQ(mine[0].bytes, a);
  EXPECT_EQ(mine[1].channel, "MINE_C");
  EXPECT_TRUE(mine[1].bytes.empty());
  EXPECT_EQ(receiver_->malformed(), 0);
  for (int i = 0; i < 20 && by_lcm.size() < 2; ++i) reader.handleTimeout(100);
  ASSERT_EQ(by_lcm.size(), 2u);
  EXPECT_EQ(by_lcm[0].channel, "OTHER_B");
  EXPECT_EQ(by_lcm[0].bytes, b);
  EXPECT_EQ(by_lcm[1].channel, "OTHER_A");
  EXPECT_EQ(by_lcm[1].bytes, a);
}

// Given datagrams that are not LCM's (too short, a wrong magic, a channel without its NUL
// or longer than 63 characters, fragments that do not fit their message or name no
// fragment count), when they arrive among good messages, then each is dropped and counted
// and the good ones arrive as sent.
TEST_F(UdpmReceiverTest, DatagramsThatAreNotLcmsAreDroppedAndCounted) {
  lcm::LCM lcm(url_);
  const unsigned char payload[3] = {7, 8, 9};
  std::vector<std::vector<unsigned char>> bad;
  bad.push_back({1, 2, 3});
  bad.push_back({'X', 'X', '0', '2', 0, 0, 0, 1, 'C', 0, 5});
  std::vector<unsigned char> no_nul = {'L', 'C', '0', '2', 0, 0, 0, 1};
  no_nul.insert(no_nul.end(), 80, 'c');
  bad.push_back(no_nul);
  std::vector<unsigned char> frag = {'L', 'C', '0', '3', 0, 0, 0, 9,  // seqno 9
                                     0, 0, 0, 4,                       // message of 4 bytes
                                     0, 0, 0, 2,                       // at offset 2
                                     0, 1, 0, 2,                       // fragment 1 of 2
                                     1, 2, 3};                         // 3 bytes: past the end
  bad.push_back(frag);
  frag[18] = 0, frag[19] = 0;  // fragment count 0
  bad.push_back(frag);
  ASSERT_EQ(lcm.publish("GOOD", payload, 3u), 0);
  for (const auto& b : bad) SendRaw(b);
  ASSERT_EQ(lcm.publish("GOOD", payload, 3u), 0);
  const std::vector<Message> got = ReceiveAll();
  ASSERT_EQ(got.size(), 2u);
  for (const Message& m : got) {
    EXPECT_EQ(m.channel, "GOOD");
    EXPECT_EQ(m.bytes, std::vector<unsigned char>(payload, payload + 3));
  }
  EXPECT_EQ(receiver_->malformed(), static_cast<std::int64_t>(bad.size()));
}

// An LC03 fragment: seqno 5, a message of `size` bytes, `n` bytes of `fill` at `offset`,
// fragment `no` of `count`; fragment 0 carries the channel "F".
std::vector<unsigned char> Fragment(std::uint32_t size, std::uint32_t offset, std::uint16_t no,
                                    std::uint16_t count, std::size_t n, unsigned char fill) {
  std::vector<unsigned char> d = {'L', 'C', '0', '3', 0, 0, 0, 5};
  for (std::uint32_t v : {size, offset}) {
    for (int s = 24; s >= 0; s -= 8) d.push_back(static_cast<unsigned char>(v >> s));
  }
  for (std::uint16_t v : {no, count}) {
    d.push_back(static_cast<unsigned char>(v >> 8));
    d.push_back(static_cast<unsigned char>(v));
  }
  if (no == 0) d.insert(d.end(), {'F', 0});
  d.insert(d.end(), n, fill);
  return d;
}

// Given the fragments of a message arriving out of order, then it is put together whole;
// given a fragment over bytes another fragment gave, then it is counted and the message,
// short of the bytes no fragment gave, is never handed on; given a header that declares
// 16 MB and nothing after it, then nothing is handed on; given more fragments than the
// header says the message has, then the extra ones are counted.
TEST_F(UdpmReceiverTest, FragmentsCompleteAMessageOnlyWhenTheyCoverEveryByteOnce) {
  sockaddr_in from{};
  from.sin_family = AF_INET;
  from.sin_port = htons(4000);
  std::vector<Message> got;
  const auto keep = [&](std::string_view ch, const unsigned char* d, int n) {
    got.push_back({std::string(ch), std::vector<unsigned char>(d, d + n)});
  };
  const auto feed = [&](const std::vector<unsigned char>& d) {
    return receiver_->OnDatagram(d.data(), static_cast<int>(d.size()), from, keep);
  };
  EXPECT_FALSE(feed(Fragment(30, 20, 2, 3, 10, 'c')));
  EXPECT_FALSE(feed(Fragment(30, 0, 0, 3, 10, 'a')));
  EXPECT_TRUE(feed(Fragment(30, 10, 1, 3, 10, 'b')));
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].channel, "F");
  EXPECT_EQ(std::string(got[0].bytes.begin(), got[0].bytes.end()),
            std::string(10, 'a') + std::string(10, 'b') + std::string(10, 'c'));
  EXPECT_EQ(receiver_->malformed(), 0);

  got.clear();
  EXPECT_FALSE(feed(Fragment(30, 0, 0, 3, 10, 'a')));
  EXPECT_FALSE(feed(Fragment(30, 5, 1, 3, 20, 'b')));   // over bytes 5..9 of fragment 0
  EXPECT_EQ(receiver_->malformed(), 1);
  EXPECT_FALSE(feed(Fragment(30, 20, 2, 3, 10, 'c')));  // bytes 10..19 never came
  EXPECT_FALSE(feed(Fragment(30, 20, 2, 3, 10, 'c')));  // nor does a repeat stand for them
  EXPECT_EQ(receiver_->malformed(), 2);
  EXPECT_FALSE(feed(Fragment(std::uint32_t{1} << 24, 0, 0, 300, 100, 'z')));
  EXPECT_TRUE(got.empty());

  // More pieces than the message has fragments: each one-byte fragment would cost far
  // more to keep than it brings.
  EXPECT_FALSE(feed(Fragment(100, 0, 0, 3, 1, 'a')));
  EXPECT_FALSE(feed(Fragment(100, 1, 1, 3, 1, 'b')));
  EXPECT_FALSE(feed(Fragment(100, 2, 2, 3, 1, 'c')));
  EXPECT_EQ(receiver_->malformed(), 2);
  EXPECT_FALSE(feed(Fragment(100, 3, 2, 3, 1, 'd')));
  EXPECT_EQ(receiver_->malformed(), 3);
  EXPECT_TRUE(got.empty());
}

// Given 50 messages waiting in the socket, when one call may hand on 10, then it hands on
// the first 10 and the next calls the rest, in order: nothing is read and then dropped.
TEST_F(UdpmReceiverTest, ACallHandsOnABoundedNumberAndTheRestFollowsInOrder) {
  lcm::LCM lcm(url_);
  for (int i = 0; i < 50; ++i) ASSERT_EQ(lcm.publish("N", &i, sizeof(i)), 0);
  usleep(100000);
  std::vector<int> seen;
  auto take = [&](std::string_view, const unsigned char* d, int n) {
    ASSERT_EQ(n, static_cast<int>(sizeof(int)));
    int v;
    std::memcpy(&v, d, sizeof(v));
    seen.push_back(v);
  };
  EXPECT_EQ(receiver_->Receive(0, 10, take), 10);
  EXPECT_EQ(seen.size(), 10u);
  while (receiver_->Receive(200, 10, take) > 0) {
  }
  ASSERT_EQ(seen.size(), 50u);
  for (int i = 0; i < 50; ++i) EXPECT_EQ(seen[static_cast<std::size_t>(i)], i);
}

// Given a receive buffer far too small for a burst, when the burst arrives before the
// process reads, then every datagram is either handed on or counted as dropped by the
// kernel: a lockstep run that stalls on a lost datagram can say where it was lost.
TEST_F(UdpmReceiverTest, DatagramsTheKernelDropsForAFullBufferAreCounted) {
  UdpmAddress small = address_;
  small.recv_buf_size = 4096;
  UdpmReceiver rx(small);
  std::string err;
  ASSERT_TRUE(rx.Open(&err)) << err;
  lcm::LCM lcm(url_);
  const std::vector<unsigned char> payload(1000, 7);
  constexpr int kSent = 100;
  for (int i = 0; i < kSent; ++i) {
    ASSERT_EQ(lcm.publish("BURST", payload.data(), static_cast<unsigned>(payload.size())), 0);
  }
  usleep(100000);
  int received = 0;
  while (rx.Receive(100, 1000, [&](std::string_view, const unsigned char*, int) { ++received; }) >
         0) {
  }
  EXPECT_GT(rx.overflowed(), 0);
  EXPECT_EQ(received + rx.overflowed(), kSent);
}

// Given nothing on the bus, when the receiver waits, then it returns 0 after about the
// time asked, and at once when asked not to wait.
TEST_F(UdpmReceiverTest, WaitsNoLongerThanAsked) {
  auto none = [](std::string_view, const unsigned char*, int) { FAIL(); };
  EXPECT_EQ(receiver_->Receive(0, 10, none), 0);
  EXPECT_EQ(receiver_->Receive(50, 10, none), 0);
}

// Given a receiver waiting for the bus, when a datagram arrives during the wait, then the
// wait ends with it (recvmmsg waits itself: no poll before it); and when a signal comes
// (Ctrl-C, without SA_RESTART, as StopSignals installs it), then the wait ends with
// nothing handed on, for the caller to look why.
TEST_F(UdpmReceiverTest, AWaitEndsWithTheFirstDatagramOrASignal) {
  using Clock = std::chrono::steady_clock;
  std::thread sender([this] {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    lcm::LCM lcm(url_);
    const int v = 7;
    lcm.publish("W", &v, sizeof(v));
  });
  int got = 0;
  auto start = Clock::now();
  EXPECT_EQ(receiver_->Receive(10000, 10, [&](std::string_view ch, const unsigned char*, int n) {
    EXPECT_EQ(ch, "W");
    EXPECT_EQ(n, static_cast<int>(sizeof(int)));
    ++got;
  }), 1);
  sender.join();
  EXPECT_EQ(got, 1);
  EXPECT_LT(Clock::now() - start, std::chrono::seconds(5));

  struct sigaction sa = {}, old = {};
  sa.sa_handler = [](int) {};
  ASSERT_EQ(sigaction(SIGUSR1, &sa, &old), 0);
  const pthread_t waiting = pthread_self();
  std::thread signaller([waiting] {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    pthread_kill(waiting, SIGUSR1);
  });
  start = Clock::now();
  EXPECT_EQ(receiver_->Receive(10000, 10, [](std::string_view, const unsigned char*, int) {
    FAIL();
  }), 0);
  EXPECT_LT(Clock::now() - start, std::chrono::seconds(5));
  signaller.join();
  sigaction(SIGUSR1, &old, nullptr);
}

// A real-time tick reads only what reached the host by its time: the receiver gives each
// message the kernel's receive time, on the clock the loops' deadlines use, and -1 when it
// was not asked to record them.
TEST_F(UdpmReceiverTest, RecordsWhenEachMessageReachedTheSocketOnTheMonotonicClock) {
  lcm::LCM lcm(url_);
  const int v = 7;
  ASSERT_EQ(lcm.publish("UNSTAMPED", &v, sizeof(v)), 0);
  std::vector<std::int64_t> unstamped;
  while (receiver_->Receive(500, 1000, [&](std::string_view, const unsigned char*, int) {
    unstamped.push_back(receiver_->arrival_ns());
  }) > 0) {
  }
  ASSERT_EQ(unstamped, std::vector<std::int64_t>{-1});

  ASSERT_TRUE(receiver_->RecordArrivals());
  // The kernel turns its receive stamps on a moment later (a deferred work item); until
  // then a datagram is stamped when read. A process asks at start, long before its run.
  usleep(100000);
  const std::int64_t before = MonotonicNs();
  ASSERT_EQ(lcm.publish("FIRST", &v, sizeof(v)), 0);
  const std::int64_t between0 = MonotonicNs();
  usleep(30000);
  const std::int64_t between1 = MonotonicNs();
  ASSERT_EQ(lcm.publish("SECOND", &v, sizeof(v)), 0);
  const std::int64_t after = MonotonicNs();
  usleep(30000);  // read well after both arrived: the times are the arrivals, not the read
  std::vector<std::pair<std::string, std::int64_t>> got;
  while (receiver_->Receive(500, 1000, [&](std::string_view ch, const unsigned char*, int) {
    got.emplace_back(std::string(ch), receiver_->arrival_ns());
  }) > 0) {
  }
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[0].first, "FIRST");
  EXPECT_EQ(got[1].first, "SECOND");
  // A margin for the wall and monotonic clocks read one after the other.
  constexpr std::int64_t kSlackNs = 200000;
  EXPECT_GE(got[0].second, before - kSlackNs);
  EXPECT_LE(got[0].second, between0 + kSlackNs);
  EXPECT_GE(got[1].second, between1 - kSlackNs);
  EXPECT_LE(got[1].second, after + kSlackNs);
  EXPECT_EQ(receiver_->arrival_ns(), -1);  // outside a handler
}

// Given the URLs Shoal and LCM users write, when parsed, then group, port and receive
// buffer are LCM's reading of them (its defaults where left out); other providers and
// malformed URLs are refused.
TEST(UdpmUrl, ParsedAsLcmReadsIt) {
  UdpmAddress a;
  ASSERT_TRUE(ParseUdpmUrl("udpm://239.255.77.20:10001?ttl=0&recv_buf_size=4194304", &a));
  EXPECT_EQ(a.port, 10001);
  EXPECT_EQ(a.recv_buf_size, 4194304);
  EXPECT_EQ(ntohl(a.group.s_addr), (239u << 24) | (255u << 16) | (77u << 8) | 20u);
  ASSERT_TRUE(ParseUdpmUrl("udpm://", &a));
  EXPECT_EQ(a.port, 7667);
  EXPECT_EQ(a.recv_buf_size, 0);
  EXPECT_EQ(a.ttl, 0);
  ASSERT_TRUE(ParseUdpmUrl("udpm://239.255.76.67:7667?ttl=1", &a));
  EXPECT_EQ(a.ttl, 1);
  EXPECT_FALSE(ParseUdpmUrl("udpm://239.255.76.67:7667?ttl=256", &a));
  EXPECT_FALSE(ParseUdpmUrl("memq://", &a));
  EXPECT_FALSE(ParseUdpmUrl("udpm://239.255.76.67:notaport", &a));
  EXPECT_FALSE(ParseUdpmUrl("udpm://239.255.76.67:70000", &a));
  EXPECT_FALSE(ParseUdpmUrl("udpm://nowhere:7667", &a));
  EXPECT_FALSE(ParseUdpmUrl("udpm://239.255.76.67:7667?recv_buf_size=lots", &a));
}

}  // namespace
}  // namespace shoal
