#include "tools/retime_command.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <limits>
#include <optional>
#include <sstream>
#include <vector>

#include <nlohmann/json.hpp>

#include "analysis/analysis.h"
#include "analysis/run_data.h"
#include "analysis/verdict.h"
#include "runtime/bus_auth.h"
#include "runtime/channels.h"
#include "runtime/log_reader.h"
#include "runtime/log_writer.h"
#include "scenario/regular_file.h"

namespace shoal {
namespace {

constexpr const char* kWho = "shoal retime: ";

/// The mission time a Shoal message holds: its utime, if it decodes as the analysis reads
/// it. -1 for other channels, a message that does not decode (the analysis drops it), or
/// a time outside [0, limit] (a status stamped with the wall clock, a damaged or forged
/// time).
Micros MissionTimeOf(std::string_view ch, const std::uint8_t* d, int n, Micros limit) {
  const Micros t = DecodedTimeOf(ch, d, n);
  return t >= 0 && t <= limit ? t : -1;
}

bool Exists(const std::string& p) {
  struct stat st {};
  return lstat(p.c_str(), &st) == 0;
}

/// The directory part of `path` ("." when none), for the temporary file next to it.
std::string DirOf(const std::string& path) {
  const std::size_t slash = path.find_last_of('/');
  if (slash == std::string::npos) return ".";
  return slash == 0 ? "/" : path.substr(0, slash);
}

std::string BaseOf(const std::string& path) {
  const std::size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

/// A new, empty temporary file next to `path` (same file system, so rename is atomic).
bool MakeTemp(const std::string& path, std::string* tmp, std::string* error) {
  std::string name = DirOf(path) + "/." + BaseOf(path) + ".tmp.XXXXXX";
  const int fd = mkstemp(name.data());
  if (fd < 0) {
    *error = path + ": cannot create a file next to it (" + std::strerror(errno) + ")";
    return false;
  }
  close(fd);
  *tmp = name;
  return true;
}

/// Syncs the written file and renames it to `path`. Removes it on failure.
bool Commit(const std::string& tmp, const std::string& path, mode_t mode, std::string* error) {
  const int fd = open(tmp.c_str(), O_RDONLY);
  const bool ok = fd >= 0 && fchmod(fd, mode) == 0 && fsync(fd) == 0;
  if (fd >= 0) close(fd);
  if (!ok || rename(tmp.c_str(), path.c_str()) != 0) {
    *error = path + ": cannot write it (" + std::strerror(errno) + ")";
    unlink(tmp.c_str());
    return false;
  }
  return true;
}

/// Copies the key file `from` to `to` (mode 0600), atomically.
bool CopyKey(const std::string& from, const std::string& to, std::string* error) {
  std::ifstream in(from, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  std::string tmp;
  if (!in || !MakeTemp(to, &tmp, error)) {
    if (error->empty()) *error = from + ": cannot read the key file";
    return false;
  }
  std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
  out << text.str();
  out.close();
  if (!out) {
    *error = to + ": cannot write the key file";
    unlink(tmp.c_str());
    return false;
  }
  return Commit(tmp, to, 0600, error);
}

/// The log's event count and its reader's warnings if it is damaged (one pass); its span,
/// the earliest and latest stamps, as its analysis reads them (RunData).
struct Stamps {
  std::int64_t first = 0, last = 0, events = 0;
  std::int64_t first_state = -1;  // the earliest vehicle state's stamp (-1: none)
  std::vector<std::string> damage;
};

bool ReadStamps(const std::string& path, Stamps* s, std::string* error) {
  LcmLogReader reader;
  if (!reader.Open(path, error)) return false;
  LogEventView ev;
  while (reader.Next(&ev)) ++s->events;
  if (reader.damaged_regions() > 0) s->damage = reader.warnings();
  return true;
}

/// Writes the marker and every event of `log`, restamped, into `tmp`. With the log's key,
/// only messages that verify set the mission time: a forged or damaged one, which the
/// analysis drops, must not carry every later event to its time.
bool WriteRetimed(const std::string& log, const std::string& tmp, Micros limit, const Stamps& s,
                  const std::optional<bus_auth::Key>& key, std::int64_t* shoal_timed,
                  Micros* last_mission, std::string* error) {
  LcmLogReader reader;
  if (!reader.Open(log, error)) return false;
  try {
    LogWriter w(tmp);
    nlohmann::ordered_json m{{"format", kRetimedFormat},
                             {"source", BaseOf(log)},
                             {"first_timestamp_us", s.first},
                             {"last_timestamp_us", s.last},
                             {"events", s.events},
                             {"first_state_timestamp_us", s.first_state}};
    // The copy holds what could be read: its analysis must say the original was damaged.
    if (!s.damage.empty()) m["original_damage"] = s.damage;
    const std::string marker = m.dump();
    w.WriteRaw(kRetimedChannel, s.first, marker.data(), static_cast<int>(marker.size()));
    Micros mission = 0;  // the running mission time: stamps never go back
    RunData counts;      // the verifier's, unused
    LogVerifier verifier(key, &counts);
    LogEventView ev;
    while (reader.Next(&ev)) {
      // The message as the analysis reads it: verified with the key and without its
      // trailer (without a key, a trailer stripped unchecked).
      const int size = verifier.Check(ev.channel, ev.data, ev.size);
      const Micros t = size < 0 ? -1 : MissionTimeOf(ev.channel, ev.data, size, limit);
      if (t >= 0) {
        mission = std::max(mission, t);
        ++*shoal_timed;
      }
      if (s.first > 0 && mission > std::numeric_limits<Micros>::max() - s.first) {
        *error = log + ": its first receive time (" + std::to_string(s.first) +
                 " us) plus the mission time passes the largest stamp a log can hold: "
                 "not a recording's clock";
        return false;
      }
      w.WriteRaw(std::string(ev.channel), s.first + mission, ev.data, ev.size);
    }
    w.Close();
    *last_mission = mission;
  } catch (const std::exception& e) {
    *error = e.what();
    return false;
  }
  for (const std::string& warn : reader.warnings()) std::cerr << kWho << "warning: " << warn << "\n";
  return true;
}

/// The options' problems, before anything is read: false with *error.
bool CheckPaths(const RetimeOptions& opt, std::string* error) {
  if (opt.log.empty() || opt.out.empty()) {
    *error = "give a LOG and --out OUT (shoal retime --help)";
  } else if (opt.log == opt.out || SameFile(opt.log, opt.out) ||
             (Exists(opt.out + ".key") && SameFile(opt.log + ".key", opt.out + ".key"))) {
    *error = opt.out + ": is the input log (or its key); write the retimed log elsewhere";
  } else if (opt.out.size() >= 4 && opt.out.compare(opt.out.size() - 4, 4, ".key") == 0) {
    *error = opt.out + ": give the log's path, not a key file's";
  } else if (!opt.force && Exists(opt.out)) {
    *error = opt.out + ": exists; give --force to replace it";
  } else if (!opt.force && Exists(opt.out + ".key")) {
    // Whether the input has a key or not: an OUT.key left beside the new log would be
    // taken as its key, and none of its messages would verify.
    *error = opt.out + ".key: exists; give --force to replace it (or remove it, for a log "
             "without a key)";
  }
  return error->empty();
}

}  // namespace

int RunRetime(const RetimeOptions& opt) {
  std::string error;
  if (!CheckPaths(opt, &error)) {
    std::cerr << kWho << error << "\n";
    return kExitBadInput;
  }
  // The run's bounds: a mission time beyond the last possible delivery is not one.
  RunData run;
  if (!LoadRunLog(opt.log, LoadOptions{}, &run, &error)) {
    std::cerr << kWho << error << "\n";
    return kExitBadInput;
  }
  if (run.retimed_from.retimed) {
    std::cerr << kWho << opt.log << ": is already retimed (from " << run.retimed_from.source
              << ")\n";
    return kExitBadInput;
  }
  const StateTimeBounds b = StateTimeBoundsOf(run);
  const Micros limit = b.deliver_limit_us >= 0 ? b.deliver_limit_us
                                                : std::numeric_limits<Micros>::max() / 2;
  Stamps s;
  std::string tmp;
  std::int64_t timed = 0;
  Micros mission = 0;
  const bool key = access((opt.log + ".key").c_str(), F_OK) == 0;
  std::optional<bus_auth::Key> run_key;
  bus_auth::Key k{};
  if (key && !bus_auth::ReadKeyFile(opt.log + ".key", &k, &error)) {
    std::cerr << kWho << error << "\n";
    return kExitBadInput;
  }
  if (key) run_key = k;
  if (!ReadStamps(opt.log, &s, &error) || !MakeTemp(opt.out, &tmp, &error)) {
    std::cerr << kWho << error << "\n";
    return kExitBadInput;
  }
  // The span as the analysis takes it: without a damaged stamp far from its neighbours'.
  s.first = run.first_timestamp;
  s.last = run.last_timestamp;
  s.first_state = run.first_state_timestamp;
  if (!WriteRetimed(opt.log, tmp, limit, s, run_key, &timed, &mission, &error) ||
      !Commit(tmp, opt.out, 0644, &error)) {
    unlink(tmp.c_str());
    std::cerr << kWho << error << "\n";
    return kExitBadInput;
  }
  if (key && !CopyKey(opt.log + ".key", opt.out + ".key", &error)) {
    std::cerr << kWho << error << "\n";
    return kExitBadInput;
  }
  // --force over a log that had a key, with an input that has none: the old key goes too.
  if (!key && unlink((opt.out + ".key").c_str()) != 0 && errno != ENOENT) {
    std::cerr << kWho << opt.out << ".key: cannot remove the old key (" << std::strerror(errno)
              << "); remove it, or shoal analyze takes it as this log's key\n";
    return kExitBadInput;
  }
  if (!opt.quiet) {
    std::fprintf(stderr,
                 "shoal retime: wrote %s: %lld events (%lld with a mission time), %.2f s of "
                 "mission; the original spans %.2f s%s\n",
                 opt.out.c_str(), static_cast<long long>(s.events), static_cast<long long>(timed),
                 ToSeconds(mission),
                 ToSeconds(s.last - s.first), key ? (", key copied to " + opt.out + ".key").c_str() : "");
  }
  return kExitOk;
}

}  // namespace shoal
