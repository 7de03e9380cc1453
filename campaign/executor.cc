#include "campaign/executor.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/types.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <string>

namespace shoal {
namespace {

using Clock = std::chrono::steady_clock;

// A run's JSON is a few kilobytes; a point that prints without end must not exhaust memory.
constexpr std::size_t kMaxStdoutBytes = 64u << 20;
constexpr std::size_t kStderrTailBytes = 4096;
// After the point's process exited, how long its pipes may stay open (held by a process it
// started) before the group is killed and the output taken as it is.
constexpr double kPipeDrainS = 1.0;

struct Running {
  const PointJob* job = nullptr;
  pid_t pid = -1;
  int out_fd = -1, err_fd = -1;
  Clock::time_point start, deadline, kill_at, exited_at;
  bool term_sent = false, timed_out = false, exited = false;
  std::string out, err;
};

double Seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

/// The point index of SHOAL_SWEEP_TEST_FAULT="crash=N", or -1.
std::int64_t TestCrashPoint() {
  const char* fault = std::getenv(kTestFaultEnv);
  if (fault == nullptr || std::strncmp(fault, "crash=", 6) != 0) return -1;
  return std::strtoll(fault + 6, nullptr, 10);
}

/// In the child: its own process group, stdout and stderr to the pipes, default signals.
[[noreturn]] void ExecChild(const PointJob& job, int out_w, int err_w, pid_t parent) {
  setpgid(0, 0);
  // A sweep killed outright (SIGKILL, a Slurm job cancelled) must not leave its points
  // running: SIGTERM lets a `shoal run` point stop its own processes in order.
  prctl(PR_SET_PDEATHSIG, SIGTERM);
  if (getppid() != parent) _exit(127);
  for (const int sig : {SIGINT, SIGTERM, SIGHUP, SIGPIPE, SIGCHLD}) signal(sig, SIG_DFL);
  sigset_t none;
  sigemptyset(&none);
  sigprocmask(SIG_SETMASK, &none, nullptr);
  const int null_fd = open("/dev/null", O_RDONLY);
  if (null_fd >= 0) dup2(null_fd, 0);
  if (null_fd > 2) close(null_fd);
  dup2(out_w, 1);
  dup2(err_w, 2);
  if (job.index == TestCrashPoint()) {
    signal(SIGSEGV, SIG_DFL);  // a sanitizer's handler would turn the crash into an exit
    raise(SIGSEGV);
  }
  std::vector<char*> argv;
  for (const std::string& a : job.argv) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  execv(argv[0], argv.data());
  const std::string message = "cannot run " + job.argv[0] + ": " + std::strerror(errno) + "\n";
  (void)!write(2, message.data(), message.size());
  _exit(127);
}

bool Start(const PointJob& job, Running* r) {
  int out[2], err[2];
  if (pipe2(out, O_CLOEXEC) != 0) return false;
  if (pipe2(err, O_CLOEXEC) != 0) {
    close(out[0]), close(out[1]);
    return false;
  }
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid < 0) {
    for (const int fd : {out[0], out[1], err[0], err[1]}) close(fd);
    return false;
  }
  if (pid == 0) ExecChild(job, out[1], err[1], parent);
  setpgid(pid, pid);  // as the child does: whichever runs first, the group exists
  close(out[1]);
  close(err[1]);
  fcntl(out[0], F_SETFL, O_NONBLOCK);
  fcntl(err[0], F_SETFL, O_NONBLOCK);
  r->job = &job;
  r->pid = pid;
  r->out_fd = out[0];
  r->err_fd = err[0];
  r->start = Clock::now();
  r->deadline = r->start + std::chrono::duration_cast<Clock::duration>(
                               std::chrono::duration<double>(job.timeout_s));
  return true;
}

/// Reads what `fd` holds now; closes it (-1) at end of file.
void Drain(int* fd, std::string* into, bool is_stdout) {
  char buffer[1 << 16];
  while (*fd >= 0) {
    const ssize_t n = read(*fd, buffer, sizeof(buffer));
    if (n > 0) {
      if (!is_stdout || into->size() < kMaxStdoutBytes) into->append(buffer, static_cast<std::size_t>(n));
      if (!is_stdout && into->size() > 2 * kStderrTailBytes) {
        into->erase(0, into->size() - kStderrTailBytes);
      }
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && errno == EAGAIN) return;
    close(*fd);
    *fd = -1;
  }
}

/// The last non-empty line of `text`.
std::string LastLine(const std::string& text) {
  std::size_t end = text.find_last_not_of("\n\r ");
  if (end == std::string::npos) return "";
  const std::size_t begin = text.rfind('\n', end);
  return text.substr(begin == std::string::npos ? 0 : begin + 1,
                     end + 1 - (begin == std::string::npos ? 0 : begin + 1));
}

/// Reaps the exited point (its group killed first, while the zombie leader still holds
/// the group id) and describes how it ended.
PointOutcome Finish(Running* r) {
  kill(-r->pid, SIGKILL);  // anything the point started and left behind
  int status = 0;
  struct rusage usage = {};
  while (wait4(r->pid, &status, 0, &usage) < 0 && errno == EINTR) {
  }
  Drain(&r->out_fd, &r->out, true);
  Drain(&r->err_fd, &r->err, false);
  for (int* fd : {&r->out_fd, &r->err_fd}) {
    if (*fd >= 0) close(*fd), *fd = -1;
  }
  PointOutcome o;
  o.index = r->job->index;
  o.wall_s = Seconds(r->exited_at - r->start);
  o.cpu_s = static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
            1e-6 * static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
  o.stderr_tail = r->err.size() > kStderrTailBytes ? r->err.substr(r->err.size() - kStderrTailBytes)
                                                   : r->err;
  const std::string last = LastLine(o.stderr_tail);
  const std::string said = last.empty() ? "" : ": " + last;
  if (WIFEXITED(status)) o.exit_status = WEXITSTATUS(status);
  if (WIFSIGNALED(status)) o.signal = WTERMSIG(status);
  if (r->timed_out) {
    o.status = PointStatus::kTimeout;
    char text[64];
    std::snprintf(text, sizeof(text), "%g", r->job->timeout_s);
    o.why = std::string("timeout: no result after ") + text + " s, killed" + said;
    return o;
  }
  if (o.signal != 0) {
    o.status = PointStatus::kCrashed;
    const char* name = sigabbrev_np(o.signal);
    o.why = "crashed: killed by signal " + std::to_string(o.signal) +
            (name ? std::string(" (SIG") + name + ")" : "") + said;
    return o;
  }
  o.result = nlohmann::ordered_json::parse(r->out, nullptr, /*allow_exceptions=*/false);
  if (!o.result.is_object()) {
    o.result = nlohmann::ordered_json();
    o.status = PointStatus::kNoResult;
    o.why = "no result: exit status " + std::to_string(o.exit_status) + " without JSON" + said;
    return o;
  }
  o.status = PointStatus::kOk;
  return o;
}

/// Waits up to 0.2 s (less before a deadline) for output of the running points; reads it.
void PollOutput(std::vector<Running>* running) {
  std::vector<pollfd> fds;
  for (const Running& r : *running) {
    for (const int fd : {r.out_fd, r.err_fd}) {
      if (fd >= 0) fds.push_back({fd, POLLIN, 0});
    }
  }
  poll(fds.data(), fds.size(), 200);  // EINTR (a signal, a child's exit): just go on
  for (Running& r : *running) {
    Drain(&r.out_fd, &r.out, true);
    Drain(&r.err_fd, &r.err, false);
  }
}

/// Sends SIGTERM to a point's group, and SIGKILL once its grace has passed.
void Stop(Running* r, double grace_s, Clock::time_point now) {
  if (!r->term_sent) {
    kill(-r->pid, SIGTERM);
    r->term_sent = true;
    r->kill_at = now + std::chrono::duration_cast<Clock::duration>(
                           std::chrono::duration<double>(grace_s));
  } else if (now >= r->kill_at) {
    kill(-r->pid, SIGKILL);
  }
}

/// Notes which running points have exited (without reaping them: see Finish).
void CheckExits(std::vector<Running>* running, Clock::time_point now) {
  for (Running& r : *running) {
    if (r.exited) continue;
    siginfo_t info = {};
    if (waitid(P_PID, static_cast<id_t>(r.pid), &info, WEXITED | WNOHANG | WNOWAIT) == 0 &&
        info.si_pid == r.pid) {
      r.exited = true;
      r.exited_at = now;
    }
  }
}

}  // namespace

