// The machine witness of real-time runs: its threads fold wake-ups into stalls and see a
// stall of the whole process; the timing verdict names a process's problem the machine's
// only when a stall covered at least half the time each of its overruns lost.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <thread>

#include "launcher/machine_witness.h"
#include "launcher/run_report.h"
#include "runtime/channels.h"
#include "runtime/clock.h"
#include "runtime/overrun_note.h"
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

// A real-time run's verdict from the processes' last health reports, their overrun notes
// in their output files, and the machine's stalls.
struct TimedRun {
  RunAnalysis analysis;
  RunReport report;
  std::string dir;
  TimedRun() {
    char tmpl[] = "/tmp/shoal-machine-test.XXXXXX";
    const char* made = mkdtemp(tmpl);
    if (made == nullptr) std::abort();  // no temporary folder: nothing here can be tested
    dir = made;
    report.launch.mode = ModeName(Mode::kRealtime);
    report.launch.process_output_dir = dir;
    report.launch.machine.watched = true;
  }
  ~TimedRun() { std::system(("rm -rf '" + dir + "'").c_str()); }
  TimedRun(const TimedRun&) = delete;
  TimedRun& operator=(const TimedRun&) = delete;
  /// Process `id` (0 leader, else a vehicle) overran at each of `due_s`, each time done
  /// `lost_s` after it was due; `counted` overruns in its last report (-1: as many as
  /// noted).
  void Overruns(int id, std::vector<double> due_s, double lost_s = 0.025, int counted = -1,
                double p99_s = 0.002) {
    std::ofstream out(dir + "/" + (id == 0 ? "leader" : "vehicle" + std::to_string(id)) +
                      ".txt");
    out << "shoal_vehicle: SCHED_OTHER, timer slack 1 ns\n";
    for (std::size_t i = 0; i < due_s.size(); ++i) {
      // On the monotonic clock, tick 0 at 1000 s.
      const auto due_ns = static_cast<std::int64_t>((1000 + due_s[i]) * 1e9);
      out << FormatOverrunNote({static_cast<std::int64_t>(due_s[i] * 50), due_ns, due_s[i],
                                lost_s - 0.0002, lost_s})
          << "\n";
    }
    HealthRecord h;
    h.process_id = id;
    h.overruns = counted >= 0 ? counted : static_cast<std::int64_t>(due_s.size());
    h.lateness_p99_s = p99_s;
    analysis.processes.push_back({id, 5, h});
  }
  /// The channel emulator released late at each of `due_s`, each `late_s` after it was
  /// due; `end`: then wrote that more followed. The notes' seconds from tick 0 are off by
  /// `skew_s` (their CLOCK_MONOTONIC times right, tick 0 at 1000 s).
  void LateReleases(std::vector<double> due_s, double late_s = 0.05, bool end = false,
                    double skew_s = 0.0) {
    std::ofstream out(dir + "/emulator.txt");
    out << "shoal_channel_emulator: SCHED_OTHER, nice -10\n";
    for (const double d : due_s) {
      out << FormatLateReleaseNote(static_cast<std::int64_t>((1000 + d) * 1e9), d + skew_s,
                                   late_s)
          << "\n";
    }
    if (end) out << kLateReleaseNotesEnd << "\n";
    HealthRecord h;
    h.process_id = kEmulatorId;
    h.lateness_p99_s = late_s;
    analysis.processes.push_back({kEmulatorId, 5, h});
  }
  void Stall(double start_s, double length_s) {
    report.launch.machine.stalls.push_back({start_s, length_s, 0});
  }
  void Judge(double period_s = 0.02) { JudgeTiming(analysis, period_s, &report); }
};

TEST(OverrunNote, ReadsBackWhatItWrites) {
  const OverrunNote n{205, 123456789012345, 4.102003, 0.0231, 0.0234};
  OverrunNote back;
  ASSERT_TRUE(ParseOverrunNote(FormatOverrunNote(n), &back)) << FormatOverrunNote(n);
  EXPECT_EQ(back.tick, 205);
  EXPECT_EQ(back.due_ns, 123456789012345);
  EXPECT_NEAR(back.due_s, 4.102003, 1e-9);
  EXPECT_NEAR(back.woke_s, 0.0231, 1e-9);
  EXPECT_NEAR(back.done_s, 0.0234, 1e-9);
  EXPECT_FALSE(ParseOverrunNote(FormatOverrunNote(n) + " and more", &back));
  EXPECT_FALSE(ParseOverrunNote("overrun: tick 5", &back));
  EXPECT_FALSE(ParseOverrunNote(kOverrunNotesEnd, &back));
}

