// The hosts file of `shoal run --hosts` (docs/run.md, "A swarm over several hosts"): the
// hosts a run spans, the command prefix that starts a process on each, the bus, and which
// host runs which process. Read and validated completely before anything starts; every
// problem is a HostsFileError located as the scenario loader's are:
// "<file>:<line>: <key>: <what> (got <value>); <fix>".
#pragma once

#include <cstddef>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace shoal {

class HostsFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

inline constexpr std::size_t kMaxHostsFileBytes = 1u << 20;
/// The host that runs what the file does not place elsewhere: the one shoal run runs on.
inline constexpr const char* kLocalHostName = "local";

struct Host {
  std::string name;
  /// The command that starts a process there, the process's own command line after it
  /// (["ssh", "-o", "BatchMode=yes", "rack2"], ["ip", "netns", "exec", "h2"]); empty: a
  /// child of shoal run, as without --hosts.
  std::vector<std::string> prefix;
  /// The prefix hands its arguments to a shell on the host as one command line (ssh does):
  /// shoal run then quotes each. Default: true when the prefix's program is ssh.
  bool remote_shell = false;
  /// The interface multicast must leave by there ("": not checked). LCM's udpm URL cannot
  /// choose one (it joins and sends on the interface of the host's route for the group),
  /// so it is checked against that route before the run starts, not passed on.
  std::string interface;
  int line = 0;  // its [[host]] header; 0 for the implicit "local"
};

/// Which processes a hosts file places: the roles besides the vehicles.
enum class HostRole { kLogger, kEmulator, kLeader };

struct HostsFile {
  std::string path;
  std::vector<Host> hosts;  // in file order; "local" is always there (first if implicit)
  /// [bus] url: everything on this one URL (as --lcm-url); "" : the private URL, one
  /// group per vehicle, with `ttl`.
  std::string bus_url;
  int ttl = 1;  // [bus] ttl: 1 crosses a bridge or switch, not a router
  int ttl_line = 0;  // where [bus] ttl is given; 0: not given
  /// Host index of the logger, the emulator and the leader, and of each vehicle placed by
  /// id; everything else runs on `default_host`.
  std::map<HostRole, std::size_t> roles;
  std::map<int, std::size_t> vehicles;
  std::map<int, int> vehicle_lines;  // where each vehicle was placed
  std::size_t default_host = 0;
  int placement_line = 0;

  /// The host that runs vehicle `id` (0: the leader).
  const Host& HostOfVehicle(int id) const;
  const Host& HostOf(HostRole role) const;
  /// Every host that runs a process of a run with `followers` vehicles, each once.
  std::vector<const Host*> UsedHosts(int followers) const;
};

/// Reads and validates `path`; throws HostsFileError.
HostsFile LoadHostsFile(const std::string& path);
/// Validates hosts-file text; `path` names it in messages.
HostsFile ParseHostsFile(const std::string& text, const std::string& path);

/// "" if `hosts` can place a scenario with `followers` vehicles: a vehicle it names must
/// be one of 1..followers. Else the located error.
std::string CheckPlacement(const HostsFile& hosts, int followers);

/// `url` with its ttl parameter set to `ttl` (added if it has none).
std::string UrlWithTtl(const std::string& url, int ttl);
/// The ttl parameter of an LCM URL, as LCM reads it (LCM's default 0 when there is none);
/// -1 if it is not a number.
int TtlOfUrl(const std::string& url);

}  // namespace shoal
