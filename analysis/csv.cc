#include "analysis/csv.h"

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>

namespace shoal {
namespace {

/// A CSV file written through one large buffer.
class CsvFile {
 public:
  bool Open(const std::string& path, std::string* error) {
    path_ = path;
    f_ = std::fopen(path.c_str(), "w");
    if (f_ == nullptr) {
      *error = path + ": cannot write (" + std::strerror(errno) + ")";
      return false;
    }
    buf_.reserve(kFlush + 4096);
    return true;
  }
  ~CsvFile() {
    if (f_ != nullptr) std::fclose(f_);
  }
  void Header(const char* h) {
    buf_ += h;
    buf_ += '\n';
  }
  CsvFile& Num(double v) {
    Sep();
    if (!std::isfinite(v)) {
      buf_ += std::isnan(v) ? "NaN" : (v > 0 ? "Inf" : "-Inf");
      return *this;
    }
    char tmp[32];
    const auto r = std::to_chars(tmp, tmp + sizeof(tmp), v);
    buf_.append(tmp, r.ptr);
    return *this;
  }
  CsvFile& Int(long long v) {
    Sep();
    char tmp[24];
    const auto r = std::to_chars(tmp, tmp + sizeof(tmp), v);
    buf_.append(tmp, r.ptr);
    return *this;
  }
  void EndRow() {
    buf_ += '\n';
    first_ = true;
    if (buf_.size() >= kFlush) Flush();
  }
  bool Close(std::string* error) {
    Flush();
    const bool ok = !failed_ && std::fclose(f_) == 0;
    f_ = nullptr;
    if (!ok) *error = path_ + ": write failed (" + std::strerror(errno) + ")";
    return ok;
  }

