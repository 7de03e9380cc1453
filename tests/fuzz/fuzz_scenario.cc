// Fuzz target: scenario/loader.h's ParseScenario on arbitrary text. Its contract: a
// validated Scenario or a ScenarioError; any other exception, a crash or undefined
// behaviour is a bug.
#include <cstddef>
#include <cstdint>
#include <string>

#include "scenario/loader.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > (64u << 10)) return 0;  // scenario files are a few kB
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    shoal::ParseScenario(text, "fuzz.toml");
  } catch (const shoal::ScenarioError&) {
  }
  return 0;
}
