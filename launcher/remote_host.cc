#include "launcher/remote_host.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/ioctl.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <chrono>
#include <cstring>
#include <set>
#include <sstream>
#include <thread>

#include "runtime/process.h"

namespace shoal {
namespace {

// $1: the folder to run in; the key line on standard input; then the command. The
// watcher keeps the process's start time (field 22 of /proc/PID/stat, which exec does not
// change) so that it never signals another process that took the pid after it ended.
// Standard input is handed to the watcher as fd 3: a background command of a
// non-interactive shell reads /dev/null otherwise.
constexpr const char* kWrapper =
    "cd -- \"$1\" || exit 126; shift; "
    "IFS= read -r k || { echo 'shoal run: no key line on standard input' >&2; exit 125; }; "
    "if [ -n \"$k\" ]; then SHOAL_BUS_KEY=$k; export SHOAL_BUS_KEY; "
    "else unset SHOAL_BUS_KEY; fi; unset k; "
    "s=$(cut -d' ' -f22 /proc/$$/stat); exec 3<&0; "
    "( cat <&3; [ \"$(cut -d' ' -f22 /proc/$$/stat 2>/dev/null)\" = \"$s\" ] && kill -TERM $$ ) "
    ">/dev/null 2>&1 & "
    "exec \"$@\" 3<&- </dev/null";

// Prints what CheckHosts compares with shoal run's own; $1: the interface the hosts file
// names ("" for none), then the groups.
// fifo<P>: whether SCHED_FIFO priority P may be had there ("ok", chrt's refusal, or "nochrt":
// not known, and each process checks for itself).
static_assert(kNodeFifoPriority == 40 && kEmulatorFifoPriority == 50,
              "kProbe's chrt asks for the priorities a run's processes take");
constexpr const char* kProbe =
    "echo \"pid=$$\"; "
    "echo \"boot=$(cat /proc/sys/kernel/random/boot_id 2>/dev/null)\"; "
    "echo \"timens=$(readlink /proc/$$/ns/time 2>/dev/null)\"; "
    "echo \"pidns=$(readlink /proc/$$/ns/pid 2>/dev/null)\"; "
    "echo \"netns=$(readlink /proc/$$/ns/net 2>/dev/null)\"; "
    "i=$1; shift; "
    "if [ -n \"$i\" ]; then case \"$i\" in .|..) ;; *) [ -d \"/sys/class/net/$i\" ] && "
    "echo iface=ok;; esac; echo \"ifaces=$(ls /sys/class/net 2>/dev/null | tr '\\n' ' ')\"; fi; "
    "for p in 40 50; do "
    "if ! command -v chrt >/dev/null 2>&1; then echo \"fifo$p=nochrt\"; "
    "elif chrt -f $p true 2>/dev/null; then echo \"fifo$p=ok\"; "
    "else echo \"fifo$p=$(chrt -f $p true 2>&1 | head -n 1)\"; fi; done; "
    "for g in \"$@\"; do echo \"route $g=$(ip route get \"$g\" 2>&1 | head -n 1)\"; done";

constexpr int kProbeTimeoutS = 30;

/// The words after the prefix: as they are, or quoted for the host's shell.
std::vector<std::string> Prefixed(const Host& h, const std::vector<std::string>& words) {
  std::vector<std::string> cmd = h.prefix;
  for (const std::string& w : words) cmd.push_back(h.remote_shell ? ShellQuote(w) : w);
  return cmd;
}

/// `program` as found on PATH (shoal run's Spawn execs without a search), or as it is.
std::string OnPath(const std::string& program) {
  const char* path = std::getenv("PATH");
  if (program.find('/') != std::string::npos || path == nullptr) return program;
  std::istringstream dirs(path);
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    const std::string candidate = (dir.empty() ? "." : dir) + "/" + program;
    if (access(candidate.c_str(), X_OK) == 0) return candidate;
  }
  return program;
}

std::string ReadLink(const char* path) {
  char buf[256];
  const ssize_t n = readlink(path, buf, sizeof(buf) - 1);
  return n > 0 ? std::string(buf, static_cast<std::size_t>(n)) : "";
}

std::string ReadLine(const char* path) {
  std::string s;
  if (FILE* f = std::fopen(path, "r")) {
    char buf[256];
    if (std::fgets(buf, sizeof(buf), f)) s = buf;
    std::fclose(f);
  }
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
  return s;
}

/// Runs `argv` (stdin /dev/null, stdout and stderr into *out) for at most `timeout_s`;
/// returns its waitpid status (-1: could not run, or killed at the time limit: *timed_out)
/// and its pid in *pid.
int RunCapture(const std::vector<std::string>& argv, int timeout_s, std::string* out,
               pid_t* pid, bool* timed_out) {
  int fds[2];
  *timed_out = false;
  if (pipe2(fds, O_CLOEXEC) != 0) return -1;
  *pid = fork();
  if (*pid == 0) {
    setpgid(0, 0);
    const int devnull = open("/dev/null", O_RDONLY);
    if (devnull >= 0) dup2(devnull, 0);
    dup2(fds[1], 1);
    dup2(fds[1], 2);
    std::vector<char*> args;
    for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    execvp(args[0], args.data());
    std::fprintf(stderr, "cannot run %s: %s\n", args[0], std::strerror(errno));
    _exit(127);
  }
  close(fds[1]);
  if (*pid < 0) {
    close(fds[0]);
    return -1;
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(timeout_s);
  char buf[4096];
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
        deadline - std::chrono::steady_clock::now());
    pollfd p = {fds[0], POLLIN, 0};
    const int ready = left.count() <= 0 ? 0 : poll(&p, 1, static_cast<int>(left.count()));
    if (ready < 0 && errno == EINTR) continue;  // a signal: wait again, within the time
    if (ready == 0) {
      *timed_out = true;
      kill(-*pid, SIGKILL);
      break;
    }
    if (ready < 0) break;
    const ssize_t n = read(fds[0], buf, sizeof(buf));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    if (out->size() < (1u << 16)) out->append(buf, static_cast<std::size_t>(n));
  }
  close(fds[0]);
  int status = 0;
  while (waitpid(*pid, &status, 0) < 0 && errno == EINTR) {
  }
  return *timed_out ? -1 : status;
}

