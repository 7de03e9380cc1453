#include "runtime/process.h"

#include <fcntl.h>
#include <sched.h>
#include <signal.h>
#include <sys/prctl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#include <CLI/CLI.hpp>

#include "runtime/stop_signals.h"
#include "scenario/loader.h"

namespace shoal {

void AddProcessOptions(CLI::App* app, ProcessOptions* opt) {
  app->add_option("--scenario", opt->scenario, "Scenario file (TOML)")->required();
  app->add_option("--set", opt->set,
                  "KEY=VALUE: change the scenario as shoal run was told to (repeatable)")
      ->allow_extra_args(false);
  app->add_option("--lcm-url", opt->lcm_url, "LCM URL of the run's bus")->required();
  app->add_option("--rx-url", opt->rx_url,
                  "LCM URL on which this process receives (default: --lcm-url)");
  app->add_option("--mode", opt->mode, "lockstep or realtime")
      ->check(CLI::IsMember({ModeName(Mode::kLockstep), ModeName(Mode::kRealtime)}));
  app->add_option("--t0-ns", opt->t0_ns, "realtime: CLOCK_MONOTONIC ns of tick 0");
  app->add_option("--duration", opt->duration_s, "Simulated seconds (default: the scenario's)");
  app->add_flag("--insecure", opt->insecure,
                "Do not authenticate the bus's messages (else the run's key is read from "
                "SHOAL_BUS_KEY, docs/run.md)");
}

int StartProcess(CLI::App* app, int argc, char** argv, const std::string& name,
                 const ProcessOptions& opt, Scenario* scenario) {
  try {
    app->parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app->exit(e) == 0 ? 0 : 2;
  }
  InstallProcessSignals();
  return LoadScenarioWithSetsOrReport(name, opt.scenario, opt.set, scenario) ? -1 : 2;
}

void InstallProcessSignals() {
  static StopSignals signals;  // for the life of the process, never restored
  prctl(PR_SET_PDEATHSIG, SIGTERM);
  if (getppid() == 1) StopSignals::Request();  // the parent died before prctl took effect
}

bool StopRequested() { return StopSignals::Requested(); }

std::string EnableRealtimeScheduling(int priority) {
  prctl(PR_SET_TIMERSLACK, 1UL);
  // SCHED_FIFO is opt-in: under load a late FIFO process catching up starves lcm-logger
  // and the others (docs/benchmarks.md, real time).
  if (std::getenv("SHOAL_SCHED_FIFO") == nullptr) return "SCHED_OTHER, timer slack 1 ns";
  sched_param sp = {};
  sp.sched_priority = priority;
  if (sched_setscheduler(0, SCHED_FIFO, &sp) == 0) {
    return "SCHED_FIFO priority " + std::to_string(priority) + ", timer slack 1 ns";
  }
  return std::string("SCHED_OTHER (SCHED_FIFO refused: ") + std::strerror(errno) +
         "), timer slack 1 ns";
}

std::string EnableBatchScheduling() {
  sched_param sp = {};
  sp.sched_priority = 0;
  if (sched_setscheduler(0, SCHED_BATCH, &sp) == 0) return "SCHED_BATCH";
  return std::string("SCHED_OTHER (SCHED_BATCH refused: ") + std::strerror(errno) + ")";
}

CpuLatencyRequest::CpuLatencyRequest() {
  fd_ = open("/dev/cpu_dma_latency", O_WRONLY | O_CLOEXEC);
  if (fd_ < 0) {
    note_ = std::string("no CPU latency request (/dev/cpu_dma_latency: ") + std::strerror(errno) + ")";
    return;
  }
  const std::int32_t zero_us = 0;
  if (write(fd_, &zero_us, sizeof(zero_us)) != static_cast<ssize_t>(sizeof(zero_us))) {
    note_ = std::string("no CPU latency request (write: ") + std::strerror(errno) + ")";
    close(fd_);
    fd_ = -1;
    return;
  }
  note_ = "CPU latency request 0 us held (idle CPUs poll)";
}

CpuLatencyRequest::~CpuLatencyRequest() {
  if (fd_ >= 0) close(fd_);
}

}  // namespace shoal
