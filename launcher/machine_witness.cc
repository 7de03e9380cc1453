#include "launcher/machine_witness.h"

#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <system_error>

#include "runtime/clock.h"

namespace shoal {

std::vector<int> AllowedCpus() {
  std::vector<int> cpus;
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof(set), &set) != 0) return cpus;
  for (int c = 0; c < CPU_SETSIZE && static_cast<int>(cpus.size()) < kMaxWatchedCpus; ++c) {
    if (CPU_ISSET(c, &set)) cpus.push_back(c);
  }
  return cpus;
}

double MachineWatch::worst_s() const {
  double w = 0.0;
  for (const MachineStall& s : stalls) w = std::max(w, s.length_s);
  return w;
}

const MachineStall* MachineWatch::MostOverlapping(double from_s, double to_s,
                                                  double* overlap_s) const {
  const MachineStall* most = nullptr;
  *overlap_s = 0.0;
  for (const MachineStall& s : stalls) {
    const double begin = std::max(from_s, s.start_s - kWitnessPeriodNs * 1e-9);
    const double end = std::min(to_s, s.start_s + s.length_s);
    if (end > begin && end - begin > *overlap_s) {
      *overlap_s = end - begin;
      most = &s;
    }
  }
  return most;
}

void StallTracker::Wake(std::int64_t deadline_ns, std::int64_t woke_ns) {
  const std::int64_t min_ns = static_cast<std::int64_t>(kMachineStallMinS * 1e9);
  if (open_ && deadline_ns <= end_ns_) {  // a deadline passed during the stall
    end_ns_ = std::max(end_ns_, woke_ns);
    return;
  }
  if (open_) Close();
  if (woke_ns - deadline_ns < min_ns) return;
  open_ = true;
  start_ns_ = deadline_ns;
  end_ns_ = woke_ns;
}

void StallTracker::Close() {
  open_ = false;
  if (stalls_.size() >= stalls_.capacity()) {
    ++not_kept_;
    return;
  }
  stalls_.push_back({start_ns_ * 1e-9, (end_ns_ - start_ns_) * 1e-9, cpu_});
}

std::vector<MachineStall> StallTracker::Finish() {
  if (open_) Close();
  return std::move(stalls_);
}

std::string WitnessRefusal(bool fifo_asked) {
  const bool from_env = std::getenv("SHOAL_SCHED_FIFO") != nullptr;
  if (!fifo_asked && !from_env) return "";
  std::ifstream in("/proc/sys/kernel/sched_rt_runtime_us");
  long long runtime_us = 0;
  if (in >> runtime_us && runtime_us == -1) return "";
  return std::string(fifo_asked ? "--sched-fifo" : "SHOAL_SCHED_FIFO") +
         " puts run processes at SCHED_FIFO, and real-time throttling "
         "(kernel.sched_rt_runtime_us) would hold the witness with a busy one";
}

void MachineWitness::Start(std::int64_t t0_ns) {
  if (started_) return;
  started_ = true;
  stop_ = false;
  t0_ns_ = t0_ns;
  const std::vector<int> cpus = AllowedCpus();
  threads_.resize(cpus.size());  // before any thread runs: each holds a pointer to its slot
  for (std::size_t i = 0; i < cpus.size(); ++i) {
    threads_[i].cpu = cpus[i];
    try {
      threads_[i].thread = std::thread(&MachineWitness::Watch, this, &threads_[i]);
    } catch (const std::system_error& e) {
      threads_[i].refused = std::string("cannot start a thread: ") + e.what();
    }
  }
}

void MachineWitness::Watch(Thread* t) {
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(t->cpu, &set);
  int err = pthread_setaffinity_np(pthread_self(), sizeof(set), &set);
  if (err != 0) {
    t->refused = std::string("cannot pin a thread to CPU ") + std::to_string(t->cpu) + ": " +
                 std::strerror(err);
    return;
  }
  sched_param p{};
  p.sched_priority = sched_get_priority_max(SCHED_FIFO);
  err = pthread_setschedparam(pthread_self(), SCHED_FIFO, &p);
  if (err != 0) {
    t->refused = std::string("no real-time priority (SCHED_FIFO ") +
                 std::to_string(p.sched_priority) + "): " + std::strerror(err) +
                 "; it needs root, CAP_SYS_NICE or an RLIMIT_RTPRIO of " +
                 std::to_string(p.sched_priority);
    return;
  }
  StallTracker tracker(t->cpu, kStallRoom);
  // Until tick 0 in short sleeps, so that a run stopped before it stops the witness at once.
  while (!stop_.load(std::memory_order_relaxed) && MonotonicNs() < t0_ns_ - 20000000) {
    SleepUntilNs(std::min(t0_ns_, MonotonicNs() + 10000000));
  }
  // From tick 0 on (the processes start their loops then), or from now if later.
  std::int64_t k = std::max<std::int64_t>(0, (MonotonicNs() - t0_ns_) / kWitnessPeriodNs + 1);
  while (!stop_.load(std::memory_order_relaxed)) {
    const std::int64_t deadline = t0_ns_ + k * kWitnessPeriodNs;
    SleepUntilNs(deadline);
    const std::int64_t woke = MonotonicNs();
    ++t->wakeups;
    tracker.Wake(deadline - t0_ns_, woke - t0_ns_);
    // After a stall, the next deadline not yet passed: the ones passed are in the stall.
    k = std::max(k + 1, (woke - t0_ns_) / kWitnessPeriodNs + 1);
  }
  t->stalls = tracker.Finish();
  t->not_kept = tracker.not_kept();
}

MachineWatch MachineWitness::Stop() {
  MachineWatch w;
  if (!started_) {
    w.note = "not watched";
    return w;
  }
  started_ = false;
  stop_ = true;
  for (Thread& t : threads_) {
    if (t.thread.joinable()) t.thread.join();
  }
  w.cpus = static_cast<int>(threads_.size());
  w.watched = w.cpus > 0;
  for (Thread& t : threads_) {
    if (!t.refused.empty()) {
      w.watched = false;
      w.note = t.refused;
    }
    w.wakeups += t.wakeups;
    w.stalls_not_kept += t.not_kept;
    w.stalls.insert(w.stalls.end(), t.stalls.begin(), t.stalls.end());
  }
  if (w.cpus == 0) w.note = "no CPU to watch (sched_getaffinity failed)";
  if (!w.watched) {
    w.stalls.clear();
  } else {
    std::sort(w.stalls.begin(), w.stalls.end(),
              [](const MachineStall& a, const MachineStall& b) { return a.start_s < b.start_s; });
    w.note = "a thread per CPU at SCHED_FIFO " +
             std::to_string(sched_get_priority_max(SCHED_FIFO)) + ", every " +
             std::to_string(kWitnessPeriodNs / 1000) + " us";
  }
  threads_.clear();
  return w;
}

}  // namespace shoal
