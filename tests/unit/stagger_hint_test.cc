// shoal run's hint about --no-stagger: given exactly when a real-time run's loops queued for
// the CPUs (several late, more loops than CPUs, unstaggered, one host, a scenario that
// allows it), and never otherwise.
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

}  // namespace
}  // namespace shoal