std::string Joined(const std::vector<std::string>& words) {
  std::string s;
  for (const std::string& w : words) s += (s.empty() ? "" : " ") + w;
  return s;
}

std::string LastLine(std::string text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
  const std::size_t nl = text.rfind('\n');
  return nl == std::string::npos ? text : text.substr(nl + 1);
}

std::map<std::string, std::string> Fields(const std::string& out) {
  std::map<std::string, std::string> f;
  std::istringstream lines(out);
  std::string line;
  while (std::getline(lines, line)) {
    const std::size_t eq = line.find('=');
    if (eq != std::string::npos) f[line.substr(0, eq)] = line.substr(eq + 1);
  }
  return f;
}

/// The interface in `ip route get` output ("... dev veth1 table local src ..."), or "".
std::string RouteDev(const std::string& route) {
  const std::size_t at = route.find(" dev ");
  if (at == std::string::npos) return "";
  const std::size_t start = at + 5;
  return route.substr(start, route.find(' ', start) - start);
}

std::string Where(const HostsFile& hosts, const Host& h) {
  return h.line > 0 ? " (" + hosts.path + ":" + std::to_string(h.line) + ")" : "";
}

/// Runs the probe on host h; false with *error if it does not answer as expected.
bool Probe(const HostsFile& hosts, const Host& h, const std::vector<std::string>& groups,
           std::map<std::string, std::string>* fields, bool* in_place, double* seconds,
           std::string* error) {
  std::vector<std::string> words = {"sh", "-c", kProbe, "shoal-probe", h.interface};
  words.insert(words.end(), groups.begin(), groups.end());
  const std::vector<std::string> cmd = Prefixed(h, words);
  std::string out;
  pid_t pid = -1;
  bool timed_out = false;
  const auto start = std::chrono::steady_clock::now();
  const int status = RunCapture(cmd, kProbeTimeoutS, &out, &pid, &timed_out);
  *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  *fields = Fields(out);
  if (status == 0 && fields->count("pid") != 0) {
    *in_place = (*fields)["pid"] == std::to_string(pid);
    return true;
  }
  const std::string prefix = h.prefix.empty() ? "sh" : Joined(h.prefix);
  *error = "host " + h.name + Where(hosts, h) + ": `" + prefix + " ...` " +
           (timed_out ? "did not answer within " + std::to_string(kProbeTimeoutS) + " s"
            : status < 0 ? "could not be run"
                         : "failed (" + std::string(WIFEXITED(status) ? "exit status " + std::to_string(WEXITSTATUS(status)) : "killed by a signal") + ")") +
           (LastLine(out).empty() ? "" : ": " + LastLine(out)) +
           "; shoal run starts every process placed there with this prefix";
  return false;
}

