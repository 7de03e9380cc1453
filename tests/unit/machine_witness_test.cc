// The machine witness of real-time runs: its threads fold wake-ups into stalls and see a
// stall of the whole process; the timing verdict names a process's problem the machine's
// only when the machine stalled for half a period, and half the process's lateness, in
// every stretch the process was late.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <thread>

#include "launcher/machine_witness.h"
#include "launcher/run_report.h"
#include "runtime/channels.h"
#include "runtime/clock.h"
#include "runtime/process.h"

namespace shoal {
namespace {

constexpr std::int64_t kMs = 1000000;

TEST(StallTracker, FoldsTheDeadlinesPassedDuringAStallIntoOne) {
  StallTracker t(1, 16);
  t.Wake(0, kMs / 10);             // on time
  t.Wake(2 * kMs, 25 * kMs);       // 23 ms late: a stall from 2 ms to 25 ms
  for (std::int64_t d = 4; d <= 24; d += 2) t.Wake(d * kMs, 25 * kMs + d);  // passed in it
  t.Wake(26 * kMs, 26 * kMs + 50000);  // on time again
  t.Wake(30 * kMs, 31 * kMs);          // 1 ms late: jitter, not a stall
  t.Wake(40 * kMs, 43 * kMs);          // 3 ms late: a second stall
  const std::vector<MachineStall> s = t.Finish();
  ASSERT_EQ(s.size(), 2u);
  EXPECT_DOUBLE_EQ(s[0].start_s, 0.002);
  EXPECT_NEAR(s[0].length_s, 0.023, 1e-7);  // to the last wake-up it held: 25 ms + 24 ns
  EXPECT_EQ(s[0].cpu, 1);
  EXPECT_DOUBLE_EQ(s[1].start_s, 0.040);
  EXPECT_NEAR(s[1].length_s, 0.003, 1e-12);
  EXPECT_EQ(t.not_kept(), 0);
}

TEST(StallTracker, CountsWhatItHasNoRoomFor) {
  StallTracker t(0, 2);
  for (int i = 0; i < 5; ++i) t.Wake(i * 100 * kMs, i * 100 * kMs + 5 * kMs);
  EXPECT_EQ(t.Finish().size(), 2u);
  EXPECT_EQ(t.not_kept(), 3);
}

TEST(MachineWitness, SeesTheWholeProcessStopped) {
  if (geteuid() != 0) GTEST_SKIP() << "real-time priority needs root here";
  MachineWitness w;
  w.Start(MonotonicNs());
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  // Stopped for 80 ms by a child: every thread of this process, the witness's too, is held,
  // as a hypervisor holds a virtual CPU.
  const pid_t parent = getpid();
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    kill(parent, SIGSTOP);
    usleep(80000);
    kill(parent, SIGCONT);
    _exit(0);
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const MachineWatch m = w.Stop();
  ASSERT_TRUE(m.watched) << m.note;
  EXPECT_GE(m.cpus, 1);
  EXPECT_GT(m.wakeups, 100);
  // Every CPU's thread saw it, and none counted it twice.
  int long_ones = 0;
  for (const MachineStall& s : m.stalls) long_ones += s.length_s >= 0.06;
  EXPECT_EQ(long_ones, m.cpus);
  EXPECT_GE(m.worst_s(), 0.07);
  EXPECT_LT(m.worst_s(), 5.0);
}

TEST(MachineWitness, StopsAtOnceBeforeTickZero) {
  MachineWitness w;
  w.Start(MonotonicNs() + 30LL * 1000 * kMs);
  std::this_thread::sleep_for(std::chrono::milliseconds(30));
  const auto t = std::chrono::steady_clock::now();
  const MachineWatch m = w.Stop();
  // It sleeps in steps of 10 ms until tick 0: a generous bound that a sleep to tick 0 (30 s)
  // cannot meet.
  EXPECT_LT(std::chrono::steady_clock::now() - t, std::chrono::seconds(5));
  EXPECT_TRUE(m.stalls.empty());
  if (geteuid() == 0) {
    EXPECT_TRUE(m.watched) << m.note;
  }
}

// A run of one vehicle (id 3) and the leader, with health reports every second.
struct TimedRun {
  RunData data;
  RunAnalysis analysis;
  RunReport report;
  TimedRun() {
    report.launch.mode = ModeName(Mode::kRealtime);
    report.launch.machine.watched = true;
  }
  /// Process `id` reports at t = 1..5 s; `late` at the report of second `second`: one
  /// overrun and 25 ms of lateness in the second before it.
  void Reports(int id, std::vector<int> late_seconds) {
    std::int64_t overruns = 0;
    HealthRecord h;
    h.process_id = id;
    for (int second = 1; second <= 5; ++second) {
      h.utime = second * 1000000LL;
      h.lateness_window_count = 50;
      h.lateness_window_max_s = 0.001;
      for (int l : late_seconds) {
        if (l != second) continue;
        ++overruns;
        h.lateness_window_max_s = 0.025;
      }
      h.overruns = overruns;
      h.lateness_p99_s = 0.002;
      h.lateness_max_s = overruns > 0 ? 0.025 : 0.001;
      data.health.push_back(h);
    }
    analysis.processes.push_back({id, 5, h});
  }
  void Stall(double start_s, double length_s) {
    report.launch.machine.stalls.push_back({start_s, length_s, 0});
  }
  void Judge() { JudgeTiming(data, analysis, 0.02, &report); }
};

TEST(MachineTiming, AProblemInEverySecondOfWhichTheMachineStalledIsTheMachines) {
  TimedRun r;
  r.Reports(3, {2, 4});  // late in (1 s, 2 s] and (3 s, 4 s]
  r.Reports(0, {});
  r.Stall(1.50, 0.030);
  r.Stall(3.20, 0.013);  // half of the 25 ms the vehicle lost, and more
  r.Judge();
  EXPECT_FALSE(r.report.timing_ok);
  ASSERT_EQ(r.report.timing_problems.size(), 1u);
  EXPECT_NE(r.report.timing_problems[0].find("vehicle 3: 2 overruns"), std::string::npos);
  EXPECT_NE(r.report.timing_problems[0].find("the machine itself stalled for half a period or "
                                             "more (worst 30.0 ms, at t = 1.50 s)"),
            std::string::npos)
      << r.report.timing_problems[0];
  EXPECT_TRUE(r.report.timing_machine_limited);
}

TEST(MachineTiming, ASecondWithoutAStallOfHalfAPeriodIsNot) {
  for (const double length_s : {0.009, 0.0}) {  // too short; none in that second
    TimedRun r;
    r.Reports(3, {2, 4});
    r.Stall(1.50, 0.030);
    if (length_s > 0) r.Stall(3.20, length_s);
    r.Stall(4.60, 0.040);  // a second later than the late one
    r.Judge();
    ASSERT_EQ(r.report.timing_problems.size(), 1u);
    EXPECT_EQ(r.report.timing_problems[0].find("machine"), std::string::npos)
        << r.report.timing_problems[0];
    EXPECT_FALSE(r.report.timing_machine_limited);
  }
}

TEST(MachineTiming, AShortStallDoesNotExplainAMuchLongerLateness) {
  for (const double late_s : {0.025, 1.5}) {  // a machine stall, a process stopped
    TimedRun r;
    r.Reports(3, {2});
    r.data.health[1].lateness_window_max_s = late_s;
    r.Stall(1.50, 0.013);  // half a period, but not half of 1.5 s
    r.Judge();
    ASSERT_EQ(r.report.timing_problems.size(), 1u);
    EXPECT_EQ(r.report.timing_machine_limited, late_s < 0.026) << late_s;
  }
}

TEST(MachineTiming, OneProblemNotTheMachinesIsEnoughToSaySo) {
  TimedRun r;
  r.Reports(3, {2});
  r.Reports(4, {5});
  r.Stall(1.90, 0.020);
  r.Judge();
  ASSERT_EQ(r.report.timing_problems.size(), 2u);
  EXPECT_NE(r.report.timing_problems[0].find("machine"), std::string::npos);
  EXPECT_EQ(r.report.timing_problems[1].find("machine"), std::string::npos);
  EXPECT_FALSE(r.report.timing_machine_limited);
}

TEST(MachineTiming, NotWhereTheWitnessCannotSpeak) {
  for (const bool elsewhere : {false, true}) {
    TimedRun r;
    r.Reports(3, {2});
    r.Stall(1.50, 0.030);
    if (elsewhere) {
      r.report.launch.unwatched_ids = {3};  // on a host with another kernel
    } else {
      r.report.launch.machine.watched = false;  // no real-time priority
    }
    r.Judge();
    ASSERT_EQ(r.report.timing_problems.size(), 1u);
    EXPECT_FALSE(r.report.timing_machine_limited);
  }
}

TEST(MachineTiming, OnTimeRunsAreNotTheMachines) {
  TimedRun r;
  r.Reports(3, {});
  r.Stall(1.50, 0.030);
  r.Judge();
  EXPECT_TRUE(r.report.timing_ok);
  EXPECT_FALSE(r.report.timing_machine_limited);
}

}  // namespace
}  // namespace shoal
