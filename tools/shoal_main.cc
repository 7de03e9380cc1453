// shoal: the command-line tool. main() only parses flags and dispatches; each command's
// flags are defined by one function below, its work is done by the command (tools/*_command.h)
// and the libraries behind it. Exit statuses: docs/cli.md.
#include <CLI/CLI.hpp>
#include <cmath>
#include <iostream>
#include <string>
#include <vector>

#include "analysis/verdict.h"
#include "design/module.h"
#include "runtime/process.h"
#include "tools/analyze_command.h"
#include "tools/compare_command.h"
#include "tools/design_command.h"
#include "tools/render_command.h"
#include "tools/retime_command.h"
#include "tools/run_command.h"
#include "tools/sim_command.h"
#include "tools/soak_command.h"
#include "tools/sweep_command.h"

namespace {

/// --set KEY=VALUE, repeatable: one argument per occurrence, so that the scenario after
/// it is never taken for a second change.
void AddSetOption(CLI::App* c, std::vector<std::string>* set) {
  c->add_option("--set", *set,
                "Change the scenario: KEY=VALUE, a dotted key and a TOML value "
                "(--set channel.delay.base_s=0.3); repeatable, applied in order "
                "(docs/scenario.md)")
      ->allow_extra_args(false);
}

CLI::App* AddSim(CLI::App* app, shoal::SimOptions* sim) {
  CLI::App* c = app->add_subcommand(
      "sim", "Run a scenario's whole swarm in one process, as fast as the CPU allows");
  c->add_option("scenario", sim->scenario, "Scenario file (TOML, see docs/scenario.md)")
      ->required();
  AddSetOption(c, &sim->set);
  c->add_option("--out", sim->out, "Write an LCM log (lcm-logplayer format) to this path");
  c->add_option("--duration", sim->duration_s,
                "Simulated seconds (default: the scenario's run.duration_s)");
  c->add_flag("--json", sim->json, "Print one JSON object instead of the summary");
  c->add_flag("--quiet", sim->quiet, "No progress line");
  c->add_flag("--allow-large", sim->allow_large,
              "Run even if the run is estimated to take over 1 h or 4 GiB of memory");
  return c;
}

// --sched-fifo all|emulator, for shoal run and shoal soak.
void AddSchedFifoOption(CLI::App* c, std::string* sched_fifo) {
  c->add_option("--sched-fifo", *sched_fifo,
                "Real time: run the loops at SCHED_FIFO, ahead of everything else on the "
                "machine. all: the leader, the vehicles and the channel emulator; emulator: "
                "the emulator alone. Needs CAP_SYS_NICE (root has it) or RLIMIT_RTPRIO >= 50 "
                "(40 where only the leader or vehicles run) on every host concerned: refused before anything starts where not "
                "permitted, and in lockstep. Many loops on few CPUs meet their targets with "
                "all, but a loop that falls behind then takes the CPU from lcm-logger and "
                "the rest, and where real-time tasks are throttled (the default) the "
                "machine's own stalls are not watched (docs/run.md, \"SCHED_FIFO\")")
      ->check(CLI::IsMember({shoal::kSchedFifoAll, shoal::kSchedFifoEmulator}));
}

// shoal run's options for the real-time loops: their start time and their phases.
void AddRunLoopOptions(CLI::App* c, shoal::RunOptions* run) {
  auto* stagger = c->add_flag(
      "--stagger", run->launch.stagger,
      "Real time: spread the followers' loops over half the control period (vehicle i "
      "runs its ticks i/(N+1) of half a period late; each tick still reads only what "
      "reached the host by its time). The default whenever the channel's smallest delay "
      "is above one period; given, such a scenario is required");
  c->add_flag("--no-stagger", run->no_stagger,
              "Real time: wake every loop at the start of its period, all at one instant")
      ->excludes(stagger);
  AddSchedFifoOption(c, &run->launch.sched_fifo);
  c->add_option("--t0-clock", run->t0_clock,
                "realtime: the clock on which the processes are given tick 0: monotonic "
                "(--t0-ns, this host's CLOCK_MONOTONIC) or wall (--t0-unix-ns, "
                "CLOCK_REALTIME, for processes on hosts whose wall clocks agree: NTP "
                "~1-10 ms, PTP us, which bounds how well their ticks line up)")
      ->check(CLI::IsMember({"monotonic", "wall"}))
      ->capture_default_str();
}

CLI::App* AddRun(CLI::App* app, shoal::RunOptions* run) {
  CLI::App* c = app->add_subcommand(
      "run",
      "Launch the scenario as a SIL run: one process per vehicle, leader, channel "
      "emulator and lcm-logger, supervised");
  c->add_option("scenario", run->launch.scenario, "Scenario file (TOML)")->required();
  AddSetOption(c, &run->launch.set);
  c->add_option("--mode", run->launch.mode,
                "lockstep (deterministic, as fast as possible) or "
                "realtime (wall-clock loops)")
      ->check(CLI::IsMember({shoal::ModeName(shoal::Mode::kLockstep),
                                     shoal::ModeName(shoal::Mode::kRealtime)}));
  c->add_option("--duration", run->launch.duration_s,
                "Simulated seconds (default: the scenario's)");
  c->add_option("--out", run->launch.out, "LCM log path (default: <scenario name>.lcmlog)");
  c->add_option("--lcm-url", run->launch.lcm_url, "Use this LCM URL instead of a private one");
  c->add_option("--hosts", run->hosts_file,
                "Run the processes on several hosts, as this hosts file places them "
                "(docs/run.md: A swarm over several hosts)");
  c->add_flag("--per-vehicle-urls", run->launch.per_vehicle_urls,
              "Deliver to each vehicle on its own multicast group (the default with "
              "the private URL; refused with --lcm-url)");
  c->add_flag("--shared-url", run->launch.shared_url,
              "Put every process on the run's one multicast group (every vehicle then "
              "receives all traffic; the log then also holds SHOAL_RX_<id>)");
  c->add_option("--max-lookahead", run->launch.max_lookahead,
                "lockstep: most ticks released per round trip (the channel's delivery "
                "lag at the window's ticks bounds it; 1 = a round trip every tick)")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  c->add_flag("--insecure", run->launch.insecure,
              "Do not authenticate the run's messages (for foreign LCM tools on its bus); "
              "the log's statuses and the report say so");
  c->add_flag("--allow-large", run->launch.allow_large,
              "Run even if the run is estimated to take over 1 h or 4 GiB of memory");
  c->add_flag("--deep-idle", run->launch.deep_idle,
              "Let idle CPUs halt during the run (by default, as root, shoal run holds "
              "a 0 us CPU latency request: idle CPUs poll, wake-ups are cheaper; in real "
              "time, where no cpuidle driver acts on it, a thread per CPU at SCHED_IDLE "
              "keeps the CPUs polling instead)");
  c->add_flag("--keep-going", run->launch.keep_going,
              "A vehicle or the leader that dies or is stopped does not stop the run "
              "(it is reported, and the run fails); by default any such fault stops it");
  c->add_option("--restart", run->restart,
                "on-failure: a vehicle, the leader or the channel emulator that dies (exit "
                "status other than 0, or killed by a signal) is started again, a vehicle "
                "resuming from its last published state; no: any such death stops the run")
      ->check(CLI::IsMember({"no", "on-failure"}))
      ->capture_default_str();
  c->add_option("--max-restarts", run->launch.max_restarts,
                "With --restart on-failure: most restarts per process; one more death "
                "stops the run")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  c->add_option("--resource-interval", run->launch.resource_interval_s,
                "Sample every process's RSS and CPU time at each multiple of this many "
                "mission seconds, and at the end, into <log>.d/resources.csv (0: never)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  AddRunLoopOptions(c, run);
  CLI::Option* print_launch =
      c->add_flag("--print-launch", run->print_launch,
                  "Start nothing: print to stdout a bash script that starts lcm-logger, the "
                  "emulator, the leader and the vehicles with the commands shoal run would "
                  "use (tick 0 on the wall clock; docs/run.md, \"Launching by hand or by "
                  "script\")");
  c->add_flag("--json", run->json, "Print one JSON object instead of the summary")
      ->excludes(print_launch);  // the script is what is printed
  c->add_flag("--quiet", run->quiet, "No progress line");
  return c;
}

CLI::App* AddCompare(CLI::App* app, shoal::CompareOptions* cmp) {
  CLI::App* c = app->add_subcommand(
      "compare", "Compare the vehicle states of two logs at matching vehicle and time");
  c->add_option("a", cmp->a, "First LCM log")->required();
  c->add_option("b", cmp->b, "Second LCM log")->required();
  c->add_option("--position-tol-m", cmp->position_tol_m,
                "Largest position difference (m) that passes; exit 1 beyond it")
      ->capture_default_str();
  c->add_option("--velocity-tol-mps", cmp->velocity_tol_mps,
                "Largest velocity difference (m/s) that passes; exit 1 beyond it")
      ->capture_default_str();
  c->add_flag("--allow-missing", cmp->allow_missing,
              "Compare only the states both logs hold (a log known to be partial); without "
              "it a state in only one log fails the comparison");
  c->add_flag("--json", cmp->json, "Print one JSON object");
  c->add_option("--key-a", cmp->key_a, "Key file of the first log's run (default: a.key if it exists)");
  c->add_option("--key-b", cmp->key_b, "Key file of the second log's run (default: b.key if it exists)");
  return c;
}

CLI::App* AddAnalyze(CLI::App* app, shoal::AnalyzeOptions* ana) {
  CLI::App* c = app->add_subcommand(
      "analyze",
      "Metrics of a run from its LCM log (or live from a bus): formation errors, "
      "channel ground truth, process health; JSON and CSV (docs/analyze.md)");
  c->add_option("log", ana->log, "LCM log of shoal sim --out, shoal run, or lcm-logger");
  c->add_flag("--json", ana->json, "Print one JSON object instead of the summary");
  c->add_option("--csv", ana->csv_dir,
                "Write tidy CSV time series into this directory (created if missing)");
  c->add_option("--scenario", ana->scenario,
                "Scenario file to use instead of the one the log carries");
  c->add_flag("--live", ana->live,
              "Listen on an LCM URL (a running swarm or lcm-logplayer) instead of a log; "
              "ends on Ctrl-C, when the run finishes, after --duration or --until-idle; "
              "exit 3 when the stream missed part of the run");
  c->add_option("--lcm-url", ana->lcm_url, "With --live: LCM URL (default: LCM's default)");
  c->add_option("--duration", ana->duration_s, "With --live: stop after S wall-clock seconds");
  c->add_option("--until-idle", ana->until_idle_s,
                "With --live: stop when no Shoal message arrived for S wall-clock seconds, "
                "after the first one (default 30; 0: never)");
  c->add_flag("--quiet", ana->quiet, "No progress line (--live)");
  c->add_option("--key", ana->key_file,
                "The run's key file: every message must authenticate with it (default: "
                "<log>.key if it exists; --live: SHOAL_BUS_KEY if set)");
  return c;
}

CLI::App* AddRetime(CLI::App* app, shoal::RetimeOptions* ret) {
  CLI::App* c = app->add_subcommand(
      "retime",
      "Copy a run's log with every event stamped at its mission time, so that "
      "lcm-logplayer replays it at the mission's pace (docs/analyze.md, Replay)");
  c->add_option("log", ret->log, "LCM log of shoal run, shoal sim or lcm-logger (only read)")
      ->required();
  c->add_option("--out", ret->out,
                "The retimed log (written atomically; <log>.key is copied to <out>.key)")
      ->required();
  c->add_flag("--force", ret->force, "Replace --out if it exists (never the input log)");
  c->add_flag("--quiet", ret->quiet, "No summary line");
  return c;
}

CLI::App* AddDesign(CLI::App* app, shoal::DesignOptions* design) {
  CLI::App* c = app->add_subcommand(
      "design",
      "Gains and stability certificates for a scenario: Theorems 1-2, the exact "
      "delay margin, a verdict; optionally the empirical margin and Ceres tuning "
      "(docs/theory.md)");
  c->add_option("scenario", design->scenario, "Scenario file (TOML)")->required();
  AddSetOption(c, &design->set);
  c->add_flag("--json", design->json, "Print one JSON object instead of the report");
  c->add_option("--k1", design->k1, "Position gain k1 (default: the scenario's)");
  c->add_option("--k2", design->k2, "Velocity gain k2 (default: the scenario's)");
  c->add_option("--h", design->h_s,
                "Delay bound h in seconds (default: max tau of the scenario's links)");
  c->add_option("--kappa", design->kappa,
                "Bound on d tau/dt, in [0, 1) (default: from the delay model)");
  c->add_option("--alpha", design->alpha, "Theorem 1-2 alpha (default 0.05, the paper's)");
  c->add_option("--beta", design->beta, "Theorem 1-2 beta (default 6.4, the paper's)");
  c->add_option("--rho0", design->rho0,
                "Lipschitz constant of the uncertain factor (default: from the model)");
  c->add_option("--safety", design->safety,
                "Required margin as a multiple of h for --tune and advice (default 2)");
  c->add_option("--certificate", design->certificate,
                "Write Theorem 3's matrices (Q, Psi, Z, X, Y, Phi) as JSON to this file");
  c->add_flag("--empirical", design->empirical,
              "Also find the constant delay at which shoal sim stops converging");
  c->add_option("--empirical-duration", design->empirical_duration_s,
                "Simulated seconds per --empirical run (default: the scenario's)");
  c->add_flag("--tune", design->tune,
              "Tune k1, k2 with Ceres (min formation error, margin >= safety x h)");
  c->add_option("--tune-horizon", design->tune_horizon_s,
                "Simulated seconds per --tune cost evaluation (default 120)");
  c->add_option("--tune-cost", design->tune_cost,
                "--tune cost: itse (time-weighted, default), ise, position_ise "
                "(docs/theory.md)")
      ->check(CLI::IsMember({"itse", "ise", "position_ise"}));
  c->add_flag("--advise", design->advise,
              "Advise gains: the scale (c^2 k1, c k2) Theorem 3 certifies at h, or else the "
              "one it certifies for the largest delay (docs/theory.md)");
  c->add_option("--write-scenario", design->write_scenario,
                "With the advised gains (implies --advise), write the scenario to this TOML "
                "file");
  c->add_flag("--allow-large", design->allow_large,
              "Run even if Theorem 3 is estimated to take over 10 min or 4 GiB of memory");
  return c;
}

CLI::App* AddRender(CLI::App* app, shoal::RenderOptions* ren) {
  CLI::App* c =
      app->add_subcommand("render",
                          "Draw a run's figures from its log as PNG, off-screen (OSMesa): 3-D "
                          "trajectories, states, tracking errors, the channel");
  c->add_option("log", ren->log, "LCM log of shoal sim or shoal run (or re-recorded)")->required();
  c->add_option("--out", ren->out_dir, "Directory for the PNG files (created)")->required();
  c->add_option("--size", ren->size,
                "Size of every figure, WxH pixels (default: "
                "1400x1000 for 3-D, 1600x1000 for the others)");
  c->add_option("--scenario", ren->scenario, "Scenario file to use instead of the one in the log");
  c->add_flag("--linear-errors", ren->linear_errors,
              "Tracking errors on a linear axis (default: logarithmic)");
  c->add_flag("--quiet", ren->quiet, "Do not list the files written");
  c->add_option("--key", ren->key_file,
                "The run's key file: every message must authenticate with it (default: "
                "<log>.key if it exists)");
  return c;
}

CLI::App* AddSweep(CLI::App* app, shoal::SweepOptions* sw, shoal::SweepMergeOptions* merge) {
  CLI::App* c = app->add_subcommand(
      "sweep",
      "Run every point of a campaign (parameter grid or Latin hypercube) as its own shoal "
      "sim/run, judge each by the campaign's pass criteria, write results and the pass/fail "
      "boundary (docs/campaigns.md)");
  c->add_option("campaign", sw->campaign, "Campaign file (TOML, see docs/campaigns.md)");
  c->add_option("--out", sw->out,
                "Output directory: results.jsonl, results.csv, summary.json, "
                "stability_map.png; run again with "
                "the same directory to resume");
  c->add_option("--workers", sw->workers,
                "Points run at a time (default: the campaign's, else one per core; realtime 1)")
      ->check(CLI::Range(1, 1024));
  c->add_option("--shard", sw->shard,
                "K/N: run only the points with index % N == K-1 (combine with sweep merge)");
  c->add_option("--set", sw->set,
                "KEY=VALUE scenario override for every point, applied before the axes "
                "(repeatable)")
      ->allow_extra_args(false);
  c->add_flag("--quiet", sw->quiet, "No progress line and no summary");
  c->add_flag("--allow-large", sw->allow_large,
              "Run points estimated to take over 1 h or 4 GiB each (passed to each point's "
              "shoal sim/run); without it such a campaign is refused before anything runs");
  CLI::App* m = c->add_subcommand(
      "merge", "Combine the output directories of a campaign's shards into one, as one run");
  m->add_option("dirs", merge->dirs, "Shard output directories")->required();
  m->add_option("--out", merge->out, "Output directory")->required();
  m->add_flag("--allow-missing", merge->allow_missing, "Merge even if some points have no row");
  m->add_flag("--allow-overlap", merge->allow_overlap,
              "Merge even if a point has rows in two directories (the first is kept)");
  m->add_flag("--quiet", merge->quiet, "No summary");
  return c;
}

CLI::App* AddSoak(CLI::App* app, shoal::SoakOptions* soak) {
  CLI::App* c = app->add_subcommand(
      "soak",
      "One long SIL run (lockstep or realtime) whose phases step the campaign's channel "
      "values, judged phase by phase and minute by minute: a pass/fail verdict, soak.json and "
      "soak.png (docs/campaigns.md)");
  c->add_option("campaign", soak->campaign, "Campaign file with a [soak] table (TOML)")->required();
  c->add_option("--out", soak->out,
                "Output directory: soak.lcmlog (the run's log), soak.json, soak.png")
      ->required();
  AddSetOption(c, &soak->set);
  AddSchedFifoOption(c, &soak->sched_fifo);
  c->add_flag("--json", soak->json, "Print soak.json instead of the summary");
  c->add_flag("--quiet", soak->quiet, "No progress line");
  c->add_flag("--allow-large", soak->allow_large,
              "Run a soak estimated to take over 1 h of wall time or 4 GiB (a real-time soak "
              "of more than an hour needs it); without it such a soak is refused before "
              "anything runs");
  return c;
}

/// -1 is the commands' "not given" marker: a --duration the user typed must be positive
/// and at most 1e9 s, as the scenario's run.duration_s (inf or 1e30 would count no tick).
bool CheckDuration(const CLI::App* cmd, const char* flag, double value) {
  if (!cmd->parsed() || cmd->count(flag) == 0 || (value > 0 && value <= 1e9)) return true;
  std::cerr << "shoal " << cmd->get_name() << ": " << flag
            << " must be a positive number of seconds, at most 1e9 (got " << value << ")\n";
  return false;
}

/// NaN is the "not given" marker of these options: a NaN the user typed is not a number
/// of seconds (it would mean "not given", and --duration nan would listen for ever).
bool CheckNotNaN(const CLI::App* cmd, const char* flag, double value) {
  if (!cmd->parsed() || cmd->count(flag) == 0 || !std::isnan(value)) return true;
  std::cerr << "shoal " << cmd->get_name() << ": " << flag << " must be a number of seconds (got nan)\n";
  return false;
}

bool IsCommand(const CLI::App& app, const std::string& word) {
  for (const CLI::App* c : app.get_subcommands({})) {
    if (c->check_name(word)) return true;
  }
  return false;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"shoal: SIL harness for leader-following UUV formation control"};
  app.set_version_flag("--version", "shoal " SHOAL_VERSION);
  app.require_subcommand(1);
  shoal::SimOptions sim;
  shoal::RunOptions run;
  shoal::CompareOptions cmp;
  shoal::AnalyzeOptions ana;
  shoal::DesignOptions design;
  shoal::RenderOptions ren;
  CLI::App* sim_cmd = AddSim(&app, &sim);
  CLI::App* run_cmd = AddRun(&app, &run);
  CLI::App* cmp_cmd = AddCompare(&app, &cmp);
  CLI::App* ana_cmd = AddAnalyze(&app, &ana);
  CLI::App* design_cmd = AddDesign(&app, &design);
  CLI::App* ren_cmd = AddRender(&app, &ren);
  shoal::SweepOptions sweep;
  shoal::SweepMergeOptions sweep_merge;
  CLI::App* sweep_cmd = AddSweep(&app, &sweep, &sweep_merge);
  shoal::SoakOptions soak;
  CLI::App* soak_cmd = AddSoak(&app, &soak);
  shoal::RetimeOptions retime;
  CLI::App* retime_cmd = AddRetime(&app, &retime);
  // A word that names no command: CLI11 would say only that a subcommand is required.
  if (argc > 1 && argv[1][0] != '-' && !IsCommand(app, argv[1])) {
    std::string names;
    for (const CLI::App* c : app.get_subcommands({})) {
      names += (names.empty() ? "" : ", ") + c->get_name();
    }
    std::cerr << "shoal: unknown command '" << argv[1] << "'; the commands are " << names
              << " (shoal --help)\n";
    return shoal::kExitBadInput;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? shoal::kExitOk : shoal::kExitBadInput;
  }
  if (!CheckDuration(sim_cmd, "--duration", sim.duration_s) ||
      !CheckDuration(run_cmd, "--duration", run.launch.duration_s) ||
      !CheckDuration(design_cmd, "--empirical-duration", design.empirical_duration_s) ||
      !CheckNotNaN(ana_cmd, "--duration", ana.duration_s) ||
      !CheckNotNaN(ana_cmd, "--until-idle", ana.until_idle_s)) {
    return shoal::kExitBadInput;
  }
  if (sim_cmd->parsed()) return shoal::RunSim(sim);
  if (run_cmd->parsed()) {
    run.command.assign(argv, argv + argc);
    run.command[0] = "shoal";
    return shoal::RunRun(run);
  }
  if (cmp_cmd->parsed()) return shoal::RunCompare(cmp);
  if (ana_cmd->parsed()) return shoal::RunAnalyze(ana);
  if (design_cmd->parsed()) {
    std::string error;
    const shoal::DesignModule* m = shoal::LoadDesignModule(&error);
    if (m == nullptr) {
      std::cerr << "shoal design: " << error << "\n";
      return 2;
    }
    return m->run_design(design);
  }
  if (ren_cmd->parsed()) return shoal::RunRender(ren);
  if (retime_cmd->parsed()) return shoal::RunRetime(retime);
  if (soak_cmd->parsed()) return shoal::RunSoak(soak);
  if (sweep_cmd->parsed()) {
    if (sweep_cmd->get_subcommand("merge")->parsed()) return shoal::RunSweepMerge(sweep_merge);
    if (sweep.campaign.empty() || sweep.out.empty()) {
      std::cerr << "shoal sweep: give a campaign file and --out DIR (see shoal sweep --help)\n";
      return shoal::kExitBadInput;
    }
    return shoal::RunSweep(sweep);
  }
  return shoal::kExitBadInput;
}