TEST(MachineTiming, OverrunsTheMachineStalledThroughAreTheMachines) {
  TimedRun r;
  r.Overruns(3, {1.5, 3.2});
  r.Overruns(0, {});
  r.Stall(1.499, 0.030);  // began up to a witness period before the tick was due
  r.Stall(3.21, 0.013);   // half of the 25 ms the vehicle lost, and more
  r.Judge();
  EXPECT_FALSE(r.report.timing_ok);
  ASSERT_EQ(r.report.timing_problems.size(), 1u);
  EXPECT_NE(r.report.timing_problems[0].find("vehicle 3: 2 overruns"), std::string::npos);
  EXPECT_NE(r.report.timing_problems[0].find("the machine itself stalled for at least half of "
                                             "each overrun (worst 30.0 ms, at t = 1.499 s)"),
            std::string::npos)
      << r.report.timing_problems[0];
  EXPECT_TRUE(r.report.timing_machine_limited);
}

TEST(MachineTiming, AnOverrunWithoutAStallThroughItIsNot) {
  // Too short; beginning 20 ms into the 25 ms the tick lost; a few ms after the tick was
  // done; a second before it; none.
  for (const double at_s : {3.2, 3.22, 3.23, 2.2, -1.0}) {
    TimedRun r;
    r.Overruns(3, {1.5, 3.2});
    r.Stall(1.50, 0.030);
    if (at_s >= 0) r.Stall(at_s, at_s == 3.2 ? 0.012 : 0.030);
    r.Judge();
    ASSERT_EQ(r.report.timing_problems.size(), 1u);
    EXPECT_EQ(r.report.timing_problems[0].find("machine"), std::string::npos)
        << at_s << ": " << r.report.timing_problems[0];
    EXPECT_FALSE(r.report.timing_machine_limited) << at_s;
  }
}

TEST(MachineTiming, AStallBeganUpToAWitnessPeriodBeforeItsStart) {
  // 22 ms lost from 3.2 s; a stall the witness noticed at 3.2015 s, to 3.212 s: it began
  // up to 2 ms earlier, so it covers 12 ms of the 22, more than half.
  TimedRun r;
  r.Overruns(3, {3.2}, 0.022);
  r.Stall(3.2015, 0.0105);
  r.Judge();
  EXPECT_TRUE(r.report.timing_machine_limited) << r.report.timing_problems[0];
}

TEST(MachineTiming, TheNotesMonotonicTimeIsTheOneJudged) {
  // The note's seconds from tick 0 off by 5 s (the process converted a wall-clock start
  // time after the wall clock was stepped); its CLOCK_MONOTONIC time right.
  TimedRun r;
  r.report.launch.t0_monotonic_ns = 1000000000000;  // 1000 s, as the notes above
  r.Overruns(3, {1.5});
  std::ifstream in(r.dir + "/vehicle3.txt");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::size_t at = text.find("due at t = 1.5");
  ASSERT_NE(at, std::string::npos) << text;
  text.replace(at, 14, "due at t = 6.5");
  std::ofstream(r.dir + "/vehicle3.txt") << text;
  r.Stall(1.50, 0.030);
  r.Judge();
  EXPECT_TRUE(r.report.timing_machine_limited) << text;
}

TEST(MachineTiming, NeverARestartedProcess) {
  TimedRun r;
  r.Overruns(3, {1.5});
  r.Stall(1.50, 0.030);
  r.report.launch.restarts.push_back({"vehicle 3", 100, 101, "killed by signal 9", 3.0});
  r.Judge();
  ASSERT_EQ(r.report.timing_problems.size(), 1u);
  EXPECT_FALSE(r.report.timing_machine_limited);
}

