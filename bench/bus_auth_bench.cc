// Cost of authenticating one bus message (runtime/bus_auth.h): signing it before it is
// published and verifying it on receipt, for the sizes a run sends (docs/benchmarks.md).
#include <benchmark/benchmark.h>

#include <vector>

#include "runtime/bus_auth.h"

namespace {

// A vehicle_state_t is 228 bytes; a lockstep clock window of 3 ticks listing 30 deliveries
// about 900; 8000 bytes is near a large channel batch.
void BM_SignAndVerify(benchmark::State& st) {
  const shoal::bus_auth::Authenticator auth(shoal::bus_auth::NewKey());
  const int size = static_cast<int>(st.range(0));
  std::vector<unsigned char> msg(static_cast<std::size_t>(size) + shoal::bus_auth::kTrailerBytes, 7);
  for (auto _ : st) {
    auth.Sign("SHOAL_STATE_1", msg.data(), size, msg.data() + size);
    const int n = auth.Verify("SHOAL_STATE_1", msg.data(), static_cast<int>(msg.size()));
    benchmark::DoNotOptimize(n);
  }
  st.SetItemsProcessed(st.iterations());
}
BENCHMARK(BM_SignAndVerify)->Arg(228)->Arg(900)->Arg(8000);

// The same, keying HMAC anew for each message (what the pads precomputed save).
void BM_SignAndVerifyRekeyed(benchmark::State& st) {
  const shoal::bus_auth::Key key = shoal::bus_auth::NewKey();
  const int size = static_cast<int>(st.range(0));
  std::vector<unsigned char> msg(static_cast<std::size_t>(size) + shoal::bus_auth::kTrailerBytes, 7);
  for (auto _ : st) {
    shoal::bus_auth::Sign(key, "SHOAL_STATE_1", msg.data(), size, msg.data() + size);
    const int n = shoal::bus_auth::Verify(key, "SHOAL_STATE_1", msg.data(),
                                          static_cast<int>(msg.size()));
    benchmark::DoNotOptimize(n);
  }
  st.SetItemsProcessed(st.iterations());
}
BENCHMARK(BM_SignAndVerifyRekeyed)->Arg(228);

}  // namespace

BENCHMARK_MAIN();
