// The training run of shoal_core's profile-guided build (cmake/pgo.cmake): steps the
// swarm of each scenario given, as shoal sim does, in a build of the core instrumented
// with -fprofile-generate. What it runs decides which branches and calls the optimised
// core lays out as the common case, so it runs what users run most: the paper's
// Example 2 (shoal sim, campaigns) and a REMUS swarm with its limits and events.
// Usage: shoal_pgo_train SECONDS SCENARIO...
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

#include "core/swarm.h"
#include "scenario/loader.h"

namespace {

// Sees every message and decision, as shoal sim's log does, so that the observer's
// calls are part of the profile too.
class CountingObserver : public shoal::SwarmObserver {
 public:
  void OnState(const shoal::StateMsg&) override { ++events; }
  void OnDeliver(int, const shoal::StateMsg&) override { ++events; }
  void OnChannel(const shoal::ChannelDecision&) override { ++events; }
  long events = 0;
};

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s SECONDS SCENARIO...\n", argv[0]);
    return 2;
  }
  const double seconds = std::atof(argv[1]);
  if (!(seconds > 0.0)) {
    std::fprintf(stderr, "%s: SECONDS must be a positive number, not '%s'\n", argv[0], argv[1]);
    return 2;
  }
  try {
    for (int i = 2; i < argc; ++i) {
      const shoal::Scenario s = shoal::LoadScenario(argv[i]);
      shoal::Swarm quiet(s, seconds);
      while (quiet.Step(nullptr)) {
      }
      // A tenth of the time with an observer: shoal sim --out's path.
      CountingObserver seen;
      shoal::Swarm observed(s, seconds / 10.0);
      while (observed.Step(&seen)) {
      }
      std::printf("trained on %s: %g s, %ld observed events\n", argv[i], seconds, seen.events);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", argv[0], e.what());
    return 1;
  }
  return 0;
}
