// Restart (shoal run --restart on-failure): a Follower resumed from its checkpoint goes on
// exactly as the uninterrupted one, given the same neighbour data from then on; the
// checkpoint file survives a write torn by the process's death (the other slot, one tick
// older, is read) and refuses what is not a record of the process asking.
#include "runtime/checkpoint.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <string>

#include "core/follower.h"

namespace shoal {
namespace {

constexpr Micros kPeriod = 20000;

// Two followers: 2 hears 1 and the leader; an ocean current (a random process) disturbs
// them, so that its state must be carried over too.
Scenario TwoFollowersInACurrent() {
  Scenario s;
  s.name = "two";
  s.followers = 2;
  s.edges = {{2, 1}};
  s.leader_links = {1, 2};
  s.k1 = 0.3;
  s.k2 = 1.1;
  s.offsets_m = {Vec3(1.0, -2.0, 0.5), Vec3(-3.0, 0.0, 0.0)};
  s.initial.resize(2);
  s.initial[1].given = true;
  s.initial[1].eta << -4, 5, 6, -0.05, -3.1;
  s.initial[1].nu << 0.5, 0, 0, 0.01, -0.02;
  s.vehicle.integrator_step_s = 0.005;
  s.disturbance.kind = DisturbanceKind::kOceanCurrent;
  s.disturbance.current.noise_mps = 0.3;
  return s;
}

StateMsg Leader(std::int32_t seq, Micros utime) {
  StateMsg m;
  m.vehicle_id = 0;
  m.seq = seq;
  m.utime = utime;
  m.eta << 0.1 * ToSeconds(utime), 0.0, 0.0, 0.0, 0.0;
  m.eta_dot << 0.1, 0.0, 0.0, 0.0, 0.0;
  return m;
}

TEST(FollowerCheckpoint, ResumedFollowerGoesOnAsTheUninterruptedOne) {
  const Scenario s = TwoFollowersInACurrent();
  const Topology topo = Topology::Build(s.followers, s.edges, s.leader_links);
  Follower a(s, topo, 2);
  // Before the checkpoint: ticks without neighbour data (which the resumed one could not
  // have: Resume drops it), the current and the plant evolving.
  for (int k = 0; k < 100; ++k) a.Tick(k * kPeriod);
  const Follower::Checkpoint c = a.MakeCheckpoint();
  EXPECT_EQ(c.published.seq, 99);
  EXPECT_EQ(c.published.utime, 99 * kPeriod);
  Follower b(s, topo, 2);
  b.Resume(c);
  EXPECT_EQ(b.state().eta, a.state().eta);
  EXPECT_EQ(b.counters().ticks, 100);
  // Both without data for a while, then both with the leader's new states (whose send
  // times the resumed one's history covers): the same states, bit for bit.
  for (int k = 100; k < 300; ++k) {
    if (k >= 150) {
      a.Receive(Leader(k, k * kPeriod));
      b.Receive(Leader(k, k * kPeriod));
    }
    const StateMsg ma = a.Tick(k * kPeriod);
    const StateMsg mb = b.Tick(k * kPeriod);
    ASSERT_EQ(ma.seq, mb.seq) << k;
    ASSERT_EQ(ma.eta, mb.eta) << k;
    ASSERT_EQ(ma.tau, mb.tau) << k;
  }
  EXPECT_EQ(a.state().nu, b.state().nu);
}

std::string TmpFile(const std::string& name) {
  return ::testing::TempDir() + "/" + name + "." + std::to_string(getpid());
}

CheckpointPayload Payload(double x) {
  CheckpointPayload p;
  p.Put(x);
  p.Put(std::int32_t{7});
  return p;
}

TEST(CheckpointFile, ReadsTheNewestValidRecord) {
  const std::string path = TmpFile("ckpt");
  std::remove(path.c_str());
  CheckpointRecord r;
  std::string error;
  EXPECT_FALSE(ReadCheckpoint(path, 3, &r, &error));  // no file yet
  {
    CheckpointFile f;
    ASSERT_TRUE(f.Open(path, 0, &error)) << error;
    for (int tick = 0; tick < 5; ++tick) ASSERT_TRUE(f.Write(3, tick, Payload(tick * 1.5)));
  }
  ASSERT_TRUE(ReadCheckpoint(path, 3, &r, &error)) << error;
  EXPECT_EQ(r.tick, 4);
  EXPECT_EQ(r.generation, 4u);
  double x = 0;
  std::int32_t seven = 0;
  ASSERT_TRUE(r.payload.Get(&x) && r.payload.Get(&seven));
  EXPECT_EQ(x, 6.0);
  EXPECT_EQ(seven, 7);
  EXPECT_FALSE(r.payload.Get(&x));  // past the end
  // Another process's file is refused.
  EXPECT_FALSE(ReadCheckpoint(path, 2, &r, &error));
  EXPECT_NE(error.find("no valid checkpoint"), std::string::npos) << error;
  std::remove(path.c_str());
}

TEST(CheckpointFile, TornWriteFallsBackToTheRecordBefore) {
  const std::string path = TmpFile("torn");
  std::remove(path.c_str());
  std::string error;
  std::uint64_t next = 0;
  {
    CheckpointFile f;
    ASSERT_TRUE(f.Open(path, 0, &error)) << error;
    ASSERT_TRUE(f.Write(1, 10, Payload(1.0)));  // slot 0
    ASSERT_TRUE(f.Write(1, 11, Payload(2.0)));  // slot 1
    next = 2;
  }
  // The newest record (slot 1) torn: a byte of its payload changed.
  std::fstream io(path, std::ios::in | std::ios::out | std::ios::binary);
  io.seekg(0, std::ios::end);
  const std::streamoff slot = io.tellg() / 2;
  io.seekp(slot + 40);
  io.put('\x5a');
  io.close();
  CheckpointRecord r;
  ASSERT_TRUE(ReadCheckpoint(path, 1, &r, &error)) << error;
  EXPECT_EQ(r.tick, 10);
  // A process resumed from it goes on writing after it: its next record is the newest.
  {
    CheckpointFile f;
    ASSERT_TRUE(f.Open(path, r.generation + 1, &error)) << error;
    ASSERT_TRUE(f.Write(1, 11, Payload(3.0)));
  }
  ASSERT_TRUE(ReadCheckpoint(path, 1, &r, &error)) << error;
  EXPECT_EQ(r.tick, 11);
  EXPECT_GE(r.generation, next - 1);
  // Both torn: no checkpoint.
  std::fstream both(path, std::ios::in | std::ios::out | std::ios::binary);
  both.seekp(40);
  both.put('\x11');
  both.seekp(slot + 40);
  both.put('\x22');
  both.close();
  EXPECT_FALSE(ReadCheckpoint(path, 1, &r, &error));
  std::remove(path.c_str());
}

}  // namespace
}  // namespace shoal
