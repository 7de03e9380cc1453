// Hosts file loading and validation (docs/run.md). Unknown keys are errors at every level,
// with the closest valid key suggested.
#include "launcher/hosts_file.h"

#include <toml++/toml.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <optional>
#include <sstream>
#include <string_view>
#include <system_error>

#include "scenario/regular_file.h"
#include "scenario/toml_depth.h"

namespace shoal {
namespace {

constexpr std::array<std::string_view, 3> kTopKeys = {"bus", "host", "placement"};
constexpr std::array<std::string_view, 2> kBusKeys = {"url", "ttl"};
constexpr std::array<std::string_view, 4> kHostKeys = {"name", "prefix", "interface",
                                                       "remote_shell"};
constexpr std::array<std::string_view, 5> kPlacementKeys = {"logger", "emulator", "leader",
                                                            "vehicles", "default"};
constexpr std::size_t kMaxShownChars = 80;
// Vehicle ids of a scenario are at most 1000 (the scenario loader's limit).
constexpr std::int64_t kMaxVehicleId = 1000;

int LineOf(const toml::node& node) {
  return std::max(1, static_cast<int>(node.source().begin.line));
}

int EditDistance(std::string_view a, std::string_view b) {
  std::vector<int> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = static_cast<int>(j);
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = static_cast<int>(i);
    for (std::size_t j = 1; j <= b.size(); ++j) {
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] != b[j - 1])});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

std::string Show(const toml::node& node) {
  std::ostringstream text;
  if (const auto* s = node.as_string()) {
    text << '"' << s->get() << '"';
  } else if (const auto* a = node.as_array()) {
    text << toml::toml_formatter(*a);
  } else if (const auto* t = node.as_table()) {
    text << "{" << toml::toml_formatter(*t) << "}";
  } else {
    node.visit([&text](const auto& v) { text << v; });
  }
  std::string out = text.str();
  std::replace(out.begin(), out.end(), '\n', ' ');
  if (out.size() > kMaxShownChars) out = out.substr(0, kMaxShownChars - 3) + "...";
  return out;
}

/// Reads checked values; every failure throws a located HostsFileError.
class Reader {
 public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void Fail(int line, const std::string& key, const std::string& what,
                         const std::string& got, const std::string& fix) const {
    std::string message = file_ + ":" + std::to_string(line) + ": ";
    if (!key.empty()) message += key + ": ";
    message += what;
    if (!got.empty()) message += " (got " + got + ")";
    if (!fix.empty()) message += "; " + fix;
    throw HostsFileError(message);
  }
  [[noreturn]] void FailAt(const toml::node& node, const std::string& key,
                           const std::string& what, const std::string& fix) const {
    Fail(LineOf(node), key, what, Show(node), fix);
  }

  template <std::size_t N>
  void CheckKeys(const toml::table& t, const std::string& prefix, const std::string& label,
                 const std::array<std::string_view, N>& allowed) const {
    for (auto&& [key, value] : t) {
      const std::string_view name = key.str();
      if (std::find(allowed.begin(), allowed.end(), name) != allowed.end()) continue;
      std::string fix;
      int best = 3;
      for (const std::string_view candidate : allowed) {
        const int d = EditDistance(name, candidate);
        if (d < best) best = d, fix = "did you mean '" + std::string(candidate) + "'?";
      }
      if (fix.empty()) {
        fix = "valid keys in " + label + ":";
        for (const std::string_view candidate : allowed) fix += " " + std::string(candidate);
      }
      Fail(std::max(1, static_cast<int>(key.source().begin.line)), prefix + std::string(name),
           "unknown key", "", fix);
    }
  }

  const toml::table& Table(const toml::node& node, const std::string& key,
                           const std::string& example) const {
    if (!node.is_table()) FailAt(node, key, "must be a table", example);
    return *node.as_table();
  }
  std::string String(const toml::node& node, const std::string& key,
                     const std::string& example) const {
    if (!node.is_string()) FailAt(node, key, "must be a string", example);
    return node.as_string()->get();
  }

 private:
  std::string file_;
};

bool IsHostName(std::string_view name) {
  return !name.empty() && name.size() <= 64 &&
         std::all_of(name.begin(), name.end(), [](char c) {
           return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.';
         });
}

