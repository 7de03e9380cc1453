// Where the time of shoal sim goes: micro-benchmarks of the core's per-tick pieces.
// Run: build/bench/core_bench   (Google Benchmark; not part of the test pass/fail)
#include <benchmark/benchmark.h>

#include <string>

#include "core/channel_model.h"
#include "core/control.h"
#include "core/swarm.h"
#include "scenario/loader.h"

namespace shoal {
namespace {

const Scenario& Example2() {
  static const Scenario s =
      LoadScenario(std::string(SHOAL_SOURCE_DIR) + "/scenarios/paper_example2.toml");
  return s;
}

void BM_Rk4OneControlPeriod(benchmark::State& st) {
  const FossenModel model;
  PlantState x;
  x.eta << 1, 2, 3, 0.1, 0.5;
  x.nu << 1.2, 0.1, -0.05, 0.01, 0.02;
  const Vec5 tau = (Vec5() << 20, 1, -1, 0.5, 0.2).finished();
  for (auto _ : st) {
    PlantState y = x;
    Integrate(model, tau, Vec3::Zero(), 0.02, 1, &y);
    benchmark::DoNotOptimize(y);
  }
}
BENCHMARK(BM_Rk4OneControlPeriod);

void BM_SaturatedFeedbackLinearise(benchmark::State& st) {
  const FossenModel model;
  const Vec5 eta = (Vec5() << 1, 2, 3, 0.1, 0.5).finished();
  const Vec5 nu = (Vec5() << 1.2, 0.1, -0.05, 0.01, 0.02).finished();
  const Vec5 a = (Vec5() << 0.1, -0.2, 0.05, 0.01, 0.02).finished();
  const Vec5 lim = Vec5::Constant(1e4);
  for (auto _ : st) {
    Vec5 tau;
    benchmark::DoNotOptimize(SaturatedFeedbackLinearise(model, eta, nu, a, lim, &tau));
    benchmark::DoNotOptimize(tau);
  }
}
BENCHMARK(BM_SaturatedFeedbackLinearise);

// One whole tick of paper Example 2 (leader, 5 followers, 10 links, metrics).
void BM_SwarmTickExample2(benchmark::State& st) {
  Swarm swarm(Example2(), 1e9);
  for (auto _ : st) swarm.Step(nullptr);
  st.SetItemsProcessed(st.iterations());
}
BENCHMARK(BM_SwarmTickExample2);

// The channel: one message through the leader's 3 links (submit + later delivery).
void BM_ChannelSubmitDeliver(benchmark::State& st) {
  const Scenario& s = Example2();
  const Topology topo = Topology::Build(s.followers, s.edges, s.leader_links);
  Channel<StateMsg> ch(BuildLinks(s, topo), s.period_us());
  std::vector<ChannelDecision> d;
  StateMsg m;
  Micros t = 0;
  for (auto _ : st) {
    d.clear();
    ch.Submit(0, static_cast<std::int32_t>(t / 20000), t, m, &d);
    ch.DeliverDue(t, [](int, const StateMsg& x) { benchmark::DoNotOptimize(x); });
    t += 20000;
  }
}
BENCHMARK(BM_ChannelSubmitDeliver);

}  // namespace
}  // namespace shoal

BENCHMARK_MAIN();