TEST(MachineTiming, NotALatenessNoOverrunNamesBelowFiftyHertz) {
  // At 10 Hz a loop can be 30 ms late at p99 without overrunning: no note names those
  // ticks. At 50 Hz each such tick overran and is noted.
  for (const double period_s : {0.1, 0.02}) {
    TimedRun r;
    r.Overruns(3, {1.5}, 0.025, -1, 0.030);
    r.Stall(1.50, 0.030);
    r.Judge(period_s);
    ASSERT_EQ(r.report.timing_problems.size(), 1u);
    EXPECT_EQ(r.report.timing_machine_limited, period_s < 0.05) << period_s;
  }
}

TEST(MachineTiming, AShortStallDoesNotExplainAMuchLongerLoss) {
  for (const double lost_s : {0.025, 1.5}) {  // a machine stall, a process stopped
    TimedRun r;
    r.Overruns(3, {2.0}, lost_s);
    r.Stall(2.01, 0.030);
    r.Judge();
    ASSERT_EQ(r.report.timing_problems.size(), 1u);
    EXPECT_EQ(r.report.timing_machine_limited, lost_s < 0.026) << lost_s;
  }
}

TEST(MachineTiming, FewerNotesThanOverrunsAreNotEnough) {
  for (const bool more : {false, true}) {
    TimedRun r;
    r.Overruns(3, {1.5}, 0.025, more ? 1 : 2);
    if (more) {
      std::ofstream(r.dir + "/vehicle3.txt", std::ios::app) << kOverrunNotesEnd << "\n";
    }
    r.Stall(1.50, 0.030);
    r.Judge();
    ASSERT_EQ(r.report.timing_problems.size(), 1u);
    EXPECT_FALSE(r.report.timing_machine_limited) << more;
  }
}

TEST(MachineTiming, OneProblemNotTheMachinesIsEnoughToSaySo) {
  TimedRun r;
  r.Overruns(3, {1.9});
  r.Overruns(4, {4.5});
  r.Stall(1.90, 0.020);
  r.Judge();
  ASSERT_EQ(r.report.timing_problems.size(), 2u);
  EXPECT_NE(r.report.timing_problems[0].find("machine"), std::string::npos);
  EXPECT_EQ(r.report.timing_problems[1].find("machine"), std::string::npos);
  EXPECT_FALSE(r.report.timing_machine_limited);
}

TEST(LateReleaseNote, ReadsBackWhatItWrites) {
  const std::string line = FormatLateReleaseNote(123456789012345, 2.551, 0.0512);
  EXPECT_EQ(line, "late release: due at t = 2.551000 s (CLOCK_MONOTONIC 123456789012345 ns), "
                  "sent 51.200 ms late");
  OverrunNote back;
  ASSERT_TRUE(ParseLateReleaseNote(line, &back));
  EXPECT_EQ(back.due_ns, 123456789012345);
  EXPECT_NEAR(back.due_s, 2.551, 1e-9);
  EXPECT_NEAR(back.done_s, 0.0512, 1e-9);
  EXPECT_FALSE(ParseLateReleaseNote(line + " and more", &back));
  EXPECT_FALSE(ParseLateReleaseNote(kLateReleaseNotesEnd, &back));
  EXPECT_FALSE(ParseOverrunNote(line, &back));
}

TEST(LateReleaseNotes, OneStallIsOneNote) {
  constexpr std::int64_t kMs = 1000000, kT0 = 1000000 * kMs;  // tick 0 at 1000 s
  LateReleaseNotes notes;
  std::vector<std::string> lines;
  const auto add = [&](std::int64_t due_ms, std::int64_t sent_ms) {
    const std::string line = notes.Add(kT0 + due_ms * kMs, due_ms * 1e-3, kT0 + sent_ms * kMs);
    if (!line.empty()) lines.push_back(line);
  };
  add(1000, 1005);  // on time
  // A stall from 2,550 to 2,650 ms: every release due then goes out after it, one per
  // message; those due before 2,630 ms are more than 20 ms late.
  for (std::int64_t due = 2550; due < 2650; ++due) add(due, 2651 + (due - 2550) / 20);
  EXPECT_TRUE(lines.empty());  // the note stays open while releases join it
  add(4000, 4030);              // another, on its own
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0], FormatLateReleaseNote(kT0 + 2550 * kMs, 2.55, 0.105));
  EXPECT_EQ(notes.Finish(), FormatLateReleaseNote(kT0 + 4000 * kMs, 4.0, 0.030));
  EXPECT_EQ(notes.Finish(), "");
}

