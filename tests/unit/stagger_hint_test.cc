// shoal run's hints about --no-stagger and --sched-fifo: given exactly when a real-time
// run's loops queued for the CPUs (several late, more loops than CPUs, one host): the first
// for a run unstaggered in a scenario that allows staggering, the second for the others
// whose loops were not all at SCHED_FIFO; never otherwise.
#include <gtest/gtest.h>

#include "launcher/run_report.h"
#include "runtime/process.h"

namespace shoal {
namespace {

// 64 followers in real time, two of them late (beyond the verdict's limits), on two CPUs,
// unstaggered, one host.
struct Late {
  RunReport report;
  LoopPlacement placement;
  Late() {
    report.followers = 64;
    report.launch.mode = ModeName(Mode::kRealtime);
    report.timing_ok = false;
    report.timing_problems = {"vehicle 3: 2 overruns", "vehicle 40: 1 overruns"};
    placement.stagger_allowed = true;
    placement.cpus = 2;
  }
};

TEST(StaggerHint, NamesTheLoopsTheCpusAndTheOption) {
  const Late l;
  const std::string hint = StaggerHint(l.report, l.placement);
  EXPECT_NE(hint.find("the 66 loops woke at the start of each period on 2 CPUs"), std::string::npos)
      << hint;
  EXPECT_NE(hint.find("without --no-stagger"), std::string::npos) << hint;
}

TEST(StaggerHint, AlsoForSeveralSlowLoopsWithinTheVerdict) {
  Late l;
  l.report.timing_ok = true;
  l.report.timing_problems.clear();
  l.report.slow_loops = 2;
  EXPECT_NE(StaggerHint(l.report, l.placement), "");
  l.report.slow_loops = 1;
  EXPECT_EQ(StaggerHint(l.report, l.placement), "") << "one slow loop";
}

TEST(StaggerHint, NoneWhereStaggeringIsNotWhatTheRunLacked) {
  {
    Late l;
    l.report.launch.mode = ModeName(Mode::kLockstep);
    EXPECT_EQ(StaggerHint(l.report, l.placement), "") << "lockstep";
  }
  {
    Late l;
    l.report.timing_problems.resize(1);
    EXPECT_EQ(StaggerHint(l.report, l.placement), "") << "one late process";
  }
  {
    Late l;
    l.report.launch.interrupted = true;
    EXPECT_EQ(StaggerHint(l.report, l.placement), "") << "interrupted";
  }
  {
    Late l;
    l.placement.staggered = true;
    EXPECT_EQ(StaggerHint(l.report, l.placement), "") << "already staggered";
  }
  {
    Late l;
    l.placement.one_host = false;
    EXPECT_EQ(StaggerHint(l.report, l.placement), "") << "several hosts";
  }
  {
    Late l;
    l.placement.stagger_allowed = false;
    EXPECT_EQ(StaggerHint(l.report, l.placement), "") << "delay within one period";
  }
  {
    Late l;
    l.placement.cpus = 66;
    EXPECT_EQ(StaggerHint(l.report, l.placement), "") << "a CPU for every loop";
  }
}

TEST(FifoHint, GivenWhereStaggeredLoopsWereStillLate) {
  Late l;
  l.placement.staggered = true;
  const std::string hint = FifoHint(l.report, l.placement);
  EXPECT_NE(hint.find("several of the 66 loops on 2 CPUs were late"), std::string::npos) << hint;
  EXPECT_NE(hint.find("--sched-fifo all"), std::string::npos) << hint;
  l.report.launch.sched_fifo = kSchedFifoEmulator;
  EXPECT_EQ(FifoHint(l.report, l.placement), hint) << "the emulator alone";
  l.placement.staggered = false;
  l.placement.stagger_allowed = false;
  EXPECT_EQ(FifoHint(l.report, l.placement), hint) << "no room to stagger";
}

TEST(FifoHint, NoneWhereItIsNotWhatTheRunLacked) {
  {
    const Late l;
    EXPECT_NE(StaggerHint(l.report, l.placement), "");
    EXPECT_EQ(FifoHint(l.report, l.placement), "") << "unstaggered: the stagger hint first";
  }
  {
    Late l;
    l.placement.staggered = true;
    l.report.launch.sched_fifo = kSchedFifoAll;
    EXPECT_EQ(FifoHint(l.report, l.placement), "") << "already SCHED_FIFO";
  }
  {
    Late l;
    l.placement.staggered = true;
    l.report.timing_problems.resize(1);
    EXPECT_EQ(FifoHint(l.report, l.placement), "") << "one late process";
  }
  {
    Late l;
    l.placement.staggered = true;
    l.report.launch.mode = ModeName(Mode::kLockstep);
    EXPECT_EQ(FifoHint(l.report, l.placement), "") << "lockstep";
  }
  {
    Late l;
    l.placement.staggered = true;
    l.placement.one_host = false;
    EXPECT_EQ(FifoHint(l.report, l.placement), "") << "several hosts";
  }
  {
    Late l;
    l.placement.staggered = true;
    l.placement.cpus = 66;
    EXPECT_EQ(FifoHint(l.report, l.placement), "") << "a CPU for every loop";
  }
}

}  // namespace
}  // namespace shoal
