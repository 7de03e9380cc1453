// shoal: the command-line tool. main() only parses flags and dispatches.
#include <CLI/CLI.hpp>

#include <iostream>
#include <tuple>

#include "tools/analyze_command.h"
#include "tools/compare_command.h"
#include "tools/design_command.h"
#include "tools/render_command.h"
#include "tools/run_command.h"
#include "tools/sim_command.h"

int main(int argc, char** argv) {
  CLI::App app{"shoal: SIL harness for leader-following UUV formation control"};
  app.require_subcommand(1);

  shoal::SimOptions sim;
  CLI::App* sim_cmd = app.add_subcommand(
      "sim", "Run a scenario's whole swarm in one process, as fast as the CPU allows");
  sim_cmd->add_option("scenario", sim.scenario, "Scenario file (TOML, see docs/scenario.md)")
      ->required();
  sim_cmd->add_option("--out", sim.out, "Write an LCM log (lcm-logplayer format) to this path");
  sim_cmd->add_option("--duration", sim.duration_s,
                      "Simulated seconds (default: the scenario's run.duration_s)");
  sim_cmd->add_flag("--json", sim.json, "Print one JSON object instead of the summary");
  sim_cmd->add_flag("--quiet", sim.quiet, "No progress line");

  shoal::RunOptions run;
  CLI::App* run_cmd = app.add_subcommand(
      "run", "Launch the scenario as a SIL run: one process per vehicle, leader, channel "
             "emulator and lcm-logger, supervised");
  run_cmd->add_option("scenario", run.scenario, "Scenario file (TOML)")->required();
  run_cmd->add_option("--mode", run.mode, "lockstep (deterministic, as fast as possible) or "
                                          "realtime (wall-clock loops)")
      ->check(CLI::IsMember({"lockstep", "realtime"}));
  run_cmd->add_option("--duration", run.duration_s, "Simulated seconds (default: the scenario's)");
  run_cmd->add_option("--out", run.out, "LCM log path (default: <scenario name>.lcmlog)");
  run_cmd->add_option("--lcm-url", run.lcm_url, "Use this LCM URL instead of a private one");
  run_cmd->add_flag("--per-vehicle-urls", run.per_vehicle_urls,
                    "Deliver to each vehicle on its own multicast group (the default with "
                    "the private URL; refused with --lcm-url)");
  run_cmd->add_flag("--shared-url", run.shared_url,
                    "Put every process on the run's one multicast group (every vehicle then "
                    "receives all traffic; the log then also holds SHOAL_RX_<id>)");
  run_cmd->add_option("--max-lookahead", run.max_lookahead,
                      "lockstep: most ticks released per round trip (the smallest delivery "
                      "lag of the channel bounds it; 1 = a round trip every tick)")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  run_cmd->add_flag("--deep-idle", run.deep_idle,
                    "Let idle CPUs halt during the run (by default, as root, shoal run holds "
                    "a 0 us CPU latency request: idle CPUs poll, wake-ups are cheaper)");
  run_cmd->add_flag("--json", run.json, "Print one JSON object instead of the summary");
  run_cmd->add_flag("--quiet", run.quiet, "No progress line");

  shoal::CompareOptions cmp;
  CLI::App* cmp_cmd = app.add_subcommand(
      "compare", "Compare the vehicle states of two logs at matching vehicle and time");
  cmp_cmd->add_option("a", cmp.a, "First LCM log")->required();
  cmp_cmd->add_option("b", cmp.b, "Second LCM log")->required();
  cmp_cmd->add_flag("--json", cmp.json, "Print one JSON object");

  shoal::AnalyzeOptions ana;
  CLI::App* ana_cmd = app.add_subcommand(
      "analyze", "Metrics of a run from its LCM log (or live from a bus): formation errors, "
                 "channel ground truth, process health; JSON and CSV (docs/analyze.md)");
  ana_cmd->add_option("log", ana.log, "LCM log of shoal sim --out, shoal run, or lcm-logger");
  ana_cmd->add_flag("--json", ana.json, "Print one JSON object instead of the summary");
  ana_cmd->add_option("--csv", ana.csv_dir,
                      "Write tidy CSV time series into this directory (created if missing)");
  ana_cmd->add_option("--scenario", ana.scenario,
                      "Scenario file to use instead of the one the log carries");
  ana_cmd->add_flag("--live", ana.live,
                    "Listen on an LCM URL (a running swarm or lcm-logplayer) instead of a log; "
                    "ends on Ctrl-C, when the run finishes, or after --duration");
  ana_cmd->add_option("--lcm-url", ana.lcm_url, "With --live: LCM URL (default: LCM's default)");
  ana_cmd->add_option("--duration", ana.duration_s, "With --live: stop after S wall-clock seconds");
  ana_cmd->add_flag("--quiet", ana.quiet, "No progress line (--live)");
  shoal::DesignOptions design;
  CLI::App* design_cmd = app.add_subcommand(
      "design", "Gains and stability certificates for a scenario: Theorems 1-2, the exact "
                "delay margin, a verdict; optionally the empirical margin and Ceres tuning "
                "(docs/theory.md)");
  design_cmd->add_option("scenario", design.scenario, "Scenario file (TOML)")->required();
  design_cmd->add_flag("--json", design.json, "Print one JSON object instead of the report");
  design_cmd->add_option("--k1", design.k1, "Position gain k1 (default: the scenario's)");
  design_cmd->add_option("--k2", design.k2, "Velocity gain k2 (default: the scenario's)");
  design_cmd->add_option("--h", design.h_s,
                         "Delay bound h in seconds (default: max tau of the scenario's links)");
  design_cmd->add_option("--kappa", design.kappa,
                         "Bound on d tau/dt, in [0, 1) (default: from the delay model)");
  design_cmd->add_option("--alpha", design.alpha, "Theorem 1-2 alpha (default 0.05, the paper's)");
  design_cmd->add_option("--beta", design.beta, "Theorem 1-2 beta (default 6.4, the paper's)");
  design_cmd->add_option("--rho0", design.rho0,
                         "Lipschitz constant of the uncertain factor (default: from the model)");
  design_cmd->add_option("--safety", design.safety,
                         "Required margin as a multiple of h for --tune and advice (default 2)");
  design_cmd->add_option("--certificate", design.certificate,
                         "Write Theorem 3's matrices (Q, Psi, Z, X, Y, Phi) as JSON to this file");
  design_cmd->add_flag("--empirical", design.empirical,
                       "Also find the constant delay at which shoal sim stops converging");
  design_cmd->add_option("--empirical-duration", design.empirical_duration_s,
                         "Simulated seconds per --empirical run (default: the scenario's)");
  design_cmd->add_flag("--tune", design.tune,
                       "Tune k1, k2 with Ceres (min formation error, margin >= safety x h)");
  design_cmd->add_option("--tune-horizon", design.tune_horizon_s,
                         "Simulated seconds per --tune cost evaluation (default 120)");
  design_cmd
      ->add_option("--tune-cost", design.tune_cost,
                   "--tune cost: itse (time-weighted, default), ise, position_ise "
                   "(docs/theory.md)")
      ->check(CLI::IsMember({"itse", "ise", "position_ise"}));

  shoal::RenderOptions ren;
  CLI::App* ren_cmd = app.add_subcommand(
      "render", "Draw a run's figures from its log as PNG, off-screen (OSMesa): 3-D "
                "trajectories, states, tracking errors, the channel");
  ren_cmd->add_option("log", ren.log, "LCM log of shoal sim or shoal run (or re-recorded)")
      ->required();
  ren_cmd->add_option("--out", ren.out_dir, "Directory for the PNG files (created)")->required();
  ren_cmd->add_option("--size", ren.size, "Size of every figure, WxH pixels (default: "
                                          "1400x1000 for 3-D, 1600x1000 for the others)");
  ren_cmd->add_option("--scenario", ren.scenario,
                      "Scenario file to use instead of the one in the log");
  ren_cmd->add_flag("--linear-errors", ren.linear_errors,
                    "Tracking errors on a linear axis (default: logarithmic)");
  ren_cmd->add_flag("--quiet", ren.quiet, "Do not list the files written");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? 0 : 2;
  }
  // -1 is the commands' "not given" marker: a --duration the user typed must be positive.
  for (auto [cmd, flag, value] :
       {std::make_tuple(sim_cmd, "--duration", sim.duration_s),
        std::make_tuple(run_cmd, "--duration", run.duration_s),
        std::make_tuple(design_cmd, "--empirical-duration", design.empirical_duration_s)}) {
    if (cmd->parsed() && cmd->count(flag) > 0 && !(value > 0)) {
      std::cerr << "shoal " << cmd->get_name() << ": " << flag
                << " must be a positive number of seconds (got " << value << ")\n";
      return 2;
    }
  }
  if (sim_cmd->parsed()) return shoal::RunSim(sim);
  if (cmp_cmd->parsed()) return shoal::RunCompare(cmp);
  if (run_cmd->parsed()) return shoal::RunRun(run);
  if (ana_cmd->parsed()) return shoal::RunAnalyze(ana);
  if (design_cmd->parsed()) return shoal::RunDesign(design);
  if (ren_cmd->parsed()) return shoal::RunRender(ren);
  return 2;
}
