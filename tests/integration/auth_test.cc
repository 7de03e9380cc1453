// Authentication of a run's bus, as users meet it: `shoal run` with real processes over
// UDP multicast on loopback (own port, ttl=0) while a forger on the same host publishes
// forged states, clock windows and statuses (without a trailer, or signed with another
// run's key) and replays the run's own messages. Authenticated, the run's result is what
// it is without the forger and the report counts the forgeries; with --insecure the same
// forger changes the run (so these tests can fail).
#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <mutex>
#include <thread>
#include <vector>

#include <shoal/clock_window_t.hpp>
#include <shoal/run_status_t.hpp>
#include <shoal/vehicle_state_t.hpp>

#include "runtime/bus_auth.h"
#include "runtime/lcm_bus.h"
#include "tests/integration/test_util.h"

namespace shoal {
namespace {

using shoal::testing::ParseJson;
using shoal::testing::ReadFile;
using shoal::testing::RunShoal;
using shoal::testing::SourcePath;
using shoal::testing::StartShoal;
using shoal::testing::TmpPath;
using shoal::testing::WaitExit;
using Bytes = std::vector<unsigned char>;

const std::string kExample2 = SourcePath("scenarios/paper_example2.toml");

std::string Url(int port) {
  return "udpm://239.255.76.67:" + std::to_string(port) + "?ttl=0&recv_buf_size=4194304";
}

template <typename Msg>
Bytes Encode(const Msg& m) {
  Bytes b(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(b.data(), 0, static_cast<int>(b.size()));
  return b;
}

/// The message's own bytes (an authentic message's trailer removed).
Bytes Payload(const lcm::ReceiveBuffer* rb) {
  const auto* p = static_cast<const unsigned char*>(rb->data);
  int n = static_cast<int>(rb->data_size);
  if (bus_auth::HasTrailer(p, n)) n -= bus_auth::kTrailerBytes;
  return Bytes(p, p + n);
}

// Publishes, for as long as it lives, on the run's shared bus: vehicle 1's newest state
// moved 3 m with a newer seq (on SHOAL_STATE_1, and as a delivery to vehicle 2), the
// clock window after the newest one as the run's last, and a "the run was interrupted"
// status -- each without a trailer and signed with another key -- and replays the run's
// own newest state and clock window, trailer and all.
class Forger {
 public:
  explicit Forger(const std::string& url) : lcm_(url), other_key_(bus_auth::NewKey()) {
    lcm_.subscribe("SHOAL_STATE_1", &Forger::OnState, this);
    lcm_.subscribe(bundle_wire::kChannel, &Forger::OnBundle, this);
    lcm_.subscribe("SHOAL_CLOCK", &Forger::OnClock, this);
    thread_ = std::thread([this] { Loop(); });
  }
  ~Forger() {
    stop_ = true;
    thread_.join();
  }
  int forged() const { return forged_; }
  int replayed() const { return replayed_; }

 private:
  void OnState(const lcm::ReceiveBuffer* rb, const std::string&) {
    TakeState(static_cast<const unsigned char*>(rb->data), static_cast<int>(rb->data_size));
  }
  // Lockstep: a process sends its window's states as one recordable bundle, each part
  // the message as it would be alone, trailer and all.
  void OnBundle(const lcm::ReceiveBuffer* rb, const std::string&) {
    bundle_wire::ForEachPart(static_cast<const unsigned char*>(rb->data),
                             static_cast<int>(rb->data_size),
                             [&](std::string_view ch, const unsigned char* d, int n) {
                               if (ch == "SHOAL_STATE_1") TakeState(d, n);
                             });
  }
  void TakeState(const unsigned char* d, int size) {
    int n = size;
    if (bus_auth::HasTrailer(d, n)) n -= bus_auth::kTrailerBytes;
    vehicle_state_t m{};
    if (m.decode(d, 0, n) != n) return;
    if (m.seq > 1000000) return;  // our own
    state_ = m;
    have_state_ = true;
    state_raw_.assign(d, d + size);
  }
  void OnClock(const lcm::ReceiveBuffer* rb, const std::string&) {
    const Bytes p = Payload(rb);
    clock_window_t c{};
    if (c.decode(p.data(), 0, static_cast<int>(p.size())) != static_cast<int>(p.size())) return;
    if (c.seq > 1000000) return;
    clock_ = c;
    have_clock_ = true;
    clock_raw_.assign(static_cast<const unsigned char*>(rb->data),
                      static_cast<const unsigned char*>(rb->data) + rb->data_size);
    ForgeClock();  // at once, to be there before the real next window
  }
  void Send(const std::string& channel, const Bytes& payload) {
    lcm_.publish(channel, payload.data(), static_cast<unsigned>(payload.size()));
    Bytes s = payload;
    s.resize(payload.size() + bus_auth::kTrailerBytes);
    bus_auth::Sign(other_key_, channel, payload.data(), static_cast<int>(payload.size()),
                   s.data() + payload.size());
    lcm_.publish(channel, s.data(), static_cast<unsigned>(s.size()));
    forged_ += 2;
  }
  void ForgeClock() {
    clock_window_t c{};
    c.vehicle_id = -1;
    c.seq = 2000000 + clock_.seq;
    c.tick = clock_.tick + clock_.n_ticks;
    c.n_ticks = 1;
    c.period_us = clock_.period_us;
    c.utime = c.tick * c.period_us;
    c.final_tick = 1;
    c.n_deliveries = 0;
    Send("SHOAL_CLOCK", Encode(c));
  }
  void ForgeState() {
    vehicle_state_t m = state_;
    m.seq = 2000000 + seq_++;
    m.eta[0] += 3.0;
    Send("SHOAL_STATE_1", Encode(m));
    Send("SHOAL_RX_2", Encode(m));
    run_status_t st{};
    st.utime = m.utime;
    st.vehicle_id = -1;
    st.seq = 2000000 + seq_;
    st.state = "interrupted";
    st.scenario_name = "forged";
    st.scenario_toml = "";
    st.followers = 5;
    st.message = "forged";
    Send("SHOAL_STATUS", Encode(st));
    lcm_.publish("SHOAL_STATE_1", state_raw_.data(), static_cast<unsigned>(state_raw_.size()));
    ++replayed_;
    if (!have_clock_) return;  // real time: no clock
    lcm_.publish("SHOAL_CLOCK", clock_raw_.data(), static_cast<unsigned>(clock_raw_.size()));
    ++replayed_;
  }
  void Loop() {
    auto last = std::chrono::steady_clock::now();
    while (!stop_) {
      lcm_.handleTimeout(5);
      if (have_state_ &&
          std::chrono::steady_clock::now() - last > std::chrono::milliseconds(10)) {
        last = std::chrono::steady_clock::now();
        ForgeState();
      }
    }
  }

  lcm::LCM lcm_;
  bus_auth::Key other_key_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<int> forged_{0}, replayed_{0};
  vehicle_state_t state_{};
  clock_window_t clock_{};
  bool have_state_ = false, have_clock_ = false;
  Bytes state_raw_, clock_raw_;
  std::int32_t seq_ = 0;
};

/// shoal run --json in the background with a forger on its bus; the report.
shoal::testing::RunResult RunWithForger(const std::string& args, int port, const std::string& tag,
                                        int* forged) {
  const std::string out = TmpPath(tag + ".out");
  const pid_t pid = StartShoal("run " + kExample2 + " --json --lcm-url '" + Url(port) + "' " +
                                   args, out);
  shoal::testing::RunResult r;
  {
    Forger f(Url(port));
    r.status = WaitExit(pid, 150, nullptr);
    *forged = f.forged();
  }
  r.out = ReadFile(out);
  r.out = r.out.substr(std::min(r.out.find('{'), r.out.size()));
  return r;
}

// Lockstep: the forged run equals shoal sim state by state, its exit status is shoal
// sim's, the forgeries are counted (per channel), never as vehicle states.
TEST(Auth, ForgedMessagesChangeNothingInALockstepRun) {
  const std::string log = TmpPath("auth_ls.lcmlog"), sim_log = TmpPath("auth_ls_sim.lcmlog");
  int forged = 0;
  const auto run = RunWithForger("--duration 20 --out " + log, 31411, "auth_ls", &forged);
  const int sim_status = RunShoal("sim " + kExample2 + " --duration 20 --out " + sim_log,
                                  "auth_ls_sim").status;
  EXPECT_EQ(run.status, sim_status) << run.out;
  EXPECT_GT(forged, 100);
  const auto j = ParseJson(run.out);
  EXPECT_EQ(j["all_processes_ok"], true) << run.out;
  EXPECT_EQ(j["bus_authenticated"], true) << run.out;
  EXPECT_EQ(j["log_states"], j["log_states_expected"]) << run.out;
  EXPECT_EQ(j["log_complete"], true) << run.out;
  // lcm-logger hears every forgery on the shared bus (it may drop some under load).
  EXPECT_GE(j["unauthenticated"].get<double>(), 0.5 * forged) << run.out;
  for (const char* ch : {"SHOAL_STATE_1", "SHOAL_RX_2", "SHOAL_CLOCK", "SHOAL_STATUS"}) {
    EXPECT_GT(j["unauthenticated_by_channel"].value(ch, 0), 0) << ch << run.out;
  }
  const auto cmp = RunShoal("compare " + log + " " + sim_log + " --allow-missing --json",
                            "auth_ls_cmp");
  EXPECT_EQ(cmp.status, 0) << cmp.out << cmp.err;
  const auto cj = ParseJson(cmp.out);
  EXPECT_EQ(cj["max_position_diff_m"].get<double>(), 0.0) << cmp.out;
  EXPECT_GE(cj["samples"].get<double>(), 0.99 * 6.0 * (20 * 50 + 1)) << cmp.out;
  // The processes dropped what reached them, and say so in their output.
  EXPECT_NE(ReadFile(log + ".d/vehicle2.txt").find("failed authentication"), std::string::npos);
  EXPECT_EQ(ReadFile(log + ".d/vehicle2.txt").find(" 0 message(s) failed"), std::string::npos)
      << ReadFile(log + ".d/vehicle2.txt");
  // shoal analyze reads <log>.key by default: the same counts, no forged status.
  const auto ana = RunShoal("analyze " + log + " --json", "auth_ls_ana");
  ASSERT_EQ(ana.status, 0) << ana.err;
  const auto aj = ParseJson(ana.out);
  EXPECT_EQ(aj["bus_authenticated"], true);
  EXPECT_EQ(aj["authentication"]["unauthenticated"], j["unauthenticated"]);
  EXPECT_EQ(aj["log_states"], j["log_states"]);
  EXPECT_EQ(aj["interrupted"], false) << ana.out;
  // Another run's key authenticates nothing; without a key the messages are read
  // unverified, and the analysis says so.
  const std::string other = TmpPath("auth_other.key");
  std::string err;
  ASSERT_TRUE(bus_auth::WriteKeyFile(other, bus_auth::NewKey(), &err)) << err;
  const auto wrong = RunShoal("analyze " + log + " --key " + other, "auth_ls_wrong");
  EXPECT_EQ(wrong.status, 2);
  EXPECT_NE(wrong.err.find("authenticates"), std::string::npos) << wrong.err;
  const auto wrong_cmp = RunShoal("compare " + log + " " + log + " --key-b " + other, "auth_ls_wrong_cmp");
  EXPECT_EQ(wrong_cmp.status, 2) << wrong_cmp.out;
  EXPECT_NE(wrong_cmp.err.find("authenticates"), std::string::npos) << wrong_cmp.err;
  ASSERT_EQ(std::rename((log + ".key").c_str(), (log + ".key.moved").c_str()), 0);
  const auto nokey = RunShoal("analyze " + log + " --json", "auth_ls_nokey");
  ASSERT_EQ(nokey.status, 0) << nokey.err;
  const auto nj = ParseJson(nokey.out);
  EXPECT_EQ(nj["bus_authenticated"], false);
  EXPECT_GT(nj["authentication"]["unverified"].get<double>(), 0);
  EXPECT_NE(nokey.err.find("unverified"), std::string::npos) << nokey.err;
}

// Real time: vehicle 1's forged states (newer seq, the time of now, 3 m off) do not
// displace its real ones: the run follows shoal sim as an unforged real-time run does.
TEST(Auth, ForgedStatesChangeNothingInARealtimeRun) {
  const std::string log = TmpPath("auth_rt.lcmlog"), sim_log = TmpPath("auth_rt_sim.lcmlog");
  int forged = 0;
  const auto run = RunWithForger("--mode realtime --duration 6 --out " + log, 31421, "auth_rt",
                                 &forged);
  RunShoal("sim " + kExample2 + " --duration 6 --out " + sim_log, "auth_rt_sim");
  EXPECT_GT(forged, 100);
  const auto j = ParseJson(run.out);
  EXPECT_EQ(j["all_processes_ok"], true) << run.out;
  EXPECT_GT(j["unauthenticated_by_channel"].value("SHOAL_STATE_1", 0), 0) << run.out;
  // Within the real-time tolerance of Sil.RealtimeRunFollowsTheLockstepRun (seen 2.4e-3 m).
  const auto cmp = RunShoal("compare " + log + " " + sim_log + " --allow-missing" +
                                " --position-tol-m 0.1 --velocity-tol-mps 1e9 --json",
                            "auth_rt_cmp");
  EXPECT_EQ(cmp.status, 0) << cmp.out << cmp.err;
  EXPECT_GE(ParseJson(cmp.out)["samples"].get<double>(), 0.9 * 6.0 * 301) << cmp.out;
}

// --insecure: the same forger does change the run (its forged last clock window ends
// vehicles early), and the report says the bus was not authenticated.
TEST(Auth, WithInsecureTheSameForgerChangesTheRun) {
  const std::string log = TmpPath("auth_insecure.lcmlog"), sim_log = TmpPath("auth_ins_sim.lcmlog");
  int forged = 0;
  const auto run = RunWithForger("--insecure --duration 10 --out " + log, 31431,
                                 "auth_insecure", &forged);
  RunShoal("sim " + kExample2 + " --duration 10 --out " + sim_log, "auth_ins_sim");
  const auto j = ParseJson(run.out);
  EXPECT_EQ(j["bus_authenticated"], false) << run.out;
  EXPECT_EQ(j["key_file"], "") << run.out;
  const auto cmp = RunShoal("compare " + log + " " + sim_log + " --json", "auth_ins_cmp");
  const bool changed = run.status != 1 || j["all_processes_ok"] != true || cmp.status != 0;
  EXPECT_TRUE(changed) << run.out << cmp.out;
  const auto ana = RunShoal("analyze " + log, "auth_ins_ana");
  EXPECT_NE(ana.out.find("--insecure"), std::string::npos) << ana.out;
}

// shoal sim writing its log where a run's log was removes that run's key file: the
// new log then reads as a log without a bus, not as a log of forgeries.
TEST(Auth, ShoalSimReplacingARunLogRemovesItsKey) {
  const std::string log = TmpPath("auth_sim_over_run.lcmlog");
  std::string err;
  ASSERT_TRUE(bus_auth::WriteKeyFile(log + ".key", bus_auth::NewKey(), &err)) << err;
  RunShoal("sim " + kExample2 + " --duration 2 --out " + log, "auth_sim_over_run");
  EXPECT_NE(access((log + ".key").c_str(), F_OK), 0);
  const auto ana = RunShoal("analyze " + log + " --json", "auth_sim_over_run_ana");
  ASSERT_EQ(ana.status, 0) << ana.err;
  EXPECT_EQ(ParseJson(ana.out)["authentication"]["unverified"], 0);
  EXPECT_EQ(ParseJson(ana.out)["authentication"]["unauthenticated"], 0);
}

/// True once some process has a UDP socket bound to `port` (LCM udpm binds its port).
bool WaitForUdpListener(int port, double timeout_s) {
  char hex[8];
  std::snprintf(hex, sizeof(hex), ":%04X ", port);
  const auto t0 = std::chrono::steady_clock::now();
  while (std::chrono::steady_clock::now() - t0 < std::chrono::duration<double>(timeout_s)) {
    if (ReadFile("/proc/net/udp").find(hex) != std::string::npos) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return false;
}

// shoal analyze --live checks what it hears with the run's key (--key FILE here;
// SHOAL_BUS_KEY works alike): a replay of an authenticated log verifies, and the
// analysis equals the log's; with another run's key nothing is taken.
TEST(Auth, LiveAnalysisVerifiesWithTheRunsKey) {
  const std::string log = TmpPath("auth_live.lcmlog");
  const auto run = RunShoal("run " + kExample2 + " --duration 4 --quiet --out " + log, "auth_live_run");
  ASSERT_TRUE(run.status == 0 || run.status == 1) << run.out << run.err;
  const auto file = ParseJson(RunShoal("analyze " + log + " --json", "auth_live_file").out);
  const std::string other = TmpPath("auth_live_other.key");
  std::string err;
  ASSERT_TRUE(bus_auth::WriteKeyFile(other, bus_auth::NewKey(), &err)) << err;
  for (const std::string& key : {log + ".key", other}) {
    const int port = 31451;
    const std::string out = TmpPath("auth_live.out");
    const pid_t ana = StartShoal("analyze --live --json --duration 8 --key " + key +
                                     " --lcm-url '" + Url(port) + "'", out);
    ASSERT_TRUE(WaitForUdpListener(port, 10));
    const std::string play = "lcm-logplayer --speed 4 --lcm-url='" + Url(port) + "' " + log +
                             " >/dev/null 2>&1";
    ASSERT_EQ(std::system(play.c_str()), 0);
    const int status = WaitExit(ana, 20, nullptr);
    const std::string text = ReadFile(out) + ReadFile(out + ".err");  // the JSON, then stderr
    if (key == other) {
      EXPECT_EQ(status, 2) << text;
      EXPECT_NE(text.find("none of them authenticated"), std::string::npos) << text;
      continue;
    }
    ASSERT_EQ(status, 0) << text;
    const auto j = ParseJson(text.substr(std::min(text.find('{'), text.size())));
    EXPECT_EQ(j["bus_authenticated"], true) << text;
    EXPECT_EQ(j["authentication"]["unauthenticated"], 0) << text;
    EXPECT_EQ(j["log_states"], file["log_states"]) << text;
  }
}

// A process started by hand needs the run's key (SHOAL_BUS_KEY) or --insecure: without
// one, or with a malformed one, it refuses to start and says how to give it.
TEST(Auth, ProcessStartedByHandWithoutAKeyRefusesToStart) {
  const std::string vehicle = std::string(SHOAL_BINARY_DIR) + "/vehicle/shoal_vehicle";
  const std::string args = " --scenario " + kExample2 + " --lcm-url '" + Url(31441) +
                           "' --id 1 --duration 0.1";
  const std::string out = TmpPath("auth_byhand.out");
  auto status = [&](const std::string& env) {
    const int raw = std::system((env + " " + vehicle + args + " >" + out + " 2>&1").c_str());
    return WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  };
  EXPECT_EQ(status("env -u SHOAL_BUS_KEY"), 2);
  EXPECT_NE(ReadFile(out).find("SHOAL_BUS_KEY"), std::string::npos) << ReadFile(out);
  EXPECT_NE(ReadFile(out).find("--insecure"), std::string::npos) << ReadFile(out);
  EXPECT_EQ(status("env SHOAL_BUS_KEY=0123"), 2);
  EXPECT_NE(ReadFile(out).find("64 hex digits"), std::string::npos) << ReadFile(out);
  const std::string emulator =
      std::string(SHOAL_BINARY_DIR) + "/channel_emulator/shoal_channel_emulator";
  const int raw = std::system(("env -u SHOAL_BUS_KEY " + emulator + " --scenario " + kExample2 +
                               " --lcm-url '" + Url(31441) + "' >" + out + " 2>&1").c_str());
  EXPECT_EQ(WIFEXITED(raw) ? WEXITSTATUS(raw) : -1, 2) << ReadFile(out);
}

}  // namespace
}  // namespace shoal
