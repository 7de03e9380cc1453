// Helpers for tests that run the real `shoal` executable.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <thread>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <cstdint>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace shoal::testing {

/// Time limits of the tests hold for the program as shipped; a sanitizer build runs it
/// 2-5 times slower (docs/benchmarks.md, "Sanitizers"), so its limits are this much wider.
/// The AddressSanitizer build is also compiled at -O1: reading a 1.8 MB scenario took it
/// 5.3-6.0 s against 0.56-0.63 s as shipped, on a loaded 2-vCPU VM.
#if defined(SHOAL_SANITIZED) && defined(__SANITIZE_ADDRESS__)
inline constexpr double kTimeLimitScale = 8.0;
#elif defined(SHOAL_SANITIZED)
inline constexpr double kTimeLimitScale = 4.0;
#else
inline constexpr double kTimeLimitScale = 1.0;
#endif

inline std::string ShoalBinary() { return std::string(SHOAL_BINARY_DIR) + "/tools/shoal"; }
inline std::string SourcePath(const std::string& rel) {
  return std::string(SHOAL_SOURCE_DIR) + "/" + rel;
}

/// A command's --json output, parsed. An output that is not one JSON object fails the
/// test (and gives an empty object). Read numbers with .get<double>(): it throws, and so
/// fails the test, where a number is null or missing.
inline nlohmann::ordered_json ParseJson(const std::string& text) {
  nlohmann::ordered_json j = nlohmann::ordered_json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!j.is_object()) {
    ADD_FAILURE() << "not a JSON object: " << text;
    return nlohmann::ordered_json::object();
  }
  return j;
}

inline std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

struct RunResult {
  int status = -1;  // exit status, or 128 + signal
  std::string out;
  std::string err;
};

/// Runs `args` (a shell-quoted argument string) with the shoal binary, under `prefix` (a
/// command such as setpriv's that runs the rest) if one is given.
inline RunResult RunShoal(const std::string& args, const std::string& tag,
                          const std::string& prefix = "") {
  const std::string dir = std::string(SHOAL_BINARY_DIR) + "/test_tmp";
  std::system(("mkdir -p " + dir).c_str());
  const std::string out = dir + "/" + tag + ".out", err = dir + "/" + tag + ".err";
  const std::string cmd = (prefix.empty() ? "" : prefix + " ") + ShoalBinary() + " " + args +
                          " >" + out + " 2>" + err + " </dev/null";
  const int raw = std::system(cmd.c_str());
  RunResult r;
  if (WIFEXITED(raw)) {
    r.status = WEXITSTATUS(raw);
  } else if (WIFSIGNALED(raw)) {
    r.status = 128 + WTERMSIG(raw);
  }
  r.out = ReadFile(out);
  r.err = ReadFile(err);
  return r;
}

inline std::string TmpPath(const std::string& name) {
  const std::string dir = std::string(SHOAL_BINARY_DIR) + "/test_tmp";
  std::system(("mkdir -p " + dir).c_str());
  return dir + "/" + name;
}