TEST(LateReleaseNotes, AtMostTheCapThenOneLineSayingMoreFollowed) {
  LateReleaseNotes notes;
  std::vector<std::string> lines;
  for (int k = 0; k < kOverrunNotes + 5; ++k) {
    const std::int64_t due = (2000 + 100 * k) * 1000000LL;  // 100 ms apart, 30 ms late
    const std::string line = notes.Add(due, due * 1e-9, due + 30000000);
    if (!line.empty()) lines.push_back(line);
  }
  const std::string last = notes.Finish();
  if (!last.empty()) lines.push_back(last);
  ASSERT_EQ(static_cast<int>(lines.size()), kOverrunNotes + 1);
  EXPECT_EQ(lines.back(), kLateReleaseNotesEnd);
  OverrunNote n;
  EXPECT_TRUE(ParseLateReleaseNote(lines[kOverrunNotes - 1], &n));
}

TEST(MachineTiming, LateReleasesTheMachineStalledThroughAreTheMachines) {
  TimedRun r;
  // Judged on the notes' CLOCK_MONOTONIC times, as the loops' are.
  r.report.launch.t0_monotonic_ns = 1000000000000;
  r.LateReleases({2.55, 2.57}, 0.05, false, 5.0);
  r.Overruns(2, {2.55});
  r.Stall(2.548, 0.102);
  r.Judge();
  ASSERT_EQ(r.report.timing_problems.size(), 2u);
  EXPECT_NE(r.report.timing_problems[0].find("channel emulator: 0 overruns, release error p99 "
                                             "50.0 ms (limits: 0 overruns, p99 20 ms); the "
                                             "machine itself stalled for at least half of each "
                                             "late release (worst 102.0 ms, at t = 2.548 s)"),
            std::string::npos)
      << r.report.timing_problems[0];
  EXPECT_TRUE(r.report.timing_machine_limited);
}

TEST(MachineTiming, AnEmulatorLateWithoutAStallOrUnnotedIsNotTheMachines) {
  // A late release a stall does not cover; none noted; more late releases than noted.
  for (const int c : {0, 1, 2}) {
    TimedRun r;
    if (c == 0) r.LateReleases({2.55, 4.0});
    if (c == 1) r.LateReleases({});  // an emulator that wrote no note
    if (c == 2) r.LateReleases({2.55}, 0.05, true);
    r.Stall(2.548, 0.102);
    r.Judge();
    ASSERT_EQ(r.report.timing_problems.size(), 1u) << c;
    EXPECT_EQ(r.report.timing_problems[0].find("machine"), std::string::npos)
        << c << ": " << r.report.timing_problems[0];
    EXPECT_FALSE(r.report.timing_machine_limited) << c;
  }
}

TEST(MachineTiming, NeverWhereTheWitnessCannotSpeak) {
  for (const int c : {0, 1, 2}) {
    TimedRun r;
    if (c == 2) {
      r.LateReleases({1.5});
      r.report.launch.unwatched_ids = {kEmulatorId};
    } else {
      r.Overruns(3, {1.5});
    }
    r.Stall(1.50, 0.030);
    if (c == 0) r.report.launch.unwatched_ids = {3};     // on a host with another kernel
    if (c == 1) r.report.launch.machine.watched = false;  // no real-time priority
    r.Judge();
    ASSERT_EQ(r.report.timing_problems.size(), 1u);
    EXPECT_FALSE(r.report.timing_machine_limited) << c;
  }
}

TEST(MachineTiming, OnTimeRunsAreNotTheMachines) {
  TimedRun r;
  r.Overruns(3, {});
  r.Stall(1.50, 0.030);
  r.Judge();
  EXPECT_TRUE(r.report.timing_ok);
  EXPECT_FALSE(r.report.timing_machine_limited);
}

}  // namespace
}  // namespace shoal
