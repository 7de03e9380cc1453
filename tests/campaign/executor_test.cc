#include "campaign/executor.h"

#include <gtest/gtest.h>

#include <chrono>
#include <thread>
#include <cstdio>
#include <cstdlib>
#include <map>

namespace shoal {
namespace {

PointJob Shell(std::int64_t index, const std::string& script, double timeout_s = 20) {
  return {index, {"/bin/sh", "-c", script}, timeout_s};
}

std::map<std::int64_t, PointOutcome> RunJobs(const std::vector<PointJob>& jobs, int workers,
                                         bool* finished = nullptr,
                                         std::function<bool()> stop = nullptr) {
  std::map<std::int64_t, PointOutcome> out;
  ExecutorOptions options;
  options.workers = workers;
  options.kill_grace_s = 0.5;
  options.stop_requested = stop;
  options.on_finished = [&](const PointOutcome& o) { out[o.index] = o; };
  const bool done = RunPoints(jobs, options);
  if (finished) *finished = done;
  return out;
}

/// Processes whose command line holds `needle` (a regular expression whose first
/// character is a bracket expression, "[s]leep 1", so that pgrep's shell, whose command
/// line holds the pattern, does not match it).
int CountProcesses(const std::string& needle) {
  FILE* pipe = popen(("pgrep -c -f -- '" + needle + "'").c_str(), "r");
  char text[32] = {0};
  const bool got = pipe && std::fgets(text, sizeof(text), pipe) != nullptr;
  if (pipe) pclose(pipe);
  return got ? std::atoi(text) : -1;
}

/// The count of processes matching `needle` once it is 0, or after 2 s: a process killed
/// with SIGKILL is gone only once the kernel has run it, which on a loaded machine takes a
/// moment after the kill.
int CountProcessesLeft(const std::string& needle) {
  int n = CountProcesses(needle);
  for (int i = 0; i < 200 && n != 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    n = CountProcesses(needle);
  }
  return n;
}

TEST(CampaignExecutor, TellsEveryWayAPointEnds) {
  const auto out = RunJobs({Shell(0, "echo '{\"a\": 1}'; echo note >&2"),
                        Shell(1, "echo oops >&2; exit 3"),
                        Shell(2, "echo last words >&2; kill -SEGV $$"),
                        Shell(3, "echo started >&2; exec sleep 30.125", 0.3)},
                       4);
  ASSERT_EQ(out.size(), 4u);
  EXPECT_EQ(out.at(0).status, PointStatus::kOk);
  EXPECT_EQ(out.at(0).result["a"], 1);
  EXPECT_EQ(out.at(0).exit_status, 0);
  EXPECT_EQ(out.at(0).stderr_tail, "note\n");
  EXPECT_EQ(out.at(1).status, PointStatus::kNoResult);
  EXPECT_EQ(out.at(1).exit_status, 3);
  EXPECT_EQ(out.at(1).why, "no result: exit status 3 without JSON: oops");
  EXPECT_EQ(out.at(2).status, PointStatus::kCrashed);
  EXPECT_EQ(out.at(2).signal, 11);
  EXPECT_EQ(out.at(2).why, "crashed: killed by signal 11 (SIGSEGV): last words");
  EXPECT_EQ(out.at(3).status, PointStatus::kTimeout);
  EXPECT_EQ(out.at(3).why, "timeout: no result after 0.3 s, killed: started");
  EXPECT_GE(out.at(3).wall_s, 0.3);
  EXPECT_LT(out.at(3).wall_s, 5.0);
  EXPECT_EQ(CountProcessesLeft("[s]leep 30.125"), 0);
}

TEST(CampaignExecutor, KillsWhatAPointLeftBehind) {
  // The point exits at once but leaves a process holding its output pipes.
  const auto t0 = std::chrono::steady_clock::now();
  const auto out = RunJobs({Shell(0, "sleep 31.25 & echo '{}'")}, 1);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out.at(0).status, PointStatus::kOk);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 5.0);
  EXPECT_EQ(CountProcessesLeft("[s]leep 31.25"), 0);
}

TEST(CampaignExecutor, RunsWorkersAtATime) {
  std::vector<PointJob> jobs;
  for (int i = 0; i < 3; ++i) jobs.push_back(Shell(i, "sleep 0.4; echo '{}'"));
  auto t0 = std::chrono::steady_clock::now();
  EXPECT_EQ(RunJobs(jobs, 3).size(), 3u);
  const double parallel = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  t0 = std::chrono::steady_clock::now();
  EXPECT_EQ(RunJobs(jobs, 1).size(), 3u);
  const double serial = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_GE(serial, 1.2);
  EXPECT_LT(parallel, serial - 0.5);
}

TEST(CampaignExecutor, StopKillsRunningPointsAndStartsNoMore) {
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<PointJob> jobs = {Shell(0, "echo '{}'")};
  for (int i = 1; i < 5; ++i) jobs.push_back(Shell(i, "trap '' TERM; sleep 33.5"));
  bool finished = true;
  const auto out = RunJobs(jobs, 2, &finished, [&] {
    return std::chrono::steady_clock::now() - t0 > std::chrono::milliseconds(500);
  });
  EXPECT_FALSE(finished);
  ASSERT_EQ(out.size(), 1u);  // the point that ended on its own; none killed by the stop
  EXPECT_EQ(out.at(0).status, PointStatus::kOk);
  // SIGTERM is ignored there: SIGKILL after the grace ends them.
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 5.0);
  EXPECT_EQ(CountProcessesLeft("[s]leep 33.5"), 0);
}

TEST(CampaignExecutor, ReportsAProgramThatCannotStart) {
  const auto out = RunJobs({{0, {"/nonexistent/shoal"}, 5}}, 1);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out.at(0).status, PointStatus::kNoResult);
  EXPECT_EQ(out.at(0).exit_status, 127);
  EXPECT_NE(out.at(0).why.find("cannot run /nonexistent/shoal"), std::string::npos);
}

}  // namespace
}  // namespace shoal
