// Runs a campaign's points as child processes, a few at a time (docs/campaigns.md). Each
// point is its own process group, so that a hung point and everything it started can be
// killed together, and Ctrl-C on the terminal reaches only `shoal sweep`, which then
// stops the points itself (no process is left behind).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace shoal {

enum class PointStatus { kOk, kCrashed, kTimeout, kNoResult };
const char* PointStatusName(PointStatus status);

struct PointJob {
  std::int64_t index = 0;
  std::vector<std::string> argv;  // argv[0]: the program's path (execv)
  double timeout_s = 60;
};

struct PointOutcome {
  std::int64_t index = 0;
  PointStatus status = PointStatus::kNoResult;
  int exit_status = -1;  // the exit status; -1 when killed by a signal
  int signal = 0;        // the signal that ended it, 0 if it exited
  nlohmann::ordered_json result;  // kOk: the JSON object it printed
  std::string stderr_tail;        // its last stderr lines
  std::string why;  // kCrashed, kTimeout, kNoResult: what happened, with stderr's last line
  double wall_s = 0;
  double cpu_s = 0;  // user + system CPU of the point's process and its waited-for children
};

struct ExecutorOptions {
  int workers = 1;
  double kill_grace_s = 2;  // SIGTERM, then SIGKILL after this long
  /// Polled between steps: true stops starting points and kills those running.
  std::function<bool()> stop_requested;
  /// Called for each point that finished (never for one killed by a stop).
  std::function<void(const PointOutcome&)> on_finished;
  /// Called about every 0.2 s and after each point (progress display).
  std::function<void()> on_tick;
};

/// Runs `jobs` in order, at most options.workers at a time. Returns true if every job
/// finished, false if stopped first (the running points were killed and not reported).
bool RunPoints(const std::vector<PointJob>& jobs, const ExecutorOptions& options);

/// Test-only: SHOAL_SWEEP_TEST_FAULT="crash=N" makes point N's child kill itself with
/// SIGSEGV instead of running, so tests can check how a crashed point is reported (no
/// real run of the harness crashes on demand). Not for users; undocumented in the CLI.
inline constexpr const char* kTestFaultEnv = "SHOAL_SWEEP_TEST_FAULT";

}  // namespace shoal