 private:
  static constexpr std::size_t kFlush = 1 << 20;
  void Sep() {
    if (!first_) buf_ += ',';
    first_ = false;
  }
  void Flush() {
    if (!buf_.empty() && std::fwrite(buf_.data(), 1, buf_.size(), f_) != buf_.size()) failed_ = true;
    buf_.clear();
  }
  std::string path_;
  std::FILE* f_ = nullptr;
  std::string buf_;
  bool first_ = true;
  bool failed_ = false;
};

constexpr const char* kVehicleHeader =
    "time_s,utime_us,seq,x_m,y_m,z_m,theta_rad,psi_rad,u_mps,v_mps,w_mps,q_radps,r_radps,"
    "x_dot_mps,y_dot_mps,z_dot_mps,theta_dot_radps,psi_dot_radps,"
    "accel_x_mps2,accel_y_mps2,accel_z_mps2,accel_theta_radps2,accel_psi_radps2,"
    "tau_x_n,tau_y_n,tau_z_n,tau_m_nm,tau_n_nm,saturated,stale_neighbour";
constexpr const char* kErrorColumns =
    ",position_error_m,velocity_error_mps,attitude_error_rad,"
    "position_error_x_m,position_error_y_m,position_error_z_m";

/// A state the run can have produced (the analysis leaves the others out, so does the CSV).
bool PossibleTime(const StateMsg& m, const StateTimeBounds& b) {
  return m.utime >= 0 && m.utime <= b.limit_us;
}

bool WriteVehicle(const RunData& run, const RunAnalysis& a, int id, const std::string& path,
                  std::string* error) {
  CsvFile f;
  if (!f.Open(path, error)) return false;
  const bool follower = id >= 1;
  f.Header((std::string(kVehicleHeader) + (follower ? kErrorColumns : "")).c_str());
  const std::vector<StateMsg>& s = run.vehicles[id].samples;
  const std::vector<FormationErrors>* err =
      follower && id <= static_cast<int>(a.followers.size()) && !a.followers[id - 1].errors.empty()
          ? &a.followers[id - 1].errors
          : nullptr;
  const std::vector<StateMsg>& lead = run.vehicles[0].samples;
  const Vec3 offset = follower && run.has_scenario && id <= static_cast<int>(run.scenario.offsets_m.size())
                          ? run.scenario.offsets_m[id - 1]
                          : Vec3::Zero();
  std::size_t l = 0;
  for (std::size_t k = 0; k < s.size(); ++k) {
    const StateMsg& m = s[k];
    if (!PossibleTime(m, a.bounds)) continue;
    f.Num(ToSeconds(m.utime)).Int(m.utime).Int(m.seq);
    for (const Vec5* v : {&m.eta, &m.nu, &m.eta_dot, &m.accel_cmd, &m.tau}) {
      for (int c = 0; c < 5; ++c) f.Num((*v)(c));
    }
    f.Int((m.flags & StateMsg::kFlagSaturated) ? 1 : 0)
        .Int((m.flags & StateMsg::kFlagStaleNeighbour) ? 1 : 0);
    if (follower) {
      const FormationErrors e = err ? (*err)[k] : FormationErrors{kNaN, kNaN, kNaN};
      f.Num(e.position_m).Num(e.velocity_mps).Num(e.attitude_rad);
      while (l < lead.size() && lead[l].utime < m.utime) ++l;
      if (err && l < lead.size() && lead[l].utime == m.utime) {
        const Vec3 d = (m.eta.head<3>() - offset) - lead[l].eta.head<3>();
        f.Num(d(0)).Num(d(1)).Num(d(2));
      } else {
        f.Num(kNaN).Num(kNaN).Num(kNaN);
      }
    }
    f.EndRow();
  }
  return f.Close(error);
}

bool WriteChannel(const RunData& run, const RunAnalysis& a, const std::string& path,
                  std::string* error) {
  CsvFile f;
  if (!f.Open(path, error)) return false;
  f.Header(
      "send_time_s,send_utime_us,sender,receiver,msg_seq,status,delivered,deliver_time_s,"
      "realised_delay_s,drawn_delay_s,configured_delay_s,delay_error_s");
  for (std::size_t k = 0; k < run.channel_events.size(); ++k) {
    const ChannelEventRecord& e = run.channel_events[k];
    if (ChannelEventTimeOf(e, a.bounds) != EventTime::kPossible) continue;
    const bool ok = e.status == 0;
    const double cfg = k < a.channel.configured_delay_s.size() ? a.channel.configured_delay_s[k] : kNaN;
    const double real = ok ? ToSeconds(e.deliver_utime - e.send_utime) : kNaN;
    f.Num(ToSeconds(e.send_utime)).Int(e.send_utime).Int(e.sender).Int(e.receiver).Int(e.msg_seq)
        .Int(e.status).Int(ok ? 1 : 0).Num(ok ? ToSeconds(e.deliver_utime) : kNaN).Num(real)
        .Num(e.delay_s).Num(cfg).Num(ok ? real - cfg : kNaN);
    f.EndRow();
  }
  return f.Close(error);
}

bool WriteHealth(const RunData& run, const std::string& path, std::string* error) {
  CsvFile f;
  if (!f.Open(path, error)) return false;
  f.Header(
      "time_s,process,ticks,lateness_p50_s,lateness_p99_s,lateness_max_s,overruns,"
      "msgs_received,msgs_dropped_invalid,msgs_dropped_old,neighbour_timeouts,"
      "active_neighbours,saturated_ticks,saturation_fraction");
  for (const HealthRecord& h : run.health) {
    f.Num(ToSeconds(h.utime)).Int(h.process_id).Int(h.ticks).Num(h.lateness_p50_s)
        .Num(h.lateness_p99_s).Num(h.lateness_max_s).Int(h.overruns).Int(h.msgs_received)
        .Int(h.msgs_dropped_invalid).Int(h.msgs_dropped_old).Int(h.neighbour_timeouts)
        .Int(h.active_neighbours).Int(h.saturated_ticks).Num(h.saturation_fraction);
    f.EndRow();
  }
  return f.Close(error);
}

}  // namespace

bool WriteRunCsv(const RunData& run, const RunAnalysis& a, const std::string& dir,
                 std::vector<std::string>* files, std::string* error) {
  if (mkdir(dir.c_str(), 0755) != 0 && errno != EEXIST) {
    *error = dir + ": cannot create the CSV directory (" + std::strerror(errno) + ")";
    return false;
  }
  struct stat st {};
  if (stat(dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) {
    *error = dir + ": exists and is not a directory; give --csv a directory";
    return false;
  }
  for (std::size_t id = 0; id < run.vehicles.size(); ++id) {
    const std::vector<StateMsg>& s = run.vehicles[id].samples;
    const auto possible = [&](const StateMsg& m) { return PossibleTime(m, a.bounds); };
    if (std::none_of(s.begin(), s.end(), possible)) continue;
    const std::string p = dir + "/vehicle_" + std::to_string(id) + ".csv";
    if (!WriteVehicle(run, a, static_cast<int>(id), p, error)) return false;
    files->push_back(p);
  }
  const std::string ch = dir + "/channel_events.csv", he = dir + "/health.csv";
  if (!WriteChannel(run, a, ch, error)) return false;
  files->push_back(ch);
  if (!WriteHealth(run, he, error)) return false;
  files->push_back(he);
  return true;
}

}  // namespace shoal