/// The route checks of one host; "" if they pass.
std::string RouteProblem(const HostsFile& hosts, const Host& h, const std::string& group,
                         const std::string& route, bool spans_hosts) {
  const std::string dev = RouteDev(route);
  const std::string iface = h.interface.empty() ? "<interface>" : h.interface;
  const std::string on = "host " + h.name + Where(hosts, h) + ": multicast to " + group;
  if (dev.empty()) {
    return on + " has no route (" + route + "); LCM's udpm needs one: there, ip route add 224.0.0.0/4 dev " + iface;
  }
  if (!h.interface.empty() && dev != h.interface) {
    return on + " leaves by " + dev + ", not by the hosts file's interface " + h.interface +
           " (LCM's URL cannot choose one: the route does); there, ip route replace 224.0.0.0/4 dev " +
           h.interface + " (or a route for the group)";
  }
  if (spans_hosts && dev == "lo") {
    return on + " stays on lo, and the run spans more than one network; there, ip route replace 224.0.0.0/4 dev " + iface;
  }
  return "";
}

/// The check of the interface the hosts file names for h, from its probe's fields; "" if
/// it passes (or none is named).
std::string InterfaceProblem(const HostsFile& hosts, const Host& h,
                             std::map<std::string, std::string>& f, bool spans_hosts) {
  if (h.interface.empty()) return "";
  const std::string on = "host " + h.name + Where(hosts, h) + ": interface " + h.interface;
  if (f["iface"] != "ok") {
    std::string has = f["ifaces"];
    while (!has.empty() && has.back() == ' ') has.pop_back();
    return on + " does not exist there (it has: " + has +
           "); name the one on the network the hosts share";
  }
  if (spans_hosts && h.interface == "lo") {
    return on + " reaches no other host, and the run spans more than one network; name the "
                "interface on the network the hosts share";
  }
  return "";
}

}  // namespace