const char* PointStatusName(PointStatus status) {
  switch (status) {
    case PointStatus::kOk: return "ok";
    case PointStatus::kCrashed: return "crashed";
    case PointStatus::kTimeout: return "timeout";
    case PointStatus::kNoResult: return "no_result";
  }
  return "no_result";
}

bool RunPoints(const std::vector<PointJob>& jobs, const ExecutorOptions& options) {
  std::vector<Running> running;
  std::size_t next = 0;
  bool stopping = false;
  Clock::time_point last_tick;
  const std::size_t workers = static_cast<std::size_t>(std::max(1, options.workers));
  while (true) {
    stopping = stopping || (options.stop_requested && options.stop_requested());
    while (!stopping && running.size() < workers && next < jobs.size()) {
      Running r;
      if (!Start(jobs[next], &r)) {  // fork or pipe failed: the machine is out of resources
        PointOutcome o;
        o.index = jobs[next].index;
        o.why = std::string("no result: cannot start the point (") + std::strerror(errno) + ")";
        if (options.on_finished) options.on_finished(o);
      } else {
        running.push_back(std::move(r));
      }
      ++next;
    }
    if (running.empty()) break;
    PollOutput(&running);
    const Clock::time_point now = Clock::now();
    CheckExits(&running, now);
    for (auto it = running.begin(); it != running.end();) {
      const bool drained = it->out_fd < 0 && it->err_fd < 0;
      if (it->exited && (drained || Seconds(now - it->exited_at) > kPipeDrainS)) {
        const PointOutcome o = Finish(&*it);
        // A point killed by the stop did not finish; one that ended on its own did.
        const bool killed_by_stop = it->term_sent && !it->timed_out;
        if (!killed_by_stop && options.on_finished) options.on_finished(o);
        it = running.erase(it);
        if (options.on_tick) options.on_tick();
        continue;
      }
      if (!it->exited && (stopping || now >= it->deadline)) {
        if (!stopping) it->timed_out = true;
        Stop(&*it, options.kill_grace_s, now);
      }
      ++it;
    }
    if (options.on_tick && Seconds(now - last_tick) >= 0.2) {
      options.on_tick();
      last_tick = now;
    }
  }
  return !stopping;
}

}  // namespace shoal
