// A published LCM type never changes in place (lcmtypes/README.md): its fingerprint is
// what logs and processes of other builds identify it by. A change of layout fails here;
// it must be a new type with a new name instead.
#include <gtest/gtest.h>

#include <shoal/channel_event_t.hpp>
#include <shoal/channel_events_t.hpp>
#include <shoal/clock_tick_t.hpp>
#include <shoal/clock_window_t.hpp>
#include <shoal/health2_t.hpp>
#include <shoal/health_t.hpp>
#include <shoal/run_status_t.hpp>
#include <shoal/vehicle_state_t.hpp>

namespace shoal {
namespace {

TEST(LcmTypes, PublishedFingerprintsNeverChange) {
  EXPECT_EQ(vehicle_state_t::getHash(), -2171968822570015224LL);
  EXPECT_EQ(clock_window_t::getHash(), -8939641885417601495LL);
  EXPECT_EQ(clock_tick_t::getHash(), 1760966442435609995LL);
  EXPECT_EQ(channel_event_t::getHash(), 4278629453183202832LL);
  EXPECT_EQ(channel_events_t::getHash(), -5988383153357340512LL);
  EXPECT_EQ(health_t::getHash(), 6236032799249078093LL);
  EXPECT_EQ(health2_t::getHash(), 4569272429480244270LL);
  EXPECT_EQ(run_status_t::getHash(), -3852900558415608576LL);
}

}  // namespace
}  // namespace shoal
