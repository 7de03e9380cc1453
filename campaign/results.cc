#include "campaign/results.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "campaign/criteria.h"

namespace shoal {
namespace {

using ojson = nlohmann::ordered_json;

std::string Dump(const ojson& j) {
  return j.dump(-1, ' ', false, ojson::error_handler_t::replace);
}

/// FNV-1a, 64 bits: an identity check of the campaign, not a security measure.
std::string Fnv1a(const std::string& text) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (const char c : text) {
    h ^= static_cast<unsigned char>(c);
    h *= 0x100000001b3ULL;
  }
  char out[17];
  std::snprintf(out, sizeof(out), "%016llx", static_cast<unsigned long long>(h));
  return out;
}

[[noreturn]] void FailIo(const std::string& path, const std::string& what) {
  throw CampaignError(path + ": cannot " + what + " (" + std::strerror(errno) + ")");
}

/// Writes `text` to `path` through a temporary file and a rename, flushed to disk, so that
/// a crash leaves the old file or the new one, never a part.
void WriteFileAtomically(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  const int fd = open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) FailIo(tmp, "write");
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      close(fd);
      FailIo(tmp, "write");
    }
    done += static_cast<std::size_t>(n);
  }
  if (fsync(fd) != 0 || close(fd) != 0) FailIo(tmp, "write");
  if (std::rename(tmp.c_str(), path.c_str()) != 0) FailIo(path, "replace");
}

std::string ReadWholeFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

/// The rows of a results.jsonl: a torn last line (a crash while writing) is skipped, as is
/// any line that is not a row of a point of this campaign.
Rows ReadRows(const std::string& path, std::int64_t points) {
  Rows rows;
  std::istringstream in(ReadWholeFile(path));
  std::string line;
  while (std::getline(in, line)) {
    ojson row = ojson::parse(line, nullptr, /*allow_exceptions=*/false);
    // Only rows as MakeRow writes them: a damaged line (a torn write, an edit) is dropped,
    // and its point runs again on resume.
    if (!row.is_object() || !row.contains("point") || !row["point"].is_number_integer() ||
        !row.contains("pass") || !row["pass"].is_boolean() || !row.contains("status") ||
        !row["status"].is_string()) {
      continue;
    }
    const std::int64_t p = row["point"].get<std::int64_t>();
    if (p < 0 || p >= points) continue;
    rows[p] = std::move(row);
  }
  return rows;
}

ojson ReadManifest(const std::string& dir) {
  const std::string path = dir + "/campaign.json";
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    throw CampaignError(dir + ": not a sweep's output directory (no campaign.json)");
  }
  ojson m = ojson::parse(ReadWholeFile(path), nullptr, false);
  if (!m.is_object() || !m.contains("hash") || !m.contains("points") ||
      !m["points"].is_number_integer()) {
    throw CampaignError(path + ": damaged (not a campaign.json written by shoal sweep)");
  }
  return m;
}

/// A CSV field: as is when plain, else quoted with quotes doubled.
std::string CsvField(const ojson& v) {
  if (v.is_null()) return "";
  const std::string text = v.is_string() ? v.get<std::string>() : Dump(v);
  if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string out = "\"";
  for (const char c : text) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

}  // namespace

bool ParseShard(const std::string& text, Shard* out, std::string* error) {
  int k = 0, n = 0;
  char tail = 0;
  if (std::sscanf(text.c_str(), "%d/%d%c", &k, &n, &tail) != 2 || k < 1 || n < 1 || k > n ||
      n > 1000000) {
    *error = "--shard " + text + ": must be K/N with 1 <= K <= N, e.g. --shard 1/4";
    return false;
  }
  *out = {k, n};
  return true;
}

namespace {

/// The pass criteria as a reader writes them: "converged = true", "x <= 0.5".
ojson CriteriaText(const Campaign& c) {
  ojson out = ojson::array();
  for (const CampaignCriterion& cr : c.pass) {
    if (cr.equals) out.push_back(cr.key + " = " + cr.equals->dump());
    std::string bound = cr.key;
    if (cr.min) bound = TomlFloatText(*cr.min) + " <= " + bound;
    if (cr.max) bound += " <= " + TomlFloatText(*cr.max);
    if (cr.min || cr.max) out.push_back(bound);
  }
  return out;
}

}  // namespace