std::string ShellQuote(const std::string& text) {
  std::string q = "'";
  for (const char c : text) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

std::vector<std::string> HostCommand(const Host& h, const std::vector<std::string>& argv,
                                     const std::string& cwd) {
  std::vector<std::string> words = {"sh", "-c", kWrapper, "shoal-host", cwd};
  words.insert(words.end(), argv.begin(), argv.end());
  std::vector<std::string> cmd = Prefixed(h, words);
  cmd[0] = OnPath(cmd[0]);
  return cmd;
}

bool KeyPipe(const std::string& line, int* read_fd, int* write_fd, std::string* error) {
  int fds[2];
  if (pipe2(fds, O_CLOEXEC) != 0) {
    *error = std::string("cannot make a pipe (") + std::strerror(errno) + ")";
    return false;
  }
  // Far below PIPE_BUF: written at once, never blocks.
  const std::string text = line + "\n";
  if (write(fds[1], text.data(), text.size()) != static_cast<ssize_t>(text.size())) {
    *error = std::string("cannot write to a pipe (") + std::strerror(errno) + ")";
    close(fds[0]);
    close(fds[1]);
    return false;
  }
  *read_fd = fds[0];
  *write_fd = fds[1];
  return true;
}

void LoginPacer::WaitForRoom(const std::string& host, const std::function<bool()>& stop) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(kProbeTimeoutS);
  while (LoggingIn(host) >= kLoginsAtOnce && !stop() &&
         std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

void LoginPacer::Started(const std::string& host, pid_t pid, int key_fd) {
  started_.emplace(host, std::make_pair(pid, key_fd));
}

int LoginPacer::LoggingIn(const std::string& host) const {
  int n = 0;
  const auto [from, to] = started_.equal_range(host);
  for (auto it = from; it != to; ++it) {
    const auto [pid, fd] = it->second;
    int unread = 0;
    if (fd < 0 || ioctl(fd, FIONREAD, &unread) != 0 || unread == 0) continue;
    // Ended (ssh failed): not logging in. WNOWAIT leaves it to the run's supervision.
    siginfo_t info{};
    if (waitid(P_PID, static_cast<id_t>(pid), &info, WEXITED | WNOHANG | WNOWAIT) == 0 &&
        info.si_pid == pid) {
      continue;
    }
    ++n;
  }
  return n;
}

double LoginSeconds(const HostCheck& c, int count) {
  if (c.same_process || count <= 0) return 0;
  const int waves = (count + kLoginsAtOnce - 1) / kLoginsAtOnce;
  return 2.0 * c.login_s * waves;
}

std::string GroupOfUrl(const std::string& url) {
  if (url.rfind("udpm://", 0) != 0) return "";
  const std::string rest = url.substr(7);
  return rest.substr(0, rest.find_first_of(":?"));
}

bool CheckHosts(const HostsFile& hosts, int followers,
                const std::map<std::string, std::vector<std::string>>& groups_by_host,
                int ttl, const std::string& ttl_fix, const std::map<std::string, int>& fifo_hosts,
                std::map<std::string, HostCheck>* checks, std::string* error) {
  const std::vector<const Host*> used = hosts.UsedHosts(followers);
  for (const Host& h : hosts.hosts) {
    if (h.name == kLocalHostName || std::find(used.begin(), used.end(), &h) != used.end()) continue;
    std::fprintf(stderr, "shoal run: warning: host %s%s runs no process of this run: not checked\n",
                 h.name.c_str(), Where(hosts, h).c_str());
  }
  std::vector<std::map<std::string, std::string>> probed(used.size());
  std::vector<bool> in_place(used.size());
  std::vector<double> login_s(used.size());
  std::set<std::string> networks;  // boot id and network namespace of each host
  for (std::size_t i = 0; i < used.size(); ++i) {
    bool b = false;
    const auto g = groups_by_host.find(used[i]->name);
    const std::vector<std::string> none;
    if (!Probe(hosts, *used[i], g == groups_by_host.end() ? none : g->second, &probed[i], &b,
               &login_s[i], error)) {
      return false;
    }
    in_place[i] = b;
    networks.insert(probed[i]["boot"] + " " + probed[i]["netns"]);
  }
  // Hosts that share one network stack (prefixes that start processes beside shoal run's)
  // reach each other on loopback with a TTL of 0, as a run without --hosts does.
  const bool spans = networks.size() > 1;
  if (spans && ttl == 0) {
    *error = hosts.path + ": the run spans " + std::to_string(networks.size()) +
             " networks, but its LCM URL's ttl is 0, which keeps every message on its host; "
             "use " + ttl_fix;
    return false;
  }
  const std::string boot = ReadLine("/proc/sys/kernel/random/boot_id");
  const std::string timens = ReadLink("/proc/self/ns/time");
  const std::string pidns = ReadLink("/proc/self/ns/pid");
  for (std::size_t i = 0; i < used.size(); ++i) {
    const Host& h = *used[i];
    std::map<std::string, std::string>& f = probed[i];
    HostCheck c;
    c.same_clock = !boot.empty() && f["boot"] == boot && f["timens"] == timens;
    // The pid namespace of a machine's init has the same inode on every machine, and the
    // remote shell's pid may equal the local ssh client's by chance: the boot id tells.
    c.same_process = in_place[i] && f["pidns"] == pidns && f["boot"] == boot;
    c.login_s = login_s[i];
    if (const auto fifo = fifo_hosts.find(h.name); fifo != fifo_hosts.end()) {
      const std::string prio = std::to_string(fifo->second);
      const std::string& said = f["fifo" + prio];
      if (said != "ok" && said != "nochrt") {
        *error = "--sched-fifo: host " + h.name + Where(hosts, h) +
                 " does not permit SCHED_FIFO priority " + prio + " (chrt -f " + prio +
                 " true: " + (said.empty() ? "no answer" : said) + ")";
        return false;
      }
    }
    *error = InterfaceProblem(hosts, h, f, spans);
    if (!error->empty()) return false;
    const auto it = groups_by_host.find(h.name);
    for (const std::string& g : it == groups_by_host.end() ? std::vector<std::string>{} : it->second) {
      const std::string route = f["route " + g];
      *error = RouteProblem(hosts, h, g, route, spans);
      if (!error->empty()) return false;
      if (c.multicast_dev.empty()) c.multicast_dev = RouteDev(route);
    }
    (*checks)[h.name] = c;
  }
  return true;
}

}  // namespace shoal
