// RecorderGate: the lockstep clock master's wait for lcm-logger. Against real processes:
// a sleeping one lets it through at once, a busy one holds it until the time limit, a
// multithreaded one is watched thread by thread, and a vanished one opens the gate.
// RecorderProgress: the wait by the recorder's own count of what it has handled.
#include "channel_emulator/recorder_gate.h"

#include <fcntl.h>

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <fstream>
#include <functional>
#include <string>
#include <thread>

#include "runtime/clock.h"
#include "runtime/lcm_queue_shim.h"
#include "runtime/process.h"

namespace shoal {
namespace {

// A child process running `body` (then sleeping for ever); killed and reaped at the end.
struct Child {
  pid_t pid = -1;
  explicit Child(const std::function<void()>& body) {
    pid = fork();
    if (pid == 0) {
      body();
      for (;;) pause();
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(30));  // let it settle
  }

  ~Child() {
    if (pid > 0) {
      kill(pid, SIGKILL);
      waitpid(pid, nullptr, 0);
    }
  }
};

void Nothing() {}
void SpinForever() {
  const volatile bool busy = true;
  while (busy) {
  }
}

// Waits (at most 5 s) until process `pid` has `n` threads; false if it never does.
bool WaitForThreads(pid_t pid, int n) {
  const std::string path = "/proc/" + std::to_string(pid) + "/status";
  for (int i = 0; i < 500; ++i) {
    std::ifstream f(path);
    std::string line;
    while (std::getline(f, line)) {
      if (line.rfind("Threads:", 0) == 0 && std::stoi(line.substr(8)) == n) return true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return false;
}

// A thread that spins for 200 ms from its own start, then sleeps for ever.
void SpinThenSleep() {
  const std::int64_t t0 = MonotonicNs();
  while (MonotonicNs() - t0 < 200000000LL) {  // a clock read: not optimised away
  }
  for (;;) pause();
}

TEST(RecorderGate, ASleepingRecorderLetsTheWindowThroughAtOnce) {
  Child c(Nothing);
  RecorderGate gate(c.pid);
  ASSERT_TRUE(gate.active());
  const std::int64_t t0 = MonotonicNs();
  gate.Wait(1000000000LL);
  EXPECT_LT(MonotonicNs() - t0, 100000000LL);
  EXPECT_EQ(gate.waits(), 0);
  EXPECT_EQ(gate.timeouts(), 0);
}

TEST(RecorderGate, ABusyRecorderHoldsTheWindowUntilTheLimit) {
  Child c(SpinForever);
  RecorderGate gate(c.pid);
  ASSERT_TRUE(gate.active());
  const std::int64_t t0 = MonotonicNs();
  gate.Wait(30000000LL);
  const std::int64_t waited = MonotonicNs() - t0;
  EXPECT_GE(waited, 30000000LL);
  EXPECT_LT(waited, 2000000000LL);
  EXPECT_EQ(gate.waits(), 1);
  EXPECT_EQ(gate.timeouts(), 1);
  EXPECT_GE(gate.waited_ns(), 30000000LL);
}

// Every thread counts: a recorder whose main thread sleeps while another thread runs for
// 200 ms, then sleeps too. The gate waits for the second thread, and no longer.
TEST(RecorderGate, ARunnableThreadOfTheRecorderIsEnoughToWaitAndItsSleepEndsTheWait) {
  Child c([] {
    std::thread worker(SpinThenSleep);
    for (;;) pause();
  });
  ASSERT_TRUE(WaitForThreads(c.pid, 2));
  RecorderGate gate(c.pid);
  ASSERT_TRUE(gate.active());
  const std::int64_t t0 = MonotonicNs();
  gate.Wait(5000000000LL);
  const std::int64_t waited = MonotonicNs() - t0;
  EXPECT_EQ(gate.waits(), 1);
  EXPECT_EQ(gate.timeouts(), 0);
  EXPECT_GT(waited, 0);
  EXPECT_LT(waited, 3000000000LL);
}

// lcm-logger creates its log file before its writer and LCM's receive thread: a gate set
// up in between must notice the threads that start later.
TEST(RecorderGate, ThreadsStartedAfterTheGateAreWatchedToo) {
  int go[2];
  ASSERT_EQ(pipe(go), 0);
  Child c([&go] {
    char byte;
    while (read(go[0], &byte, 1) != 1) {
    }
    std::thread worker(SpinThenSleep);
    for (;;) pause();
  });
  ASSERT_TRUE(WaitForThreads(c.pid, 1));
  RecorderGate gate(c.pid);  // the child has one thread, blocked in read()
  ASSERT_TRUE(gate.active());
  ASSERT_EQ(write(go[1], "x", 1), 1);
  ASSERT_TRUE(WaitForThreads(c.pid, 2));  // now two, one spinning for 200 ms
  gate.Wait(5000000000LL);
  EXPECT_EQ(gate.waits(), 1);
  EXPECT_EQ(gate.timeouts(), 0);
  close(go[0]);
  close(go[1]);
}

// A recorder that exited but is not reaped yet (a zombie) is gone: no waiting for it.
TEST(RecorderGate, AZombieRecorderOpensTheGate) {
  const pid_t pid = fork();
  if (pid == 0) _exit(0);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  RecorderGate gate(pid);
  const std::int64_t t0 = MonotonicNs();
  gate.Wait(1000000000LL);
  EXPECT_LT(MonotonicNs() - t0, 100000000LL);
  EXPECT_FALSE(gate.active());
  EXPECT_EQ(gate.timeouts(), 0);
  waitpid(pid, nullptr, 0);
}

TEST(RecorderGate, AVanishedRecorderOpensTheGate) {
  pid_t pid;
  {
    Child c(Nothing);
    pid = c.pid;
  }
  RecorderGate gone(pid);
  EXPECT_FALSE(gone.active());
  Child c(SpinForever);
  RecorderGate gate(c.pid);
  ASSERT_TRUE(gate.active());
  kill(c.pid, SIGKILL);
  waitpid(c.pid, nullptr, 0);
  c.pid = -1;
  const std::int64_t t0 = MonotonicNs();
  gate.Wait(5000000000LL);
  EXPECT_LT(MonotonicNs() - t0, 1000000000LL);
  EXPECT_FALSE(gate.active());
  RecorderGate none(0);
  EXPECT_FALSE(none.active());
  none.Wait(5000000000LL);
}

// The other lockstep helper of runtime/process.h: the 0 us CPU latency request is in force
// (the device reads back the aggregate request) while held, and gone after.
std::int32_t CurrentCpuLatencyUs() {
  const int fd = open("/dev/cpu_dma_latency", O_RDONLY | O_CLOEXEC);
  if (fd < 0) return -1;
  std::int32_t v = -1;
  if (read(fd, &v, sizeof(v)) != static_cast<ssize_t>(sizeof(v))) v = -1;
  close(fd);
  return v;
}

TEST(CpuLatencyRequest, HeldWhileItLivesAsRootElseSaysWhy) {
  const std::int32_t before = CurrentCpuLatencyUs();
  {
    CpuLatencyRequest req;
    if (geteuid() != 0 || before < 0) {
      EXPECT_FALSE(req.held());
      EXPECT_NE(req.note().find("no CPU latency request"), std::string::npos) << req.note();
      GTEST_SKIP() << "not root or no /dev/cpu_dma_latency: " << req.note();
    }
    ASSERT_TRUE(req.held()) << req.note();
    EXPECT_EQ(CurrentCpuLatencyUs(), 0);
  }
  EXPECT_EQ(CurrentCpuLatencyUs(), before);
}

// RecorderProgress against the shared memory object the preloaded logger library makes
// (runtime/lcm_queue_shim.c), made here as it makes it, under this process's pid.
struct FakeRecorderCount {
  std::string name;
  ShoalLoggerProgress* p = nullptr;
  FakeRecorderCount() {
    char b[64];
    std::snprintf(b, sizeof(b), SHOAL_LOGGER_PROGRESS_NAME, static_cast<long>(getpid()));
    name = b;
    shm_unlink(name.c_str());
    const int fd = shm_open(name.c_str(), O_RDWR | O_CREAT | O_EXCL, 0600);
    if (fd < 0 || ftruncate(fd, sizeof(ShoalLoggerProgress)) != 0) return;
    void* m = mmap(nullptr, sizeof(ShoalLoggerProgress), PROT_READ | PROT_WRITE, MAP_SHARED,
                   fd, 0);
    close(fd);
    if (m != MAP_FAILED) p = static_cast<ShoalLoggerProgress*>(m);
  }
  ~FakeRecorderCount() {
    if (p != nullptr) munmap(p, sizeof(ShoalLoggerProgress));
    shm_unlink(name.c_str());
  }
  bool Exists() const {
    const int fd = shm_open(name.c_str(), O_RDONLY, 0);
    if (fd >= 0) close(fd);
    return fd >= 0;
  }
};

TEST(RecorderProgress, WithoutTheRecordersCountNothingIsWaitedFor) {
  RecorderProgress none(0);
  EXPECT_FALSE(none.Attach());
  EXPECT_FALSE(none.WaitFor(1, 1000000));
  // A pid whose process made no count (this one, before the fake below exists).
  RecorderProgress absent(getpid());
  EXPECT_FALSE(absent.Attach());
  EXPECT_EQ(absent.handled(), 0u);
}

TEST(RecorderProgress, ACountNotYetStartedIsLookedForAgainAndThenItsNameRemoved) {
  FakeRecorderCount fake;
  ASSERT_NE(fake.p, nullptr);
  RecorderProgress progress(getpid());
  EXPECT_FALSE(progress.Attach());  // made, no magic yet
  EXPECT_TRUE(fake.Exists());
  fake.p->handled = 7;
  __atomic_store_n(&fake.p->magic, SHOAL_LOGGER_PROGRESS_MAGIC, __ATOMIC_RELEASE);
  EXPECT_TRUE(progress.Attach());
  EXPECT_FALSE(fake.Exists());  // nothing is left behind once it is mapped
  EXPECT_EQ(progress.handled(), 7u);
  __atomic_add_fetch(&fake.p->handled, 1, __ATOMIC_RELEASE);
  EXPECT_EQ(progress.handled(), 8u);  // the mapping outlives the name
}

TEST(RecorderProgress, WaitsUntilTheRecorderHasHandledTheTargetOrTheLimit) {
  FakeRecorderCount fake;
  ASSERT_NE(fake.p, nullptr);
  __atomic_store_n(&fake.p->magic, SHOAL_LOGGER_PROGRESS_MAGIC, __ATOMIC_RELEASE);
  RecorderProgress progress(getpid());
  ASSERT_TRUE(progress.Attach());
  fake.p->handled = 10;
  EXPECT_TRUE(progress.WaitFor(10, 1000000000LL));
  EXPECT_EQ(progress.waits(), 0);  // already there: no wait at all
  std::thread recorder([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
    __atomic_store_n(&fake.p->handled, 12, __ATOMIC_RELEASE);
  });
  const std::int64_t t0 = MonotonicNs();
  EXPECT_TRUE(progress.WaitFor(12, 5000000000LL));
  const std::int64_t waited = MonotonicNs() - t0;
  recorder.join();
  EXPECT_GE(waited, 20000000);
  EXPECT_LT(waited, 4000000000LL);
  EXPECT_EQ(progress.waits(), 1);
  EXPECT_EQ(progress.timeouts(), 0);
  EXPECT_TRUE(progress.WaitFor(13, 30000000));  // never reached: gives up after 30 ms
  EXPECT_EQ(progress.waits(), 2);
  EXPECT_EQ(progress.timeouts(), 1);
  EXPECT_GE(progress.waited_ns(), 50000000);
}

// lcm-logger stopped by SIGINT drops what its writer has not written: the end of a run
// waits until every event handed to the writer is written.
TEST(RecorderProgress, WaitsUntilEveryQueuedEventIsWritten) {
  FakeRecorderCount fake;
  ASSERT_NE(fake.p, nullptr);
  __atomic_store_n(&fake.p->magic, SHOAL_LOGGER_PROGRESS_MAGIC, __ATOMIC_RELEASE);
  RecorderProgress progress(getpid());
  ASSERT_TRUE(progress.Attach());
  fake.p->queued = 40;
  fake.p->written = 37;
  EXPECT_FALSE(progress.WaitForWritten(30000000));  // three pending: gives up after 30 ms
  EXPECT_EQ(progress.queued(), 40u);
  EXPECT_EQ(progress.written(), 37u);
  std::thread writer([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
    __atomic_store_n(&fake.p->written, 40, __ATOMIC_RELEASE);
  });
  const std::int64_t t0 = MonotonicNs();
  EXPECT_TRUE(progress.WaitForWritten(5000000000LL));
  writer.join();
  EXPECT_GE(MonotonicNs() - t0, 20000000);
  RecorderProgress none(0);
  EXPECT_FALSE(none.WaitForWritten(1000000));  // not attached: nothing to wait for
  EXPECT_FALSE(none.WaitForWrittenUpTo(1, 1000000));
  // Before a window: what was handed to the writer when the last window was released.
  EXPECT_TRUE(progress.WaitForWrittenUpTo(40, 1000000000LL));
  const std::int64_t waits = progress.waits();
  EXPECT_EQ(waits, 0);  // written already: no wait
  EXPECT_TRUE(progress.WaitForWrittenUpTo(41, 30000000));  // never written: gives up
  EXPECT_EQ(progress.waits(), 1);
  EXPECT_EQ(progress.timeouts(), 1);
}

// A message that never reaches the recorder (sent before it joined the group, dropped by
// the kernel) must not make every later window wait the limit: a wait that gives up while
// the recorder did nothing takes the rest as lost; one while it worked does not.
TEST(RecorderProgress, AWaitThatGivesUpWhileTheRecorderDidNothingTakesTheRestAsLost) {
  FakeRecorderCount fake;
  ASSERT_NE(fake.p, nullptr);
  __atomic_store_n(&fake.p->magic, SHOAL_LOGGER_PROGRESS_MAGIC, __ATOMIC_RELEASE);
  RecorderProgress progress(getpid());
  ASSERT_TRUE(progress.Attach());
  fake.p->handled = 10;
  fake.p->queued = 10;
  fake.p->written = 9;  // its writer still busy: not idle, nothing taken as lost
  EXPECT_TRUE(progress.WaitFor(13, 30000000));
  EXPECT_EQ(progress.lost(13), 0u);
  fake.p->written = 10;
  EXPECT_TRUE(progress.WaitFor(13, 30000000));  // idle throughout: three lost
  EXPECT_EQ(progress.timeouts(), 2);
  EXPECT_EQ(progress.lost(13), 3u);
  const std::int64_t t0 = MonotonicNs();
  EXPECT_TRUE(progress.WaitFor(13, 1000000000LL));  // nothing more to wait for
  EXPECT_LT(MonotonicNs() - t0, 500000000);
  EXPECT_EQ(progress.waits(), 2);
  // Working but not there when the limit passes: slow, not lost.
  std::thread recorder([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    __atomic_store_n(&fake.p->handled, 11, __ATOMIC_RELEASE);
  });
  EXPECT_TRUE(progress.WaitFor(16, 60000000));
  recorder.join();
  EXPECT_EQ(progress.timeouts(), 3);
  EXPECT_EQ(progress.lost(16), 3u);
  // One of the lost comes after all: the loss is at most what it has not handled.
  fake.p->handled = 14;
  EXPECT_EQ(progress.lost(16), 2u);
}

}  // namespace
}  // namespace shoal