void MapAxes(const Campaign& c, std::string* x, std::string* y) {
  // A missing side takes the first axis the other side does not name.
  const auto other = [&](const std::string& taken) -> std::string {
    for (const CampaignAxis& a : c.axes) {
      if (a.key != taken) return a.key;
    }
    return "";
  };
  if (!c.map_x.empty() && !c.map_y.empty()) {
    *x = c.map_x;
    *y = c.map_y;
  } else if (!c.map_x.empty()) {
    *x = c.map_x;
    *y = other(*x);
  } else if (!c.map_y.empty()) {
    *y = c.map_y;
    *x = other(*y);
  } else {
    *x = c.axes.empty() ? "" : c.axes[0].key;
    *y = c.axes.size() > 1 ? c.axes[1].key : "";
  }
}

nlohmann::ordered_json MakeManifest(const Campaign& c, const std::string& scenario_text,
                                    const std::vector<std::string>& cli_set,
                                    const std::vector<CampaignPoint>& points, const Shard& shard,
                                    const nlohmann::ordered_json& theory) {
  ojson identity;
  identity["scenario_text"] = scenario_text;
  identity["engine"] = EngineName(c.engine);
  identity["duration_s"] = c.duration_s;
  ojson set = ojson::array();
  for (const CampaignSet& s : c.set) set.push_back(s.text);
  for (const std::string& s : cli_set) set.push_back(s);
  identity["set"] = set;
  ojson pass = ojson::array();
  for (const CampaignCriterion& cr : c.pass) {
    pass.push_back({cr.key, cr.equals ? ojson(*cr.equals) : ojson(),
                    cr.min ? ojson(*cr.min) : ojson(), cr.max ? ojson(*cr.max) : ojson()});
  }
  identity["pass"] = pass;
  ojson axes = ojson::array();
  for (const CampaignAxis& a : c.axes) axes.push_back(a.key);
  identity["axes"] = axes;
  std::string all = Dump(identity);
  for (const CampaignPoint& p : points) {
    for (const std::string& v : p.values) all += "\n" + v;
  }
  ojson m;
  m["campaign"] = c.path;
  m["scenario"] = c.scenario;
  m["engine"] = EngineName(c.engine);
  m["sampling"] = c.sampling == CampaignSampling::kLhs ? "lhs" : "grid";
  m["points"] = static_cast<std::int64_t>(points.size());
  m["axes"] = axes;
  std::string map_x, map_y;
  MapAxes(c, &map_x, &map_y);
  const auto log_axis = [&](const std::string& key) {
    for (const CampaignAxis& a : c.axes) {
      if (a.key == key) return a.kind == CampaignAxis::Kind::kFromTo && a.log;
    }
    return false;
  };
  m["map"] = {{"x", map_x}, {"y", map_y}, {"x_log", log_axis(map_x)}, {"y_log", log_axis(map_y)}};
  m["criteria"] = CriteriaText(c);
  m["set"] = set;
  m["hash"] = Fnv1a(all);
  m["shard"] = std::to_string(shard.k) + "/" + std::to_string(shard.n);
  m["theory"] = theory;
  return m;
}

nlohmann::ordered_json MakeRow(const Campaign& c, const CampaignPoint& point,
                               const PointOutcome& outcome, const std::string& command) {
  ojson row;
  row["point"] = point.index;
  for (std::size_t a = 0; a < c.axes.size(); ++a) row[c.axes[a].key] = point.json[a];
  row["status"] = PointStatusName(outcome.status);
  row["exit_status"] = outcome.signal != 0 ? ojson() : ojson(outcome.exit_status);
  bool pass = false;
  std::string why = outcome.why;
  if (outcome.status == PointStatus::kOk && c.pass.empty()) {
    // No [pass]: the run's own verdict (exit 0: converged, every process ok), never "no
    // criterion, so passed" for a run that diverged.
    pass = outcome.exit_status == 0;
    if (!pass) why = "the run exited " + std::to_string(outcome.exit_status) + " (no [pass]: a point passes when its run exits 0)";
  } else if (outcome.status == PointStatus::kOk) {
    const Judgement j = JudgeRun(c.pass, outcome.result);
    pass = j.pass;
    why = j.why;
  }
  row["pass"] = pass;
  row["why"] = why;
  row["wall_s"] = outcome.wall_s;
  row["cpu_s"] = outcome.cpu_s;
  const ojson metrics = FlattenScalars(outcome.result);
  for (auto it = metrics.begin(); it != metrics.end(); ++it) {
    if (!row.contains(it.key()) && it.key() != "command") row[it.key()] = *it;
  }
  row["command"] = command;
  return row;
}

