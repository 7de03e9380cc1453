// What one wake-up costs this machine as the number of processes taking turns on its CPUs
// grows: N processes in a ring of pipes pass a token around, each blocking in read() until
// its turn, as N vehicles each block until their lockstep window comes (docs/benchmarks.md,
// "shoal run at scale"). Each process touches `touch_kb` of its own memory per turn (a
// vehicle's working set per window), so that the caches and TLBs see what a run's
// processes do. Each touched byte is one per STRIDE bytes: 64 touches every cache line of
// TOUCH_KB; 4096 touches one line in each of its pages, so that a turn costs TLB misses
// (a page walk each, after every switch on a CPU without PCID) rather than cache misses;
// 2097152 touches one line in each of TOUCH_KB / 2048 pages that lie 2 MiB apart, each
// with a page-table page of its own, as the pages of a process's code, libraries, heap
// and stack lie apart. STRIDE "chase" reads every line of TOUCH_KB in a random order, each
// read's address taken from the line before (as a process follows its pointers from one
// heap structure to the next), so that no prefetcher can fetch a line ahead: a vehicle's
// window, whose lines lie scattered over its heap, against the same lines read in order.
// STREAM_KB: member 0 also writes every line of STREAM_KB * (N - 1) KiB of its own memory once
// a round, as the channel emulator and the logger go through every follower's messages
// once a lockstep window, between two turns of each vehicle: what the others' turns then
// cost shows what that pushes out of the caches.
// PAUSE_US: member 0 also sleeps PAUSE_US once a round before passing the token on, so
// that the time between two turns of each member grows by that much with nothing else
// touched in it, as a vehicle's turns lie further apart in a larger swarm (a window of 128
// followers lasts about ten times one of 16). Given (0 too, for the figure to compare
// with), the ring holds a 0 us CPU-latency request (/dev/cpu_dma_latency, as shoal run does
// as root), so the idle CPUs poll through the pause as they do in a run.
// Prints, per N, the CPU time (user + system of all N; with STREAM_KB or PAUSE_US given, of
// the N - 1 others only) per hop and the wall time per hop (member 0's traffic and pause
// included), medians over `rounds` measurements.
// Usage:
//   wakeup_ring [NS] [HOPS] [TOUCH_KB] [ROUNDS] [STRIDE] [SHARED_KB] [STREAM_KB] [PAUSE_US],
//   e.g. wakeup_ring "2 8 32 64 128" 200000 16 5; wakeup_ring "4 128" 100000 400 3 4096;
//   wakeup_ring "8 131" 100000 204800 3 2097152 (100 pages 2 MiB apart);
//   wakeup_ring "8 131" 100000 21 5 chase (336 lines in a random order);
//   taskset -c 0 wakeup_ring "9 34 66" 100000 21 3 64 43 18 (vehicles' turns on one CPU,
//   with 18 kB a vehicle of others' traffic between them);
//   wakeup_ring "9" 20000 21 3 chase 43 0 3000 (a member's turns 3 ms further apart)
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <sstream>
#include <memory>
#include <string>
#include <vector>

namespace {

struct Result {
  double cpu_us_per_hop;
  double wall_us_per_hop;
};

// A process's memory: calloc takes a large block straight from the kernel, whose pages
// read as zero and cost nothing until touched, so that a sparse STRIDE (one byte every
// 2 MiB: a page-table page of its own for each touched page) holds only the pages it
// touches.
using Memory = std::unique_ptr<unsigned char[], void (*)(void*)>;
Memory Zeroed(std::size_t bytes) {
  auto* p = static_cast<unsigned char*>(std::calloc(std::max<std::size_t>(bytes, 1), 1));
  if (p == nullptr) {
    std::fprintf(stderr, "wakeup_ring: cannot allocate %zu bytes\n", bytes);
    std::exit(2);
  }
  return Memory(p, &std::free);
}

// SHARED_KB: memory every process of the ring reads, one byte per line, on every turn, as
// every vehicle runs the same code (its pages shared): allocated and written before the
// ring forks, so its pages are the same physical pages in every process.
const unsigned char* g_shared = nullptr;
std::size_t g_shared_bytes = 0;
unsigned g_sink = 0;

void ReadShared() {
  unsigned sum = 0;
  for (std::size_t k = 0; k < g_shared_bytes; k += 64) sum += g_shared[k];
  g_sink += sum;
}

constexpr std::size_t kChase = 0;  // STRIDE "chase"
constexpr std::size_t kLine = 64;

// A process's memory and what it touches of it per turn.
class Working {
 public:
  Working(std::size_t touch, std::size_t stride)
      : mem_(Zeroed(touch)), touch_(touch), stride_(stride) {
    if (stride_ != kChase || touch_ < kLine) return;
    // Each line holds the offset of the next in one random cycle through all of them.
    std::vector<std::size_t> order(touch_ / kLine);
    for (std::size_t k = 0; k < order.size(); ++k) order[k] = k * kLine;
    std::srand(static_cast<unsigned>(getpid()));
    for (std::size_t k = order.size() - 1; k > 0; --k) {
      std::swap(order[k], order[static_cast<std::size_t>(std::rand()) % (k + 1)]);
    }
    for (std::size_t k = 0; k < order.size(); ++k) {
      const std::size_t next = order[(k + 1) % order.size()];
      std::memcpy(&mem_[order[k]], &next, sizeof(next));
    }
  }
  void Turn() {
    if (stride_ != kChase) {
      for (std::size_t k = 0; k < touch_; k += stride_)
        mem_[k] = static_cast<unsigned char>(mem_[k] + 1);
      return;
    }
    std::size_t at = 0;
    for (std::size_t k = 0; k < touch_ / kLine; ++k) {
      mem_[at + sizeof(at)] = static_cast<unsigned char>(mem_[at + sizeof(at)] + 1);
      std::memcpy(&at, &mem_[at], sizeof(at));
    }
  }

