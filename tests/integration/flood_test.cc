// A run under a flood of foreign datagrams, as users meet it: `shoal run` (its default
// private bus: a shared group and one group and port per vehicle, ttl=0) while a thread of
// the test floods every one of the run's groups with what LCM accepts on the run's
// channels -- garbage, well-formed vehicle states with the right fingerprint but no trailer
// or another key's, states moved to other channels -- with messages on foreign channel
// names, and with datagrams that are not LCM at all. The verdict must be honest: complete
// (exit 0, every expected state in the log; lockstep: equal to shoal sim) or a loud
// failure that says what was lost and how much; foreign messages are never counted as the
// run's, and what was dropped is counted no higher than what was sent.
#include <arpa/inet.h>
#include <dirent.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <random>
#include <sstream>
#include <thread>
#include <vector>

#include <shoal/vehicle_state_t.hpp>

#include "launcher/run_report.h"
#include "runtime/bus_auth.h"
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
using Clock = std::chrono::steady_clock;

const std::string kExample2 = SourcePath("scenarios/paper_example2.toml");  // 5 followers
constexpr int kFollowers = 5;

std::string CmdLine(pid_t pid) {
  std::string s = ReadFile("/proc/" + std::to_string(pid) + "/cmdline");
  for (char& c : s) c = c == '\0' ? '\n' : c;
  return s;
}

pid_t ParentOf(pid_t pid) {
  const std::string stat = ReadFile("/proc/" + std::to_string(pid) + "/stat");
  const std::size_t close = stat.rfind(')');
  int ppid = -1;
  char state = 0;
  if (close == std::string::npos ||
      std::sscanf(stat.c_str() + close + 1, " %c %d", &state, &ppid) != 2) {
    return -1;
  }
  return ppid;
}

/// The argument after `flag` in the command line of the channel emulator that `run`
/// started ("" until it has started).
std::string EmulatorArg(pid_t run, const std::string& flag) {
  DIR* d = opendir("/proc");
  if (!d) return "";
  std::string found;
  while (const dirent* e = readdir(d)) {
    const int pid = std::atoi(e->d_name);
    if (pid <= 0 || ParentOf(pid) != run) continue;
    std::istringstream args(CmdLine(pid));
    std::vector<std::string> a;
    for (std::string s; std::getline(args, s);) a.push_back(s);
    if (a.empty() || a[0].find("shoal_channel_emulator") == std::string::npos) continue;
    for (std::size_t k = 0; k + 1 < a.size(); ++k) {
      if (a[k] == flag) found = a[k + 1];
    }
  }
  closedir(d);
  return found;
}

/// The socket address of a udpm URL (udpm://GROUP:PORT?...).
sockaddr_in AddressOf(const std::string& url) {
  const std::string hostport = url.substr(7, url.find('?') - 7);
  const std::size_t colon = hostport.rfind(':');
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<std::uint16_t>(std::stoi(hostport.substr(colon + 1))));
  inet_pton(AF_INET, hostport.substr(0, colon).c_str(), &a.sin_addr);
  return a;
}