/// Starts `shoal ARGS` in the background, output to out_file; returns its pid.
inline pid_t StartShoal(const std::string& args, const std::string& out_file) {
  const pid_t pid = fork();
  if (pid == 0) {
    // With --json, stdout is the report alone: what the run says as it goes (restarts,
    // problems) goes to stderr, here <out_file>.err.
    const bool json = (" " + args + " ").find(" --json ") != std::string::npos;
    const std::string cmd = "exec " + shoal::testing::ShoalBinary() + " " + args + " >" +
                            out_file + (json ? " 2>" + out_file + ".err" : " 2>&1") +
                            " </dev/null";
    execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  return pid;
}

/// Waits up to timeout_s for pid; returns its exit status, or 256 + signal if a signal
/// killed it (never confused with an exit status), -1 on timeout
/// (then it is killed). took_s, if given, receives the time it took.
inline int WaitExit(pid_t pid, double timeout_s, double* took_s) {
  const auto t0 = std::chrono::steady_clock::now();
  int status = 0;
  for (;;) {
    if (waitpid(pid, &status, WNOHANG) == pid) break;
    if (std::chrono::steady_clock::now() - t0 > std::chrono::duration<double>(timeout_s)) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      return -1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  if (took_s) *took_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return WIFEXITED(status) ? WEXITSTATUS(status) : 256 + WTERMSIG(status);
}

/// A process's command line, its arguments joined by spaces ("" once it is gone).
inline std::string CmdLine(pid_t pid) {
  std::string s = ReadFile("/proc/" + std::to_string(pid) + "/cmdline");
  for (char& c : s) c = c == '\0' ? ' ' : c;
  return s;
}

/// The parent pid of pid from /proc/<pid>/stat (after the command name in parentheses);
/// -1 once it is gone.
inline pid_t ParentOf(pid_t pid) {
  const std::string stat = ReadFile("/proc/" + std::to_string(pid) + "/stat");
  const std::size_t close = stat.rfind(')');
  if (close == std::string::npos) return -1;
  char state = 0;
  int ppid = -1;
  if (std::sscanf(stat.c_str() + close + 1, " %c %d", &state, &ppid) != 2) return -1;
  return ppid;
}

/// The state letter of /proc/<pid>/stat ('R', 'S', 'T', 'Z', ...), 0 once pid is gone.
inline char ProcessState(pid_t pid) {
  const std::string stat = ReadFile("/proc/" + std::to_string(pid) + "/stat");
  const std::size_t close = stat.rfind(')');
  return close == std::string::npos || close + 2 >= stat.size() ? 0 : stat[close + 2];
}

/// Sends `bytes` as one UDP datagram to the group and port of a udpm URL
/// (udpm://GROUP:PORT?...), with TTL 0: as any user of the host can.
inline void SendUdpDatagram(const std::string& url, const std::vector<unsigned char>& bytes) {
  const std::string hostport = url.substr(7, url.find('?') - 7);
  const std::size_t colon = hostport.rfind(':');
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(static_cast<std::uint16_t>(std::stoi(hostport.substr(colon + 1))));
  ASSERT_EQ(inet_pton(AF_INET, hostport.substr(0, colon).c_str(), &to.sin_addr), 1) << url;
  const int fd = socket(AF_INET, SOCK_DGRAM, 0);
  ASSERT_GE(fd, 0);
  const unsigned char ttl = 0, loop = 1;
  setsockopt(fd, IPPROTO_IP, IP_MULTICAST_TTL, &ttl, sizeof(ttl));
  setsockopt(fd, IPPROTO_IP, IP_MULTICAST_LOOP, &loop, sizeof(loop));
  EXPECT_EQ(sendto(fd, bytes.data(), bytes.size(), 0, reinterpret_cast<const sockaddr*>(&to),
                   sizeof(to)),
            static_cast<ssize_t>(bytes.size()));
  close(fd);
}

/// An LCM fragment ("LC03": sequence 12, message size, offset, fragment number and count)
/// followed by `rest`.
inline std::vector<unsigned char> LcmFragment(std::uint32_t size, std::uint32_t offset,
                                              std::uint16_t no, std::uint16_t count,
                                              const std::string& rest) {
  std::vector<unsigned char> d = {'L', 'C', '0', '3', 0, 0, 0, 12};
  for (const std::uint32_t v : {size, offset}) {
    for (int k = 3; k >= 0; --k) d.push_back(static_cast<unsigned char>(v >> (8 * k)));
  }
  for (const std::uint16_t v : {no, count}) {
    d.push_back(static_cast<unsigned char>(v >> 8));
    d.push_back(static_cast<unsigned char>(v));
  }
  d.insert(d.end(), rest.begin(), rest.end());
  return d;
}

/// Datagrams in LCM's format whose headers do not add up, each of which made LCM 1.3.1's
/// receive thread write outside its buffers or read past the datagram.
inline std::vector<std::vector<unsigned char>> ForgedLcmDatagrams() {
  const std::string channel = std::string("SHOAL_STATE_1") + '\0' + "z";
  return {LcmFragment(11853913, 0xffffffffu, 0, 35, channel),  // the offset wraps 32 bits
          LcmFragment(100, 0xfffffff0u, 1, 2, "zzzz"),         // a later fragment, too
          LcmFragment(100, 0, 3, 2, channel),                  // numbered beyond its count
          {'L', 'C', '0', '2', 0, 0, 0, 1, 'S', 'H', 'O', 'A', 'L'}};  // a name without NUL
}

}  // namespace shoal::testing
