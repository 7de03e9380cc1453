// What the machine alone does to the threads that could run a real-time loop: shoal run's
// machine witness (launcher/machine_witness.h, a thread per CPU at SCHED_FIFO 99) for a
// while, with whatever else runs meanwhile; prints how many stalls of 2, 5, 10 and 20 ms or
// more each CPU saw, the worst, and the witness's own CPU time.
//   Usage: build/bench/machine_stalls [SECONDS=60]   (root, CAP_SYS_NICE or RLIMIT_RTPRIO)
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <thread>

#include "launcher/machine_witness.h"
#include "runtime/clock.h"

int main(int argc, char** argv) {
  const double seconds = argc > 1 ? std::atof(argv[1]) : 60.0;
  if (!(seconds > 0)) {
    std::fprintf(stderr, "usage: machine_stalls [SECONDS=60]\n");
    return 2;
  }
  shoal::MachineWitness witness;
  witness.Start(shoal::MonotonicNs());
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  const shoal::MachineWatch m = witness.Stop();
  if (!m.watched) {
    std::fprintf(stderr, "machine_stalls: not watched: %s\n", m.note.c_str());
    return 1;
  }
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  const double cpu_s = ru.ru_utime.tv_sec + ru.ru_utime.tv_usec * 1e-6 + ru.ru_stime.tv_sec +
                       ru.ru_stime.tv_usec * 1e-6;
  std::printf("%.0f s, %d CPUs, %lld wake-ups, witness CPU %.3f s (%.2f %% of a CPU per "
              "thread)\n",
              seconds, m.cpus, static_cast<long long>(m.wakeups), cpu_s,
              100.0 * cpu_s / seconds / m.cpus);
  const double limits[] = {0.002, 0.005, 0.010, 0.020};
  std::map<int, int> by_cpu[4];
  for (const shoal::MachineStall& s : m.stalls) {
    for (int i = 0; i < 4; ++i) by_cpu[i][s.cpu] += s.length_s >= limits[i];
  }
  for (int i = 0; i < 4; ++i) {
    std::printf("stalls >= %2.0f ms:", limits[i] * 1e3);
    for (const auto& [cpu, n] : by_cpu[i]) std::printf(" CPU %d %d", cpu, n);
    std::printf("\n");
  }
  std::printf("worst %.1f ms; %lld not kept\n", m.worst_s() * 1e3,
              static_cast<long long>(m.stalls_not_kept));
  return 0;
}
