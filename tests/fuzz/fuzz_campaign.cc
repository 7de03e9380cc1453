// Fuzz target: campaign/campaign_file.h's ParseCampaign on arbitrary text. Its contract: a
// validated Campaign or a CampaignError; any other exception, a crash or undefined
// behaviour is a bug.
#include <cstddef>
#include <cstdint>
#include <string>

#include "campaign/campaign_file.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > (64u << 10)) return 0;  // campaign files are a few kB
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    shoal::ParseCampaign(text, "fuzz.toml");
  } catch (const shoal::CampaignError&) {
  }
  return 0;
}