 private:
  Memory mem_;
  std::size_t touch_, stride_;
};

// One process of the ring: reads the token from `in`, touches its memory, passes it on,
// until the token says stop (a negative count).
[[noreturn]] void Member(int in, int out, std::size_t touch, std::size_t stride) {
  Working mine(touch, stride);
  long token = 0;
  for (;;) {
    if (read(in, &token, sizeof(token)) != sizeof(token)) _exit(1);
    mine.Turn();
    ReadShared();
    if (token < 0) {
      (void)!write(out, &token, sizeof(token));
      _exit(0);
    }
    ++token;
    if (write(out, &token, sizeof(token)) != sizeof(token)) _exit(1);
  }
}

double ChildrenCpuSeconds() {
  rusage ru{};
  getrusage(RUSAGE_CHILDREN, &ru);
  return static_cast<double>(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
         static_cast<double>(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec) * 1e-6;
}

// pause_us < 0: no pause, and the CPU figure is of all N unless there is traffic.
Result Ring(int n, long hops, std::size_t touch, std::size_t stride, std::size_t stream_kb,
            long pause_us) {
  std::vector<int> rd(static_cast<std::size_t>(n)), wr(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    int p[2];
    if (pipe(p) != 0) std::exit(2);
    rd[static_cast<std::size_t>(i)] = p[0];
    wr[static_cast<std::size_t>(i)] = p[1];
  }
  // Member i reads pipe i and writes pipe (i + 1) % n. This process is member 0 (it reads
  // pipe 0, writes pipe 1 and counts the rounds).
  for (int i = 1; i < n; ++i) {
    if (fork() == 0)
      Member(rd[static_cast<std::size_t>(i)], wr[static_cast<std::size_t>((i + 1) % n)], touch,
             stride);
  }
  const double cpu0 = ChildrenCpuSeconds();
  rusage self0{};
  getrusage(RUSAGE_SELF, &self0);
  const auto t0 = std::chrono::steady_clock::now();
  Working mine(touch, stride);
  Working traffic(stream_kb * 1024 * static_cast<std::size_t>(n - 1), kLine);
  long token = 0;
  const int out = wr[static_cast<std::size_t>(1 % n)], in = rd[0];
  const long sleep_us = std::max(pause_us, 0L);
  const timespec pause{sleep_us / 1000000, sleep_us % 1000000 * 1000};
  for (long h = 0; h < hops; h += n) {
    if (sleep_us > 0) nanosleep(&pause, nullptr);
    if (write(out, &token, sizeof(token)) != sizeof(token)) std::exit(2);
    if (read(in, &token, sizeof(token)) != sizeof(token)) std::exit(2);
    mine.Turn();
    ReadShared();
    traffic.Turn();
  }
  const auto t1 = std::chrono::steady_clock::now();
  rusage self1{};
  getrusage(RUSAGE_SELF, &self1);
  token = -1;
  if (write(out, &token, sizeof(token)) != sizeof(token)) std::exit(2);
  (void)!read(in, &token, sizeof(token));
  while (wait(nullptr) > 0) {
  }
  for (int i = 0; i < n; ++i) {
    close(rd[static_cast<std::size_t>(i)]);
    close(wr[static_cast<std::size_t>(i)]);
  }
  auto secs = [](const timeval& a) { return static_cast<double>(a.tv_sec) + a.tv_usec * 1e-6; };
  const double self_cpu =
      secs(self1.ru_utime) - secs(self0.ru_utime) + secs(self1.ru_stime) - secs(self0.ru_stime);
  // The children's CPU includes their last hop and exit: small against `hops`.
  const double children_cpu = ChildrenCpuSeconds() - cpu0;
  const long done = (hops + n - 1) / n * n;
  // With traffic or a pause, member 0's turns are not a vehicle's: the others' hops alone.
  const double cpu_per_hop = stream_kb > 0 || pause_us >= 0
                                 ? children_cpu / static_cast<double>(done / n * (n - 1))
                                 : (children_cpu + self_cpu) / static_cast<double>(done);
  return {cpu_per_hop * 1e6,
          std::chrono::duration<double, std::micro>(t1 - t0).count() / static_cast<double>(done)};
}

// A 0 us CPU-latency request, held while the descriptor is open: idle CPUs poll rather than
// halt, as in a run of shoal run as root. Returns the descriptor, or -1 (and says why).
int HoldCpusPolling() {
  const int fd = open("/dev/cpu_dma_latency", O_WRONLY | O_CLOEXEC);
  if (fd < 0) {
    std::fprintf(stderr, "wakeup_ring: cannot open /dev/cpu_dma_latency (%s): idle CPUs may halt\n",
                 std::strerror(errno));
    return -1;
  }
  const std::int32_t zero = 0;
  const ssize_t n = write(fd, &zero, sizeof(zero));
  if (n != static_cast<ssize_t>(sizeof(zero))) {
    std::fprintf(stderr, "wakeup_ring: the 0 us CPU-latency request was refused (%s): idle CPUs "
                 "may halt\n", n < 0 ? std::strerror(errno) : "short write");
    close(fd);
    return -1;
  }
  return fd;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc > 1 && (std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0)) {
    std::printf(
        "usage: wakeup_ring [NS] [HOPS] [TOUCH_KB] [ROUNDS] [STRIDE] [SHARED_KB] [STREAM_KB]\n"
        "                   [PAUSE_US]\n"
        "  e.g. wakeup_ring \"2 8 32 64 128\" 200000 16 5\n"
        "  STRIDE: bytes between touched bytes (64: every cache line, 4096: one line a page),\n"
        "  or chase: every line of TOUCH_KB in a random order, each address read from the last\n"
        "  SHARED_KB: memory all processes share and read a line of each turn (as their code)\n"
        "  STREAM_KB (0 to 1048576): member 0 writes STREAM_KB * (N - 1) KiB a round (as the\n"
        "  emulator and the logger go through every follower's messages); the CPU figure is\n"
        "  then the others', the wall figure includes member 0's traffic\n"
        "  PAUSE_US (0 to 1000000): member 0 sleeps that long once a round, the idle CPUs\n"
        "  polling (a 0 us CPU-latency request, as root): the others' turns lie that much\n"
        "  further apart; given (0 too), the CPU figure is the others' and the wall figure\n"
        "  includes the pause\n");
    return 0;
  }
  std::vector<int> ns;
  std::istringstream list(argc > 1 ? argv[1] : "2 8 32 64 128");
  for (int n; list >> n;) {
    if (n < 2 || n > 4096) {
      std::fprintf(stderr, "wakeup_ring: N must be 2 to 4096, got %d\n", n);
      return 2;
    }
    ns.push_back(n);
  }
  const long hops = argc > 2 ? std::atol(argv[2]) : 200000;
  const std::size_t touch = static_cast<std::size_t>(argc > 3 ? std::atol(argv[3]) : 16) * 1024;
  const int rounds = argc > 4 ? std::atoi(argv[4]) : 5;
  const bool chase = argc > 5 && std::strcmp(argv[5], "chase") == 0;
  const long stride = chase ? 0 : argc > 5 ? std::atol(argv[5]) : 64;
  if (hops < 1 || rounds < 1 || (stride < 1 && !chase)) {
    std::fprintf(stderr, "wakeup_ring: HOPS, ROUNDS and STRIDE must be positive (or STRIDE chase)\n");
    return 2;
  }
  const long shared_kb = argc > 6 ? std::atol(argv[6]) : 0;
  if (shared_kb < 0) {
    std::fprintf(stderr, "wakeup_ring: SHARED_KB must not be negative\n");
    return 2;
  }
  const long stream_kb = argc > 7 ? std::atol(argv[7]) : 0;
  if (stream_kb < 0 || stream_kb > 1048576) {
    std::fprintf(stderr, "wakeup_ring: STREAM_KB must be 0 to 1048576\n");
    return 2;
  }
  const long pause_us = argc > 8 ? std::atol(argv[8]) : -1;  // -1: not given
  if (argc > 8 && (pause_us < 0 || pause_us > 1000000)) {
    std::fprintf(stderr, "wakeup_ring: PAUSE_US must be 0 to 1000000\n");
    return 2;
  }
  const int latency_fd = pause_us >= 0 ? HoldCpusPolling() : -1;
  g_shared_bytes = static_cast<std::size_t>(shared_kb) * 1024;
  std::vector<unsigned char> shared(g_shared_bytes, 1);
  g_shared = shared.data();
  std::printf("processes,cpu_us_per_hop,wall_us_per_hop\n");
  for (int n : ns) {
    std::vector<double> cpu, wall;
    for (int r = 0; r < rounds; ++r) {
      const Result res = Ring(n, hops, touch, static_cast<std::size_t>(stride),
                              static_cast<std::size_t>(stream_kb), pause_us);
      cpu.push_back(res.cpu_us_per_hop);
      wall.push_back(res.wall_us_per_hop);
    }
    std::sort(cpu.begin(), cpu.end());
    std::sort(wall.begin(), wall.end());
    std::printf("%d,%.3f,%.3f\n", n, cpu[cpu.size() / 2], wall[wall.size() / 2]);
    std::fflush(stdout);
  }
  if (latency_fd >= 0) close(latency_fd);
  return 0;
}
