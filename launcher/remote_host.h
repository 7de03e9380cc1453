// Starting a run's process on another host through its hosts-file prefix, and checking
// each host before anything starts (docs/run.md, "A swarm over several hosts").
#pragma once

#include <sys/types.h>

#include <functional>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "launcher/hosts_file.h"

namespace shoal {

/// What shoal run found out about a host before the run.
struct HostCheck {
  /// Same kernel and time namespace as shoal run: CLOCK_MONOTONIC is the same clock there,
  /// so a real-time run's --t0-ns start time means the same instant (network namespaces).
  bool same_clock = false;
  /// The prefix runs the command in place, in shoal run's pid namespace (ip netns exec
  /// does): the pid shoal run holds is the process's own, so signals, stops, /proc and the
  /// emulator's --recorder-pid reach the process itself. Not through ssh, where the pid
  /// is the local ssh client's.
  bool same_process = false;
  std::string multicast_dev;  // the interface of the host's route for the run's group
  /// How long the probe took through the prefix (s): through ssh, about one login.
  double login_s = 0;
};

/// At most this many processes log in to one host at once (hosts whose prefix does not
/// run in place, HostCheck::same_process false): sshd drops connections still logging in
/// beyond its MaxStartups, by default 10 (then 30 % of them, rising to all at 100).
inline constexpr int kLoginsAtOnce = 8;

/// Paces the starts of a run's processes through logins (ssh), host by host: a process
/// has logged in once it has taken the key line from its pipe (ssh reads its standard
/// input only once the login is done and the command's channel open) or has ended.
class LoginPacer {
 public:
  /// Waits until fewer than kLoginsAtOnce processes started on `host` are logging in, for
  /// at most 30 s (a login that hangs is ssh's to time out), or until `stop` says so.
  void WaitForRoom(const std::string& host, const std::function<bool()>& stop);
  /// Process `pid` was started on `host`; `key_fd`: the write end of its key pipe.
  void Started(const std::string& host, pid_t pid, int key_fd);

 private:
  int LoggingIn(const std::string& host) const;
  std::multimap<std::string, std::pair<pid_t, int>> started_;
};

/// About the longest that starting `count` processes on a host with check `c` takes:
/// 0 where the prefix runs in place, else kLoginsAtOnce at a time, each twice as long as
/// the probe's login took (s).
double LoginSeconds(const HostCheck& c, int count);

/// The command that starts `argv` on host `h` (h.prefix not empty), in the folder `cwd`:
///   PREFIX... sh -c SCRIPT shoal-host CWD ARGV...
/// (each word after the prefix quoted for a shell if h.remote_shell). SCRIPT reads one
/// line from standard input, the run's bus key in hex (or an empty line: no key), exports
/// it as SHOAL_BUS_KEY, and execs argv in place, with a watcher that sends the process
/// SIGTERM once standard input reaches its end: when shoal run closes the pipe, or dies,
/// or the ssh connection to the host is lost. So the key never appears on a command line,
/// and nothing started is left running on the host when the run stops.
std::vector<std::string> HostCommand(const Host& h, const std::vector<std::string>& argv,
                                     const std::string& cwd);

/// A pipe holding `line` and a newline, to be the standard input of a process started by
/// HostCommand; both ends close-on-exec. False with *error if it cannot be made.
bool KeyPipe(const std::string& line, int* read_fd, int* write_fd, std::string* error);

/// `text` quoted for a POSIX shell: 'text', with each ' written as '\''.
std::string ShellQuote(const std::string& text);

/// Checks every host that runs a process of a run with `followers` vehicles, before
/// anything starts: the prefix starts a command there (within 30 s), the host has a route
/// for each of its `groups_by_host` (LCM's udpm sends and joins by it), through the hosts file's
/// `interface` when it gives one and not through loopback when the run spans more than one
/// host, and `ttl` lets the run's messages leave a host when it spans more than one. Finds
/// which hosts share shoal run's CLOCK_MONOTONIC (HostCheck::same_clock: where one does
/// not, a real-time run's start time goes on the wall clock), and that each host in
/// `fifo_hosts` permits SCHED_FIFO at the priority given for it (shoal run --sched-fifo:
/// the highest its processes take; where the host has no chrt to ask, its processes check
/// for themselves at their start). Fills *checks by host name; false with *error.
/// `ttl_fix` says where the TTL is set, for the message when it is 0. Hosts that run no
/// process are not probed: each gets a warning on stderr.
bool CheckHosts(const HostsFile& hosts, int followers,
                const std::map<std::string, std::vector<std::string>>& groups_by_host,
                int ttl, const std::string& ttl_fix, const std::map<std::string, int>& fifo_hosts,
                std::map<std::string, HostCheck>* checks, std::string* error);

/// The multicast group of an udpm:// URL ("" if it is not one).
std::string GroupOfUrl(const std::string& url);

}  // namespace shoal