/// The groups of a run started with the default private bus: [0] the shared one, then
/// vehicle 0..followers's own, then the uplink on which the processes publish to the
/// channel emulator; empty if the run did not start within 10 s.
std::vector<sockaddr_in> RunGroups(pid_t run) {
  const auto t0 = Clock::now();
  while (Clock::now() - t0 < std::chrono::seconds(10)) {
    const std::string shared = EmulatorArg(run, "--lcm-url");
    const std::string vehicles = EmulatorArg(run, "--vehicle-urls");
    const std::string uplink = EmulatorArg(run, "--uplink-url");
    if (!shared.empty() && !vehicles.empty() && !uplink.empty()) {
      std::vector<sockaddr_in> g = {AddressOf(shared)};
      std::istringstream list(vehicles);
      for (std::string u; std::getline(list, u, ',');) g.push_back(AddressOf(u));
      g.push_back(AddressOf(uplink));
      return g;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return {};
}

/// True once some process has a UDP socket bound to `port` (LCM udpm binds its port).
bool WaitForUdpListener(int port, double timeout_s) {
  char hex[8];
  std::snprintf(hex, sizeof(hex), ":%04X ", port);
  const auto t0 = Clock::now();
  while (Clock::now() - t0 < std::chrono::duration<double>(timeout_s)) {
    if (ReadFile("/proc/net/udp").find(hex) != std::string::npos) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return false;
}

/// An LCM datagram (short message: magic "LC02", sequence number, channel, payload).
Bytes Datagram(const std::string& channel, const Bytes& payload, std::uint32_t seq) {
  Bytes d = {'L', 'C', '0', '2'};
  for (int k = 3; k >= 0; --k) d.push_back(static_cast<unsigned char>(seq >> (8 * k)));
  d.insert(d.end(), channel.begin(), channel.end());
  d.push_back(0);
  d.insert(d.end(), payload.begin(), payload.end());
  return d;
}

/// What a flood sent, per kind.
struct FloodCount {
  std::int64_t run_channels = 0;  // LCM messages on the run's channel names
  std::int64_t foreign = 0;       // LCM messages on foreign channel names
  std::int64_t not_lcm = 0;       // datagrams that are not LCM
  std::int64_t shared_run_channels = 0;  // of run_channels: sent to the shared group
  double seconds = 0.0;
  std::int64_t total() const { return run_channels + foreign + not_lcm; }
  double rate() const { return seconds > 0 ? total() / seconds : 0.0; }
};

/// Floods `groups` (RunGroups) from a thread of its own for as long as it lives, at
/// `rate` datagrams per second (0: as fast as it can send).
class Flooder {
 public:
  /// `foreign_only`: only messages on foreign channel names.
  Flooder(std::vector<sockaddr_in> groups, double rate, bool foreign_only = false)
      : groups_(std::move(groups)), rate_(rate), foreign_only_(foreign_only),
        other_key_(bus_auth::NewKey()) {
    fd_ = socket(AF_INET, SOCK_DGRAM, 0);
    const unsigned char ttl = 0, loop = 1;
    setsockopt(fd_, IPPROTO_IP, IP_MULTICAST_TTL, &ttl, sizeof(ttl));
    setsockopt(fd_, IPPROTO_IP, IP_MULTICAST_LOOP, &loop, sizeof(loop));
    Prepare();
    thread_ = std::thread([this] { Loop(); });
  }
  ~Flooder() { Stop(); }
  FloodCount Stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
    if (fd_ >= 0) close(fd_);
    fd_ = -1;
    return count_;
  }

 private:
  struct Message {
    std::size_t group;
    Bytes bytes;
    int kind;  // 0 run channel, 1 foreign, 2 not LCM
  };
  void Add(std::size_t group, const std::string& channel, const Bytes& payload, int kind) {
    msgs_.push_back({group, Datagram(channel, payload, seq_++), kind});
  }
  /// A plausible state of `id` on `channel`: without trailer, and signed with another key.
  void AddStates(std::size_t group, const std::string& channel, int id) {
    vehicle_state_t m{};
    m.utime = 1000000;
    m.vehicle_id = id;
    m.seq = 2000000 + id;
    Bytes p(static_cast<std::size_t>(m.getEncodedSize()));
    m.encode(p.data(), 0, static_cast<int>(p.size()));
    Add(group, channel, p, 0);
    Bytes s = p;
    s.resize(p.size() + bus_auth::kTrailerBytes);
    bus_auth::Sign(other_key_, channel, p.data(), static_cast<int>(p.size()), s.data() + p.size());
    Add(group, channel, s, 0);
  }
  void Prepare() {
    std::mt19937 rng(7);
    auto garbage = [&rng] {
      Bytes b(8 + rng() % 200);
      for (auto& c : b) c = static_cast<unsigned char>(rng());
      return b;
    };
    for (std::size_t g = 0; g < groups_.size(); ++g) {
      // Group 0 is the shared bus (what the logger records), the last the uplink (states
      // and statuses: the clock master's input); group 1 + id between them is vehicle id's
      // own (its deliveries and clock windows).
      const int id = static_cast<int>(g) - 1;
      const bool input = g == 0 || g + 1 == groups_.size();
      const std::vector<std::string> run_channels =
          input ? std::vector<std::string>{"SHOAL_STATE_1", "SHOAL_STATE_0", "SHOAL_STATUS",
                                            "SHOAL_CLOCK"}
                 : std::vector<std::string>{"SHOAL_RX_" + std::to_string(id), "SHOAL_CLOCK"};
      if (foreign_only_) {
        for (int k = 0; k < 6; ++k) Add(g, "FOREIGN_" + std::to_string(rng() % 1000), garbage(), 1);
        continue;
      }
      for (const std::string& ch : run_channels) Add(g, ch, garbage(), 0);
      AddStates(g, run_channels[0], std::max(1, id));
      Add(g, "FOREIGN_" + std::to_string(rng() % 1000), garbage(), 1);
      msgs_.push_back({g, garbage(), 2});
    }
  }
  void SendOne(const Message& m) {
    const sockaddr_in& to = groups_[m.group];
    if (sendto(fd_, m.bytes.data(), m.bytes.size(), 0, reinterpret_cast<const sockaddr*>(&to),
               sizeof(to)) < 0) {
      return;
    }
    if (m.kind == 0) ++count_.run_channels;
    if (m.kind == 0 && m.group == 0) ++count_.shared_run_channels;
    if (m.kind == 1) ++count_.foreign;
    if (m.kind == 2) ++count_.not_lcm;
  }
  void Loop() {
    const auto t0 = Clock::now();
    std::size_t next = 0;
    while (!stop_) {
      // Batches of 1 ms worth at the given rate (200 at once when as fast as it can).
      const int batch = rate_ > 0 ? std::max(1, static_cast<int>(rate_ / 1000)) : 200;
      for (int k = 0; k < batch; ++k) SendOne(msgs_[next++ % msgs_.size()]);
      if (rate_ > 0) {
        const double due_s = count_.total() / rate_;
        std::this_thread::sleep_until(t0 + std::chrono::duration<double>(due_s));
      }
    }
    count_.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  }

  std::vector<sockaddr_in> groups_;
  double rate_;
  bool foreign_only_;
  bus_auth::Key other_key_;
  int fd_ = -1;
  std::vector<Message> msgs_;
  std::uint32_t seq_ = 1;
  FloodCount count_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

/// The flood's rate: `rate`, or SHOAL_TEST_FLOOD_RATE's (datagrams a second, 0: as fast
/// as the test can send) to measure others (docs/benchmarks.md).
double FloodRate(double rate) {
  const char* env = std::getenv("SHOAL_TEST_FLOOD_RATE");
  return env != nullptr ? std::atof(env) : rate;
}

struct FloodedRun {
  int status = -1;
  std::string out;
  nlohmann::ordered_json json;
  FloodCount sent;
};

/// shoal run --json with its default private bus, flooded at `rate` from when its
/// processes have started until it exits.
FloodedRun RunFlooded(const std::string& args, double rate, const std::string& tag,
                      bool foreign_only = false) {
  const std::string out = TmpPath(tag + ".out");
  const pid_t pid = StartShoal("run " + kExample2 + " --json " + args, out);
  FloodedRun r;
  const std::vector<sockaddr_in> groups = RunGroups(pid);
  EXPECT_EQ(groups.size(), 3u + kFollowers) << "the run's groups were not found";
  {
    Flooder f(groups, rate, foreign_only);
    r.status = WaitExit(pid, 120, nullptr);
    r.sent = f.Stop();
  }
  r.out = ReadFile(out);
  r.json = ParseJson(r.out.substr(std::min(r.out.find('{'), r.out.size())));
  std::printf("[%s] exit %d; flood %.0f datagrams/s for %.1f s (%lld sent, %lld on the run's "
              "channels, %lld of them to the shared group); log_states %s of %s, "
              "unauthenticated %s, by process %s, log_problems %s, timing_problems %s, problems %s\n",
              tag.c_str(), r.status, r.sent.rate(), r.sent.seconds,
              static_cast<long long>(r.sent.total()),
              static_cast<long long>(r.sent.run_channels),
              static_cast<long long>(r.sent.shared_run_channels),
              r.json.value("log_states", nlohmann::ordered_json()).dump().c_str(),
              r.json.value("log_states_expected", nlohmann::ordered_json()).dump().c_str(),
              r.json.value("unauthenticated", nlohmann::ordered_json()).dump().c_str(),
              r.json.value("unauthenticated_by_process", nlohmann::ordered_json()).dump().c_str(),
              r.json.value("log_problems", nlohmann::ordered_json()).dump().c_str(),
              r.json.value("timing_problems", nlohmann::ordered_json()).dump().c_str(),
              r.json.value("problems", nlohmann::ordered_json()).dump().c_str());
  return r;
}

/// The verdict of a flooded run is honest: exit 1 exactly when a process failed, the log
/// lost something, a real-time loop was late or the formation did not converge; an
/// incomplete log says how many states were lost; never more states than expected.
void ExpectHonestVerdict(const FloodedRun& r) {
  const auto& j = r.json;
  ASSERT_TRUE(r.status == 0 || r.status == 1) << r.out;
  const double states = j["log_states"].get<double>();
  const double expected = j["log_states_expected"].get<double>();
  EXPECT_LE(states, expected) << "foreign states counted as the run's: " << r.out;
  EXPECT_EQ(j["bus_authenticated"], true) << r.out;
  const bool complete = j["log_complete"] == true;
  EXPECT_EQ(complete, states == expected) << r.out;
  if (!complete) {
    const std::string problems = j["log_problems"].dump();
    EXPECT_NE(problems.find("vehicle states: " + std::to_string(static_cast<long long>(
                                                     expected - states)) + " lost ("),
              std::string::npos)
        << r.out;
  }
  const bool ok = j["all_processes_ok"] == true && complete && j["timing_ok"] == true &&
                  j["converged"] == true;
  EXPECT_EQ(r.status, ok ? 0 : 1) << r.out;
  // The logger hears the shared group: what it recorded of the flood on the run's
  // channels did not authenticate; foreign channel names and non-LCM datagrams are not
  // the run's and are not counted at all.
  const double unauth = j["unauthenticated"].get<double>();
  EXPECT_GT(unauth, 0) << r.out;
  EXPECT_LE(unauth, static_cast<double>(r.sent.shared_run_channels)) << r.out;
  // Each process counts what reached it, never more than was sent to it.
  double by_process = 0;
  for (const auto& [name, n] : j["unauthenticated_by_process"].items()) {
    EXPECT_TRUE(n.is_number()) << name << ": " << r.out;
    if (n.is_number()) by_process += n.get<double>();
  }
  EXPECT_EQ(j["unauthenticated_by_process"].size(), 2u + kFollowers) << r.out;
  EXPECT_GT(j["unauthenticated_by_process"].value("vehicle 3", 0), 0) << r.out;
  EXPECT_LE(by_process, static_cast<double>(r.sent.run_channels)) << r.out;
}

// Lockstep under a flood as fast as the test can send (on this machine about 100,000
// datagrams a second): complete and equal to shoal sim, or a loud failure. 60 s: the
// formation converges at 52.5 s, so an undisturbed run exits 0.
TEST(Flood, LockstepRunUnderAFloodIsCompleteOrSaysWhatWasLost) {
  const std::string log = TmpPath("flood_ls.lcmlog"), sim_log = TmpPath("flood_ls_sim.lcmlog");
  const FloodedRun r = RunFlooded("--duration 60 --out " + log, FloodRate(0), "flood_ls");
  ExpectHonestVerdict(r);
  const int sim_status =
      RunShoal("sim " + kExample2 + " --duration 60 --out " + sim_log, "flood_ls_sim").status;
  EXPECT_EQ(sim_status, 0);
  if (r.json["all_processes_ok"] != true) {
    // Seen once in 32 runs on a loaded machine (load average 10-20): the run took
    // about 5 s longer and its log held a third of the states, loud (exit 1, checked
    // above) but no longer shoal sim's run. Not reproduced since (nor with three CPU
    // hogs beside it); the summary line above prints the problems if it happens again. A
    // process whose LCM queue overflows while it waits for the CPU would do it: lockstep
    // resends nothing, and the emulator declares a vehicle lost after 5 s of silence.
    EXPECT_FALSE(r.json["problems"].empty()) << r.out;
    return;
  }
  // What the log holds is the run shoal sim computes, state by state, complete or not;
  // complete, it is all of it.
  const bool complete = r.json["log_complete"] == true;
  const auto cmp = RunShoal("compare " + log + " " + sim_log + " --json" +
                                (complete ? "" : " --allow-missing"),
                            "flood_ls_cmp");
  EXPECT_EQ(cmp.status, 0) << cmp.out << cmp.err;
  EXPECT_EQ(ParseJson(cmp.out)["max_position_diff_m"].get<double>(), 0.0) << cmp.out;
  if (complete) {
    EXPECT_EQ(r.status, sim_status) << r.out;
  }
}

// Datagrams on foreign channel names only, as fast as the test can send (on this machine
// about 150,000 a second): lcm-logger subscribes to the run's channels only, so they never
// take a place in its 30-message queue, and the log is complete (with every channel name
// it lost 5-40 states in each of 3 runs).
TEST(Flood, ForeignChannelsDoNotCrowdTheRunOutOfItsLog) {
  const std::string log = TmpPath("flood_foreign.lcmlog");
  const std::string sim_log = TmpPath("flood_foreign_sim.lcmlog");
  const FloodedRun r = RunFlooded("--duration 60 --out " + log, 0, "flood_foreign", true);
  EXPECT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(r.json["log_complete"], true) << r.out;
  EXPECT_EQ(r.json["log_states"], r.json["log_states_expected"]) << r.out;
  EXPECT_EQ(r.json["unauthenticated"], 0) << r.out;  // not the run's: not even counted
  RunShoal("sim " + kExample2 + " --duration 60 --out " + sim_log, "flood_foreign_sim");
  const auto cmp = RunShoal("compare " + log + " " + sim_log + " --json", "flood_foreign_cmp");
  EXPECT_EQ(cmp.status, 0) << cmp.out << cmp.err;
  EXPECT_EQ(ParseJson(cmp.out)["max_position_diff_m"].get<double>(), 0.0) << cmp.out;
}

// Real time under a flood of 20,000 datagrams a second: complete, or a loud failure (a
// lost state, a late loop). 4 s do not let the formation converge: the exit status is 1
// either way, and the test checks that the report says why.
TEST(Flood, RealtimeRunUnderAFloodIsCompleteOrSaysWhatWasLost) {
  const std::string log = TmpPath("flood_rt.lcmlog");
  const FloodedRun r = RunFlooded("--mode realtime --duration 4 --out " + log,
                                  FloodRate(20000), "flood_rt");
  ExpectHonestVerdict(r);
}

// Forgeries sent straight to one vehicle's own group (port) reach that vehicle only: the
// log never sees them, the report counts them from the vehicle's own count, exactly.
TEST(Flood, ForgeriesOnAVehiclesOwnPortAreCountedByThatVehicle) {
  const std::string log = TmpPath("flood_own.lcmlog"), out = TmpPath("flood_own.out");
  // 600 s of mission: 5-25 s of lockstep here, long after the last forgery (0.5 s).
  const pid_t pid = StartShoal("run " + kExample2 + " --per-vehicle-urls --duration 600 --out " +
                                   log, out);
  const std::vector<sockaddr_in> groups = RunGroups(pid);
  ASSERT_EQ(groups.size(), 3u + kFollowers);
  // 2000 states of vehicle 1 as deliveries to vehicle 3, half without a trailer, half
  // signed with another key, over 0.5 s, well before the run ends.
  const bus_auth::Key other = bus_auth::NewKey();
  const int fd = socket(AF_INET, SOCK_DGRAM, 0);
  const unsigned char ttl = 0;
  setsockopt(fd, IPPROTO_IP, IP_MULTICAST_TTL, &ttl, sizeof(ttl));
  const sockaddr_in to = groups[1 + 3];
  // Once vehicle 3 listens, and once the log grows (the clock master starts a lockstep
  // run only when every vehicle is ready): its socket is bound before it subscribes, and
  // LCM drops what arrives in between unseen and uncounted (about 100 here, once).
  ASSERT_TRUE(WaitForUdpListener(ntohs(to.sin_port), 10));
  for (int k = 0; k < 200; ++k) {
    struct stat st {};
    if (stat(log.c_str(), &st) == 0 && st.st_size > (64 << 10)) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  const std::string channel = "SHOAL_RX_3";
  int sent = 0;
  for (int k = 0; k < 2000; ++k) {
    vehicle_state_t m{};
    m.utime = 20000 * k;
    m.vehicle_id = 1;
    m.seq = 3000000 + k;
    Bytes p(static_cast<std::size_t>(m.getEncodedSize()));
    m.encode(p.data(), 0, static_cast<int>(p.size()));
    if (k % 2) {
      p.resize(p.size() + bus_auth::kTrailerBytes);
      const int n = static_cast<int>(p.size()) - bus_auth::kTrailerBytes;
      bus_auth::Sign(other, channel, p.data(), n, p.data() + n);
    }
    const Bytes d = Datagram(channel, p, static_cast<std::uint32_t>(k));
    sent += sendto(fd, d.data(), d.size(), 0, reinterpret_cast<const sockaddr*>(&to),
                   sizeof(to)) == static_cast<ssize_t>(d.size());
    if (k % 100 == 99) std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  close(fd);
  ASSERT_EQ(sent, 2000);
  const int status = WaitExit(pid, 120, nullptr);
  const std::string text = ReadFile(out);
  EXPECT_EQ(status, 0) << text;
  EXPECT_NE(text.find("the processes dropped 2000 messages that did not authenticate "
                      "(vehicle 3 2000)"), std::string::npos)
      << text;
  EXPECT_EQ(text.find("messages on the bus did not authenticate"), std::string::npos) << text;
  EXPECT_EQ(text.find("not known what"), std::string::npos) << text;
}

// shoal run reads each process's count back from the line it writes on exit, the last
// one in its output; a process that wrote none (killed) is reported as not known.
TEST(Flood, EachProcesssCountIsReadBackFromItsExitLine) {
  std::int64_t n = -1;
  bus_auth::Setting keyed;
  keyed.key = bus_auth::NewKey();
  const std::string line = "vehicle 3: " + bus_auth::ExitNote(keyed, 123456789012) + "\n";
  EXPECT_TRUE(bus_auth::ParseExitNote("started\nvehicle 3: 5 ticks\n" + line, &n));
  EXPECT_EQ(n, 123456789012);
  EXPECT_TRUE(bus_auth::ParseExitNote(line + "vehicle 3: " + bus_auth::ExitNote(keyed, 7), &n));
  EXPECT_EQ(n, 7);
  bus_auth::Setting insecure;
  insecure.insecure = true;
  EXPECT_FALSE(bus_auth::ParseExitNote("vehicle 3: " + bus_auth::ExitNote(insecure, 0), &n));
  EXPECT_FALSE(bus_auth::ParseExitNote("", &n));
  EXPECT_FALSE(bus_auth::ParseExitNote(" message(s) failed authentication (dropped)", &n));
  EXPECT_FALSE(bus_auth::ParseExitNote(
      "x: 99999999999999999999 message(s) failed authentication (dropped)", &n));

  RunReport r;
  r.launch.key = bus_auth::NewKey();
  r.launch.unauthenticated_by_process = {{"channel emulator", 0}, {"vehicle 2", -1},
                                         {"vehicle 3", 40}, {"vehicle 4", 2}};
  const auto j = RunReportJson(r);
  EXPECT_EQ(j["unauthenticated_by_process"]["vehicle 3"], 40);
  EXPECT_TRUE(j["unauthenticated_by_process"]["vehicle 2"].is_null());
  const std::string path = TmpPath("flood_report.txt");
  std::FILE* f = std::fopen(path.c_str(), "w");
  ASSERT_NE(f, nullptr);
  PrintRunReport(r, f);
  std::fclose(f);
  const std::string text = ReadFile(path);
  EXPECT_NE(text.find("the processes dropped 42 messages that did not authenticate "
                      "(vehicle 3 40, vehicle 4 2)"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("not known what vehicle 2 dropped"), std::string::npos) << text;
}

}  // namespace
}  // namespace shoal
