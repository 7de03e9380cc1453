// Cost of authenticating one bus message (runtime/bus_auth.h): signing it before it is
// published and verifying it on receipt, for the sizes a run sends (docs/benchmarks.md).
#include <benchmark/benchmark.h>

#include <sodium.h>

#include <string>
#include <vector>

#include "runtime/bus_auth.h"

namespace {

// A vehicle_state_t is 228 bytes; a lockstep clock window of 3 ticks listing 30 deliveries
// about 900; a vehicle's window bundle (its deliveries and clock) about 2700; 8000 bytes is
// near a large channel batch.
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
BENCHMARK(BM_SignAndVerify)->Arg(228)->Arg(900)->Arg(2700)->Arg(8000);

// The same with HMAC-SHA-512/256 and its pads computed once, what a run's trailer held
// before SipHash (and what older logs still hold).
void BM_HmacSignAndVerify(benchmark::State& st) {
  const shoal::bus_auth::Key key = shoal::bus_auth::NewKey();
  crypto_auth_hmacsha512256_state keyed;
  crypto_auth_hmacsha512256_init(&keyed, key.data(), key.size());
  const int size = static_cast<int>(st.range(0));
  std::vector<unsigned char> msg(static_cast<std::size_t>(size), 7);
  const std::string channel = "SHOAL_STATE_1";
  unsigned char mac[crypto_auth_hmacsha512256_BYTES], check[crypto_auth_hmacsha512256_BYTES];
  auto tag = [&](unsigned char* out) {
    crypto_auth_hmacsha512256_state s = keyed;
    crypto_auth_hmacsha512256_update(&s, reinterpret_cast<const unsigned char*>(channel.c_str()),
                                     channel.size() + 1);  // the channel and its NUL
    crypto_auth_hmacsha512256_update(&s, msg.data(), msg.size());
    crypto_auth_hmacsha512256_final(&s, out);
  };
  for (auto _ : st) {
    tag(mac);
    tag(check);
    benchmark::DoNotOptimize(sodium_memcmp(mac, check, sizeof(mac)));
  }
  st.SetItemsProcessed(st.iterations());
}
BENCHMARK(BM_HmacSignAndVerify)->Arg(228)->Arg(900)->Arg(2700)->Arg(8000);

}  // namespace

BENCHMARK_MAIN();