std::string ProgramName(const std::string& path) {
  const std::size_t slash = path.rfind('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

void ReadBus(const Reader& r, const toml::node& node, HostsFile* h) {
  const toml::table& bus = r.Table(node, "bus", "[bus] ttl = 1");
  r.CheckKeys(bus, "bus.", "[bus]", kBusKeys);
  const toml::node* url = bus.get("url");
  const toml::node* ttl = bus.get("ttl");
  if (url != nullptr) {
    h->bus_url = r.String(*url, "bus.url", "url = \"udpm://239.255.76.67:7667?ttl=1\"");
    if (h->bus_url.empty()) r.FailAt(*url, "bus.url", "must not be empty", "leave it out for the private URL");
    if (ttl != nullptr) {
      r.FailAt(*ttl, "bus.ttl", "cannot be given with bus.url", "give the TTL in the URL (?ttl=1)");
    }
    const int url_ttl = TtlOfUrl(h->bus_url);
    if (url_ttl < 0 || url_ttl > 255) {
      r.FailAt(*url, "bus.url", "its ttl must be a number from 0 to 255", "e.g. ?ttl=1");
    }
    h->ttl = url_ttl;
  }
  if (ttl != nullptr) {
    const std::optional<std::int64_t> v = ttl->value<std::int64_t>();
    if (!ttl->is_integer() || !v || *v < 0 || *v > 255) {
      r.FailAt(*ttl, "bus.ttl", "must be an integer from 0 to 255",
               "1 crosses a bridge or switch, not a router");
    }
    h->ttl = static_cast<int>(*v);
    h->ttl_line = LineOf(*ttl);
  }
}

Host ReadHost(const Reader& r, const toml::node& node, std::size_t index) {
  const std::string where = "host[" + std::to_string(index) + "]";
  const toml::table& t = r.Table(node, where, "[[host]] name = \"h2\"");
  r.CheckKeys(t, where + ".", "[[host]]", kHostKeys);
  Host h;
  h.line = LineOf(node);
  const toml::node* name = t.get("name");
  if (name == nullptr) r.Fail(h.line, where, "has no name", "", "add name = \"h2\"");
  h.name = r.String(*name, where + ".name", "name = \"h2\"");
  if (!IsHostName(h.name)) {
    r.FailAt(*name, where + ".name", "must be 1-64 letters, digits, '_', '-' or '.'",
             "name = \"rack2\"");
  }
  if (const toml::node* prefix = t.get("prefix")) {
    const toml::array* a = prefix->as_array();
    if (a == nullptr) {
      r.FailAt(*prefix, where + ".prefix", "must be a list of strings",
               "prefix = [\"ssh\", \"-o\", \"BatchMode=yes\", \"rack2\"]");
    }
    for (const toml::node& word : *a) {
      h.prefix.push_back(r.String(word, where + ".prefix", "prefix = [\"ip\", \"netns\", \"exec\", \"h2\"]"));
      if (h.prefix.back().empty()) r.FailAt(word, where + ".prefix", "holds an empty word", "");
    }
  }
  if (h.name == kLocalHostName && !h.prefix.empty()) {
    r.FailAt(*t.get("prefix"), where + ".prefix",
             "must be empty for the host named \"local\" (the host shoal run runs on)",
             "give the host another name");
  }
  h.remote_shell = !h.prefix.empty() && ProgramName(h.prefix[0]) == "ssh";
  if (const toml::node* shell = t.get("remote_shell")) {
    if (!shell->is_boolean()) r.FailAt(*shell, where + ".remote_shell", "must be true or false", "");
    h.remote_shell = shell->as_boolean()->get();
  }
  if (const toml::node* iface = t.get("interface")) {
    h.interface = r.String(*iface, where + ".interface", "interface = \"eth1\"");
    if (!IsHostName(h.interface) || h.interface.size() > 15) {
      r.FailAt(*iface, where + ".interface", "is not an interface name", "interface = \"eth1\"");
    }
  }
  return h;
}

void ReadHosts(const Reader& r, const toml::node* node, HostsFile* h) {
  if (node != nullptr) {
    const toml::array* hosts = node->as_array();
    if (hosts == nullptr || !hosts->is_array_of_tables()) {
      r.FailAt(*node, "host", "must be a list of [[host]] tables", "[[host]] name = \"h2\"");
    }
    for (std::size_t i = 0; i < hosts->size(); ++i) {
      Host host = ReadHost(r, *hosts->get(i), i);
      for (const Host& other : h->hosts) {
        if (other.name == host.name) {
          r.Fail(host.line, "host[" + std::to_string(i) + "].name",
                 "host \"" + host.name + "\" is defined twice (first at line " +
                     std::to_string(other.line) + ")",
                 "", "give each host its own name");
        }
      }
      h->hosts.push_back(std::move(host));
    }
  }
  const bool has_local = std::any_of(h->hosts.begin(), h->hosts.end(),
                                     [](const Host& x) { return x.name == kLocalHostName; });
  if (!has_local) {
    Host local;
    local.name = kLocalHostName;
    h->hosts.insert(h->hosts.begin(), local);
  }
}

/// The index of the host named `name` (given at `line` for `key`); unknown: an error.
std::size_t HostIndex(const Reader& r, const std::string& name, int line, const std::string& key,
                      const HostsFile& h) {
  for (std::size_t i = 0; i < h.hosts.size(); ++i) {
    if (h.hosts[i].name == name) return i;
  }
  std::string known;
  for (const Host& x : h.hosts) known += (known.empty() ? "" : ", ") + x.name;
  r.Fail(line, key, "unknown host \"" + name + "\"", "",
         "the hosts are: " + known + " (define others with [[host]])");
}

std::size_t HostIndex(const Reader& r, const toml::node& node, const std::string& key,
                      const HostsFile& h) {
  return HostIndex(r, r.String(node, key, key + " = \"h2\""), LineOf(node), key, h);
}

/// One entry of a vehicle list: an id or a range "a-b".
std::pair<std::int64_t, std::int64_t> VehicleRange(const Reader& r, const toml::node& node,
                                                   const std::string& key) {
  const std::string fix = "a vehicle id from 1 to " + std::to_string(kMaxVehicleId) +
                          ", or a range such as \"4-8\"";
  if (const std::optional<std::int64_t> id = node.value<std::int64_t>(); id && node.is_integer()) {
    if (*id < 1 || *id > kMaxVehicleId) r.FailAt(node, key, "is not a vehicle id", fix);
    return {*id, *id};
  }
  if (!node.is_string()) r.FailAt(node, key, "is not a vehicle id or range", fix);
  const std::string text = node.as_string()->get();
  char* end = nullptr;
  const long long a = std::strtoll(text.c_str(), &end, 10);
  long long b = a;
  bool ok = end != text.c_str() && *end == '-';
  if (ok) {
    const char* second = end + 1;
    b = std::strtoll(second, &end, 10);
    ok = end != second && *end == '\0' && std::isdigit(static_cast<unsigned char>(text[0])) &&
         std::isdigit(static_cast<unsigned char>(*second));
  }
  if (!ok || a < 1 || b > kMaxVehicleId || a > b) r.FailAt(node, key, "is not a vehicle range", fix);
  return {a, b};
}

void ReadVehicles(const Reader& r, const toml::node& node, HostsFile* h) {
  const toml::table& t = r.Table(node, "placement.vehicles", "vehicles = { h2 = [1, 2], h3 = [\"3-6\"] }");
  for (auto&& [key, list] : t) {
    const std::string name(key.str());
    const std::string where = "placement.vehicles." + name;
    const std::size_t host =
        HostIndex(r, name, std::max(1, static_cast<int>(key.source().begin.line)), where, *h);
    const toml::array* a = list.as_array();
    if (a == nullptr) r.FailAt(list, where, "must be a list of vehicle ids", name + " = [1, 2, \"4-6\"]");
    for (const toml::node& entry : *a) {
      const auto [first, last] = VehicleRange(r, entry, where);
      for (std::int64_t id = first; id <= last; ++id) {
        const auto before = h->vehicle_lines.find(static_cast<int>(id));
        if (before != h->vehicle_lines.end()) {
          r.FailAt(entry, where,
                   "vehicle " + std::to_string(id) + " is placed twice (also on host \"" +
                       h->hosts[h->vehicles.at(static_cast<int>(id))].name + "\", line " +
                       std::to_string(before->second) + ")",
                   "place every vehicle once");
        }
        h->vehicles[static_cast<int>(id)] = host;
        h->vehicle_lines[static_cast<int>(id)] = LineOf(entry);
      }
    }
  }
}

void ReadPlacement(const Reader& r, const toml::node& node, HostsFile* h) {
  const toml::table& t = r.Table(node, "placement", "[placement] leader = \"h1\"");
  r.CheckKeys(t, "placement.", "[placement]", kPlacementKeys);
  h->placement_line = LineOf(node);
  const std::pair<const char*, HostRole> roles[] = {
      {"logger", HostRole::kLogger}, {"emulator", HostRole::kEmulator}, {"leader", HostRole::kLeader}};
  for (const auto& [key, role] : roles) {
    if (const toml::node* n = t.get(key)) h->roles[role] = HostIndex(r, *n, std::string("placement.") + key, *h);
  }
  if (const toml::node* n = t.get("default")) h->default_host = HostIndex(r, *n, "placement.default", *h);
  if (const toml::node* n = t.get("vehicles")) ReadVehicles(r, *n, h);
}

std::string ReadHostsText(const std::string& path) {
  std::string error;
  const int fd = OpenRegularFile(path, "hosts file", kMaxHostsFileBytes, &error);
  if (fd < 0) throw HostsFileError(error);
  std::string text;
  char buffer[1 << 16];
  for (;;) {
    const ssize_t count = read(fd, buffer, sizeof(buffer));
    if (count < 0 && errno == EINTR) continue;
    if (count <= 0) {
      const int e = errno;
      close(fd);
      if (count < 0) {
        throw HostsFileError(path + ": cannot read hosts file (" +
                             std::error_code(e, std::generic_category()).message() + ")");
      }
      return text;
    }
    text.append(buffer, static_cast<std::size_t>(count));
    if (text.size() > kMaxHostsFileBytes) {
      close(fd);
      throw HostsFileError(path + ": hosts file larger than " +
                           std::to_string(kMaxHostsFileBytes) + " bytes");
    }
  }
}

}  // namespace

const Host& HostsFile::HostOfVehicle(int id) const {
  if (id == 0) return HostOf(HostRole::kLeader);
  const auto it = vehicles.find(id);
  return hosts[it == vehicles.end() ? default_host : it->second];
}

const Host& HostsFile::HostOf(HostRole role) const {
  const auto it = roles.find(role);
  return hosts[it == roles.end() ? default_host : it->second];
}

std::vector<const Host*> HostsFile::UsedHosts(int followers) const {
  std::vector<const Host*> used;
  auto add = [&used](const Host& h) {
    if (std::find(used.begin(), used.end(), &h) == used.end()) used.push_back(&h);
  };
  add(HostOf(HostRole::kLogger));
  add(HostOf(HostRole::kEmulator));
  for (int id = 0; id <= followers; ++id) add(HostOfVehicle(id));
  return used;
}

HostsFile ParseHostsFile(const std::string& text, const std::string& path) {
  const std::string file = path.empty() ? "<hosts>" : path;
  if (const int line = LineOfTooDeepKey(text)) {
    throw HostsFileError(file + ":" + std::to_string(line) +
                         ": TOML syntax error: a key or table nests more than " +
                         std::to_string(kMaxKeyDepth) + " tables deep");
  }
  toml::table root;
  try {
    root = toml::parse(std::string_view(text), std::string_view(file));
  } catch (const toml::parse_error& e) {
    const toml::source_position& where = e.source().begin;
    throw HostsFileError(file + ":" + std::to_string(std::max(1, static_cast<int>(where.line))) +
                         ": TOML syntax error: " + std::string(e.description()) + " (column " +
                         std::to_string(where.column) + ")");
  }
  const Reader r(file);
  r.CheckKeys(root, "", "a hosts file", kTopKeys);
  HostsFile h;
  h.path = path;
  if (const toml::node* bus = root.get("bus")) ReadBus(r, *bus, &h);
  ReadHosts(r, root.get("host"), &h);
  if (const toml::node* placement = root.get("placement")) ReadPlacement(r, *placement, &h);
  return h;
}

HostsFile LoadHostsFile(const std::string& path) {
  return ParseHostsFile(ReadHostsText(path), path);
}

std::string CheckPlacement(const HostsFile& hosts, int followers) {
  for (const auto& [id, line] : hosts.vehicle_lines) {
    if (id > followers) {
      return hosts.path + ":" + std::to_string(line) + ": placement.vehicles." +
             hosts.hosts[hosts.vehicles.at(id)].name + ": vehicle " + std::to_string(id) +
             " is not in the scenario (its vehicles are 1 to " + std::to_string(followers) +
             "); place only those";
    }
  }
  return "";
}

std::string UrlWithTtl(const std::string& url, int ttl) {
  const std::string value = "ttl=" + std::to_string(ttl);
  const std::size_t q = url.find('?');
  if (q == std::string::npos) return url + "?" + value;
  for (std::size_t at = q; at != std::string::npos; at = url.find('&', at + 1)) {
    if (url.compare(at + 1, 4, "ttl=") != 0) continue;
    const std::size_t end = url.find('&', at + 1);
    return url.substr(0, at + 1) + value + (end == std::string::npos ? "" : url.substr(end));
  }
  return url + "&" + value;
}

int TtlOfUrl(const std::string& url) {
  const std::size_t q = url.find('?');
  if (q == std::string::npos) return 0;
  for (std::size_t at = q; at != std::string::npos; at = url.find('&', at + 1)) {
    if (url.compare(at + 1, 4, "ttl=") != 0) continue;
    const std::string v = url.substr(at + 5, url.find('&', at + 1) - (at + 5));
    char* end = nullptr;
    const long n = std::strtol(v.c_str(), &end, 0);
    return v.empty() || *end != '\0' ? -1 : static_cast<int>(std::min(n, 1000L));
  }
  return 0;
}

}  // namespace shoal