ResultsDir::ResultsDir(std::string dir, const nlohmann::ordered_json& manifest)
    : dir_(std::move(dir)), manifest_(manifest) {
  std::error_code ec;
  std::filesystem::create_directories(dir_, ec);
  if (ec || !std::filesystem::is_directory(dir_, ec)) {
    throw CampaignError(dir_ + ": cannot create the output directory (" + ec.message() + ")");
  }
  const std::string manifest_path = dir_ + "/campaign.json";
  if (std::filesystem::exists(manifest_path, ec)) {
    const ojson old = ReadManifest(dir_);
    if (old["hash"] != manifest["hash"]) {
      throw CampaignError(dir_ + ": holds the results of another campaign (its campaign.json "
                          "differs in scenario, overrides, criteria or points); use another "
                          "--out directory, or remove this one");
    }
    if (old.value("shard", "1/1") != manifest["shard"].get<std::string>()) {
      throw CampaignError(dir_ + ": holds the results of shard " + old.value("shard", "1/1") +
                          ", not " + manifest["shard"].get<std::string>() +
                          "; use another --out directory");
    }
    rows_ = ReadRows(dir_ + "/results.jsonl", manifest["points"].get<std::int64_t>());
    // The same points, with what does not change a row changed (the map's axes and its
    // theory, the campaign file's path): campaign.json takes the new, so that a merge
    // draws what this sweep's summary draws.
    if (old != manifest) WriteFileAtomically(manifest_path, manifest.dump(2) + "\n");
  } else {
    // A directory with results but no campaign.json is not ours to add to.
    if (std::filesystem::exists(dir_ + "/results.jsonl", ec)) {
      throw CampaignError(dir_ + ": holds a results.jsonl but no campaign.json; use another "
                          "--out directory");
    }
    WriteFileAtomically(manifest_path, manifest.dump(2) + "\n");
  }
  const std::string results = dir_ + "/results.jsonl";
  fd_ = open(results.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (fd_ < 0) FailIo(results, "write");
  // A torn last line (killed while writing) would glue to the next row: end it first.
  const std::string text = ReadWholeFile(results);
  if (!text.empty() && text.back() != '\n' && write(fd_, "\n", 1) != 1) FailIo(results, "write");
}

ResultsDir::~ResultsDir() {
  if (fd_ >= 0) close(fd_);
}

void ResultsDir::Append(const nlohmann::ordered_json& row) {
  const std::string line = Dump(row) + "\n";
  std::size_t done = 0;
  while (done < line.size()) {
    const ssize_t n = write(fd_, line.data() + done, line.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) FailIo(dir_ + "/results.jsonl", "write");
    done += static_cast<std::size_t>(n);
  }
  if (fsync(fd_) != 0) FailIo(dir_ + "/results.jsonl", "flush");
  rows_[row["point"].get<std::int64_t>()] = row;
}

void ResultsDir::Finish() const { WriteResults(dir_, manifest_, rows_); }

std::string RowsCsv(const Rows& rows) {
  std::vector<std::string> columns;
  std::set<std::string> seen;
  for (const auto& [p, row] : rows) {
    for (auto it = row.begin(); it != row.end(); ++it) {
      if (seen.insert(it.key()).second) columns.push_back(it.key());
    }
  }
  std::string out;
  for (std::size_t i = 0; i < columns.size(); ++i) {
    out += (i ? "," : "") + CsvField(columns[i]);
  }
  out += "\n";
  for (const auto& [p, row] : rows) {
    for (std::size_t i = 0; i < columns.size(); ++i) {
      const auto it = row.find(columns[i]);
      out += (i ? "," : "") + (it == row.end() ? std::string() : CsvField(*it));
    }
    out += "\n";
  }
  return out;
}

void WriteResults(const std::string& dir, const nlohmann::ordered_json& manifest, const Rows& rows) {
  std::string jsonl;
  for (const auto& [p, row] : rows) jsonl += Dump(row) + "\n";
  WriteFileAtomically(dir + "/results.jsonl", jsonl);
  WriteFileAtomically(dir + "/results.csv", RowsCsv(rows));
  WriteFileAtomically(dir + "/summary.json", Summarize(manifest, rows).dump(2) + "\n");
}

namespace {

/// Along `key` with the other axes fixed: per line, the last value that passes before the
/// first that fails, and that first failing value (null where there is none).
ojson Boundaries(const std::string& key, const ojson& axes, const Rows& rows) {
  std::vector<std::string> order;
  std::map<std::string, std::pair<ojson, std::vector<const ojson*>>> lines;
  for (const auto& [p, row] : rows) {
    ojson fixed = ojson::object();
    for (const auto& other : axes) {
      const std::string k = other.get<std::string>();
      if (k != key) fixed[k] = row.value(k, ojson());
    }
    const std::string id = Dump(fixed);
    auto [it, added] = lines.try_emplace(id);
    if (added) order.push_back(id), it->second.first = fixed;
    it->second.second.push_back(&row);
  }
  ojson out = ojson::array();
  for (const std::string& id : order) {
    const auto& [fixed, line] = lines[id];
    ojson last_pass, first_fail;
    for (const ojson* row : line) {
      if (!(*row)["pass"].get<bool>()) {
        first_fail = row->value(key, ojson());
        break;
      }
      last_pass = row->value(key, ojson());
    }
    out.push_back({{"fixed", fixed}, {"last_pass", last_pass}, {"first_fail", first_fail}});
  }
  return out;
}

/// Pass rate per value of `key`, in first-seen order.
ojson PassRates(const std::string& key, const Rows& rows) {
  std::vector<std::string> order;
  std::map<std::string, ojson> values;
  for (const auto& [p, row] : rows) {
    const ojson value = row.value(key, ojson());
    const std::string id = Dump(value);
    auto [it, added] = values.try_emplace(id, ojson{{"value", value}, {"points", 0}, {"passed", 0}});
    if (added) order.push_back(id);
    it->second["points"] = it->second["points"].get<int>() + 1;
    if (row["pass"].get<bool>()) it->second["passed"] = it->second["passed"].get<int>() + 1;
  }
  ojson out = ojson::array();
  for (const std::string& id : order) {
    ojson v = values[id];
    v["pass_rate"] = v["passed"].get<double>() / v["points"].get<double>();
    out.push_back(v);
  }
  return out;
}

}  // namespace

nlohmann::ordered_json Summarize(const nlohmann::ordered_json& manifest, const Rows& rows) {
  ojson s;
  for (const char* key : {"campaign", "scenario", "engine", "sampling", "points"}) {
    s[key] = manifest.value(key, ojson());
  }
  s["finished"] = rows.size();
  int passed = 0, failed = 0, crashed = 0, timeout = 0, no_result = 0;
  for (const auto& [p, row] : rows) {
    const std::string status = row.value("status", "");
    if (status == "crashed") ++crashed;
    else if (status == "timeout") ++timeout;
    else if (status == "no_result") ++no_result;
    else if (row.value("pass", false)) ++passed;
    else ++failed;
  }
  s["passed"] = passed;
  s["failed"] = failed;
  s["crashed"] = crashed;
  s["timeout"] = timeout;
  s["no_result"] = no_result;
  const ojson& axes = manifest["axes"];
  const bool grid = manifest.value("sampling", "grid") == "grid";
  s["axes"] = ojson::array();
  for (const auto& axis : axes) {
    const std::string key = axis.get<std::string>();
    ojson a = {{"key", key}, {"values", PassRates(key, rows)}};
    // A Latin hypercube has no lines along an axis: its boundary is the map's business.
    // Seeds have no order that matters: "fails from seed 2 on" would be noise.
    if (grid && key != "run.seed") a["boundary"] = Boundaries(key, axes, rows);
    s["axes"].push_back(a);
  }
  s["map"] = manifest.value("map", ojson());
  s["criteria"] = manifest.value("criteria", ojson::array());
  s["theory"] = manifest.value("theory", ojson());
  return s;
}

Rows MergeResults(const std::vector<std::string>& dirs, const std::string& out,
                  bool allow_missing, bool allow_overlap) {
  if (dirs.empty()) throw CampaignError("merge: no directories given");
  std::error_code same_ec;
  for (const std::string& dir : dirs) {
    if (std::filesystem::equivalent(dir, out, same_ec)) {
      throw CampaignError("merge: --out " + out + " is one of the shard directories (" + dir +
                          "); merge into a directory of its own");
    }
  }
  const ojson first = ReadManifest(dirs[0]);
  const std::int64_t points = first["points"].get<std::int64_t>();
  Rows rows;
  // What --out holds already is kept or refused, never lost: an earlier merge or a whole
  // sweep of this campaign gives its rows to points the directories do not hold; a shard's
  // directory, another campaign's or results without a campaign.json are refused.
  Rows kept;
  std::error_code out_ec;
  if (std::filesystem::exists(out + "/campaign.json", out_ec)) {
    const ojson old = ReadManifest(out);
    if (old["hash"] != first["hash"]) {
      throw CampaignError(out + ": holds the results of another campaign; use another --out");
    }
    if (old.value("shard", "1/1") != "1/1") {
      throw CampaignError(out + ": holds the results of shard " + old.value("shard", "") +
                          "; merge into a directory of its own, or list it among the "
                          "directories to merge");
    }
    kept = ReadRows(out + "/results.jsonl", points);
  } else if (std::filesystem::exists(out + "/results.jsonl", out_ec)) {
    throw CampaignError(out + ": holds a results.jsonl but no campaign.json; use another --out "
                        "directory");
  }
  std::vector<std::string> overlaps;
  for (const std::string& dir : dirs) {
    const ojson m = ReadManifest(dir);
    if (m["hash"] != first["hash"]) {
      throw CampaignError(dir + ": results of another campaign than " + dirs[0] +
                          " (campaign.json differs); merge shards of one campaign only");
    }
    for (auto& [p, row] : ReadRows(dir + "/results.jsonl", points)) {
      if (rows.count(p)) {
        overlaps.push_back(std::to_string(p));
        continue;
      }
      rows[p] = std::move(row);
    }
  }
  for (auto& [p, row] : kept) rows.emplace(p, std::move(row));  // the directories' first
  const auto list = [](const std::vector<std::string>& v) {
    std::string text;
    for (std::size_t i = 0; i < v.size() && i < 20; ++i) text += (i ? ", " : "") + v[i];
    return v.size() > 20 ? text + ", ... (" + std::to_string(v.size()) + " in all)" : text;
  };
  if (!overlaps.empty() && !allow_overlap) {
    throw CampaignError("merge: points in more than one directory: " + list(overlaps) +
                        "; merge each shard once, or pass --allow-overlap to keep the first");
  }
  std::vector<std::string> missing;
  for (std::int64_t p = 0; p < points; ++p) {
    if (!rows.count(p)) missing.push_back(std::to_string(p));
  }
  if (!missing.empty() && !allow_missing) {
    throw CampaignError("merge: points missing from every directory: " + list(missing) +
                        "; run the missing shards (or resume them), or pass --allow-missing");
  }
  ojson manifest = first;
  manifest["shard"] = "1/1";
  std::error_code ec;
  std::filesystem::create_directories(out, ec);
  if (ec) throw CampaignError(out + ": cannot create the output directory (" + ec.message() + ")");
  WriteFileAtomically(out + "/campaign.json", manifest.dump(2) + "\n");
  WriteResults(out, manifest, rows);
  return rows;
}

}  // namespace shoal
