// shoal run's launcher and supervisor: starts lcm-logger, the channel emulator, the leader
// and one process per vehicle, watches them until the run ends or a stop signal arrives,
// and shuts them down in order (docs/run.md). What the run achieved is read afterwards
// from its log (launcher/run_report.h).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/scenario.h"
#include "launcher/hosts_file.h"
#include "launcher/machine_witness.h"
#include "runtime/bus_auth.h"
#include "runtime/process.h"

namespace shoal {

/// LaunchOptions::sched_fifo's values (shoal run --sched-fifo).
inline constexpr const char* kSchedFifoAll = "all";
inline constexpr const char* kSchedFifoEmulator = "emulator";

struct LaunchOptions {
  std::string scenario;  // scenario file, passed on to every process
  std::vector<std::string> set;  // --set KEY=VALUE changes of it, passed on likewise
  std::string mode = ModeName(Mode::kLockstep);  // a ModeName
  double duration_s = -1;    // simulated seconds; -1: the scenario's
  std::string out;           // log path; default <scenario name>.lcmlog
  std::string lcm_url;       // default: a private udpm URL (random port, ttl=0)
  bool per_vehicle_urls = false;  // explicit; the default with the private URL anyway
  bool shared_url = false;        // everything on one group (vehicles hear all traffic)
  long long max_lookahead = 50;   // lockstep: most ticks the clock master releases at once
  bool allow_large = false;  // run even when the estimate exceeds 1 h or 4 GiB (core/swarm.h)
  bool deep_idle = false;  // do not hold the 0 us CPU latency request during the run
  /// Real time: which processes run at SCHED_FIFO (their --sched-fifo): kSchedFifoAll, the
  /// leader, the vehicles and the channel emulator; kSchedFifoEmulator, the emulator alone;
  /// empty, none (unless SHOAL_SCHED_FIFO in the environment they inherit asks). Refused
  /// in lockstep, and where this host does not permit it.
  std::string sched_fifo;
  /// Real time: spread the followers' loop phases over half the control period
  /// (ClockedNode::StaggerPhaseUs, --phase-us), so that N loops do not wake at one instant.
  /// shoal run sets it wherever the scenario allows, unless --no-stagger; shoal soak
  /// wherever it allows.
  bool stagger = false;
  /// A vehicle or the leader that dies or is stopped (SIGSTOP) does not stop the run: it
  /// is reported and the others go on (the verdict fails all the same). Without it, any
  /// process that dies, fails or is stopped stops the whole run at once.
  bool keep_going = false;
  /// --restart on-failure: a vehicle, the leader or the channel emulator that dies (exits
  /// with a status other than 0, or is killed by a signal) is started again; a vehicle or
  /// the leader resumes from its last published state (docs/reliability.md). At most
  /// max_restarts times per process; beyond that it stops the run as without restarts.
  bool restart_on_failure = false;
  int max_restarts = 3;
  bool insecure = false;   // no bus authentication (else a per-run key, docs/run.md)
  /// Every process's RSS and CPU time are sampled at each multiple of this much mission
  /// time (0 s included) and once at the end, into <log>.d/resources.csv (docs/run.md);
  /// 0: not sampled.
  double resource_interval_s = 60.0;
  /// Real time: give the processes tick 0 on the wall clock (--t0-unix-ns, CLOCK_REALTIME
  /// ns), which processes on other hosts can share if the hosts' clocks agree, instead of
  /// on this host's CLOCK_MONOTONIC (--t0-ns). Each process converts it to its monotonic
  /// clock once, at its start. A printed launch script always uses the wall clock.
  bool wall_clock_t0 = false;
  /// --hosts: the hosts the run spans, the bus and which host runs which process
  /// (docs/run.md, "A swarm over several hosts"); none: everything on this host.
  std::optional<HostsFile> hosts;
};

/// Child id of lcm-logger in a plan (not a vehicle id, nor kEmulatorId).
inline constexpr int kLoggerId = -100;

/// Placeholders in PlannedProcess::argv for what is known only once lcm-logger has
/// started: the start time of tick 0 (ns, on the clock the option before it names) and
/// lcm-logger's pid.
inline constexpr const char* kT0Arg = "${t0}";
inline constexpr const char* kLoggerPidArg = "${logger_pid}";

/// Which processes of a run are asked to run at SCHED_FIFO: kSchedFifoAll, kSchedFifoEmulator
/// or "none", from --sched-fifo (`option`, "" if not given) and SHOAL_SCHED_FIFO (`env`,
/// nullptr if unset: "emulator" asks for the emulator, any other value for every real-time
/// process), whichever asks for more. "none" in lockstep, which runs under SCHED_BATCH.
std::string SchedFifoAsked(Mode mode, const std::string& option, const char* env);

/// One process of a run: the command shoal run starts it with, and --print-launch prints.
/// Both are built from the one plan (LaunchPlan), so that they cannot differ.
struct PlannedProcess {
  std::string name;  // "lcm-logger", "channel emulator", "leader", "vehicle 3"
  int id = kLoggerId;  // vehicle id (0: the leader), kEmulatorId or kLoggerId
  std::string tag;     // its output goes to <log>.d/<tag>.txt
  /// The command it runs under, to place it elsewhere (another host, a network namespace);
  /// empty: here. The process's command line is prefix, then argv; shoal run executes its
  /// first word as it is (no PATH search), so it is an absolute path.
  std::vector<std::string> prefix;
  /// argv[0] by absolute path; may hold kT0Arg and kLoggerPidArg.
  std::vector<std::string> argv;
  /// NAME=VALUE set in its environment on top of shoal run's (lcm-logger's LD_PRELOAD).
  std::vector<std::string> env;
  int nice_inc = 0;
  bool gets_key = true;      // the run's key in its environment (all but lcm-logger)
  std::string checkpoint;    // the --checkpoint file it writes ("" none)
  std::vector<std::int64_t> reset_ticks;  // controller resets it stops itself before
};

/// A run's processes, in the order they are started (lcm-logger first), and where they
/// meet.
struct LaunchPlan {
  Mode mode = Mode::kLockstep;
  std::string lcm_url;     // the shared bus
  std::string log;         // what lcm-logger writes
  std::string output_dir;  // <log>.d
  bool insecure = false;
  bool keep_going = false;
  std::vector<PlannedProcess> processes;
};

/// A process that died and was started again (LaunchOptions::restart_on_failure).
struct ProcessRestart {
  std::string process;  // "vehicle 3", "leader", "channel emulator"
  int pid = 0;          // the process that died
  int new_pid = 0;      // the one started in its place
  std::string reason;   // what happened to it ("killed by signal 9 (Killed)")
  double mission_s = 0.0;  // mission time when shoal run saw it die
};

/// The processes' side of a run.
struct LaunchResult {
  std::string mode;
  std::string log;                 // the LCM log lcm-logger wrote
  std::string process_output_dir;  // <log>.d/: each process's stdout and stderr, <name>.txt
  /// <log>.d/resources.csv: the processes' RSS and CPU time during the run ("" when not
  /// sampled: LaunchOptions::resource_interval_s 0, or the file could not be written).
  std::string resources_file;
  std::string lcm_url;
  double duration_s = 0.0;         // simulated seconds asked for
  double wall_time_s = 0.0;        // real time: from the common start time t0
  std::int64_t t0_monotonic_ns = 0;  // real time: t0 on this host's CLOCK_MONOTONIC
  bool interrupted = false;        // SIGINT/SIGTERM/SIGHUP stopped the run
  std::vector<std::string> problems;  // processes that failed, or had to be killed
  /// How lcm-logger ended when it exited before the run did (then the run was stopped at
  /// once: nothing after that point is recorded); empty if it ran to the end.
  std::string logger_exited_early;
  std::string logger_exited_at;  // then: when (mission time, wall clock, time into the run)
  /// then: its last line of output, and whether the disk holding the log is full; each
  /// part starts with "; ".
  std::string logger_exit_note;
  /// The fault that made shoal run stop the run before its end: which process, what
  /// happened to it and when (mission time and wall time); empty if none did.
  std::string stopped_by;
  std::vector<ProcessRestart> restarts;  // in the order they happened
  bool cpu_latency_request = false;   // the 0 us CPU latency request was held
  /// Which processes were asked to run at SCHED_FIFO, by --sched-fifo or SHOAL_SCHED_FIFO
  /// (SchedFifoAsked). Each process's output file says what it got.
  std::string sched_fifo = "none";
  std::string cpu_latency_note;       // what was done about CPU latency, for the summary
  /// The kernel's cpuidle driver ("none": idle CPUs halt whatever is asked), and the
  /// threads that kept the CPUs polling instead (launcher/idle_poller.h; 0: none ran).
  std::string cpuidle_driver;
  int idle_poll_threads = 0;
  double idle_poll_cpu_s = 0.0;  // the CPU time they took (shoal run's own, not the run's)
  /// The run's bus key (none with --insecure), and the file next to the log that holds it.
  std::optional<bus_auth::Key> key;
  std::string key_file;
  /// What each run process ("vehicle 3", "leader", "channel emulator") dropped because it
  /// did not authenticate, as it said on exit in its output file; -1 if it did not say
  /// (killed before its end). Empty with --insecure. Forgeries sent straight to a
  /// vehicle's own group reach that vehicle only: the log never sees them.
  std::map<std::string, std::int64_t> unauthenticated_by_process;
  /// Real time: what the machine itself did during the run (launcher/machine_witness.h),
  /// and the processes it cannot speak for: those on hosts with another kernel (--hosts).
  MachineWatch machine;
  std::vector<int> unwatched_ids;
};

/// Shown while the run goes on.
struct LaunchProgress {
  double sim_time_s = 0.0, duration_s = 0.0;
  double realtime_factor = 0.0;
  double worst_position_error_m = 0.0;  // each follower's newest error, worst of them
  int alive = 0, processes = 0;         // run processes (the logger not counted)
};

struct LaunchCallbacks {
  /// Every 0.5 s wall; when empty the log is not followed during the run.
  std::function<void(const LaunchProgress&)> progress;
  /// A process died, failed or was stopped before the end; `stops_run`: the run is being
  /// stopped because of it (else the others keep running, LaunchOptions::keep_going).
  std::function<void(const std::string& problem, bool stops_run)> problem;
  /// A process died and was started again (LaunchOptions::restart_on_failure).
  std::function<void(const std::string& what)> restarted;
};

/// Runs scenario `s` (loaded from opt.scenario) as separate processes. Returns false with
/// *error if the run cannot start (bad options, unwritable log, missing executables): then
/// nothing was started. Installs stop-signal handlers (SIGINT, SIGTERM, SIGHUP) for its
/// duration. Holds the CPU latency request until every child has stopped.
bool LaunchRun(const Scenario& s, const LaunchOptions& opt, const LaunchCallbacks& callbacks,
               LaunchResult* result, std::string* error);

/// The plan of a run of `s` as LaunchRun would start it with `opt`, except that tick 0 is
/// always on the wall clock (--t0-unix-ns): checks what LaunchRun checks before it starts
/// anything, but writes nothing and leaves the loopback route alone (the script checks
/// it). Refused (false with *error) for what a script cannot do: --restart on-failure,
/// and a scenario that resets a vehicle's controller (shoal run restarts that process).
bool PlanLaunch(const Scenario& s, const LaunchOptions& opt, LaunchPlan* plan,
                std::string* error);

}  // namespace shoal
