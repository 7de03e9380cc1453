// The results of a campaign in its output directory (docs/campaigns.md):
//   campaign.json   what made the directory (points, hash, shard): resume and merge check it
//   results.jsonl   one row per finished point, appended and flushed to disk as each ends;
//                   rewritten in point order when the campaign ends
//   results.csv     the same rows as CSV (columns: the union, in first-seen order)
//   summary.json    counts, pass rate per axis value, the pass/fail boundary along each
//                   axis, the theory curves of the map
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "campaign/campaign_file.h"
#include "campaign/executor.h"
#include "campaign/points.h"

namespace shoal {

/// `--shard K/N`: this run does the points with index % n == k - 1.
struct Shard {
  int k = 1, n = 1;
  bool Has(std::int64_t point) const { return point % n == k - 1; }
};
/// Parses "K/N" (1 <= K <= N <= 1e6); false with *error otherwise.
bool ParseShard(const std::string& text, Shard* out, std::string* error);

/// The map's axes: [map] x and y; one given, the other is the first axis it does not name;
/// neither, the first two axes ("" when there is no second).
void MapAxes(const Campaign& c, std::string* x, std::string* y);

/// What identifies a campaign's results: the campaign file's path, the base scenario's
/// text, the overrides, engine, duration and criteria, and every point. `theory` is kept
/// for the summary (merge rebuilds it from here).
nlohmann::ordered_json MakeManifest(const Campaign& c, const std::string& scenario_text,
                                    const std::vector<std::string>& cli_set,
                                    const std::vector<CampaignPoint>& points, const Shard& shard,
                                    const nlohmann::ordered_json& theory);

/// One result row (field order as docs/campaigns.md lists them).
nlohmann::ordered_json MakeRow(const Campaign& c, const CampaignPoint& point,
                               const PointOutcome& outcome, const std::string& command);

using Rows = std::map<std::int64_t, nlohmann::ordered_json>;  // by point index

/// The output directory of one run (or shard) of a campaign.
class ResultsDir {
 public:
  /// Creates `dir` (and campaign.json) or, if it holds results already, checks that they
  /// are this campaign's (same hash and shard) and loads their rows: those points are not
  /// run again. Throws CampaignError.
  ResultsDir(std::string dir, const nlohmann::ordered_json& manifest);
  ~ResultsDir();
  ResultsDir(const ResultsDir&) = delete;
  ResultsDir& operator=(const ResultsDir&) = delete;

  const Rows& rows() const { return rows_; }
  /// Appends the row to results.jsonl and flushes it to disk (fsync).
  void Append(const nlohmann::ordered_json& row);
  /// Rewrites results.jsonl and results.csv in point order and writes summary.json.
  void Finish() const;

 private:
  std::string dir_;
  nlohmann::ordered_json manifest_;
  Rows rows_;
  int fd_ = -1;
};

/// Writes results.jsonl, results.csv and summary.json of `rows` into `dir`.
void WriteResults(const std::string& dir, const nlohmann::ordered_json& manifest, const Rows& rows);

/// summary.json of the rows.
nlohmann::ordered_json Summarize(const nlohmann::ordered_json& manifest, const Rows& rows);

/// The rows as CSV text.
std::string RowsCsv(const Rows& rows);

/// `shoal sweep merge`: combines shard directories of one campaign into `out`, as one run
/// would have written it. Refuses shards of different campaigns, points present in two
/// directories (unless allow_overlap: the first directory's row is kept) and missing
/// points (unless allow_missing), naming them. Throws CampaignError; returns the rows.
Rows MergeResults(const std::vector<std::string>& dirs, const std::string& out,
                  bool allow_missing, bool allow_overlap);

}  // namespace shoal
