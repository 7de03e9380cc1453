// The figures of a recorded run (`shoal render`): turns a loaded log (analysis/run_data.h)
// and its analysis into the arrays of render/shoal_figures.h and writes the PNGs. Kept
// apart from shoal_render, which knows nothing about logs; the command only parses its
// arguments and prints what this returns.
#pragma once

#include <string>
#include <vector>

#include "analysis/analysis.h"
#include "analysis/run_data.h"
#include "render/shoal_figures.h"

namespace shoal::render {

/// Each vehicle's states (vehicles without samples are left out), leader first.
std::vector<VehicleSeries> VehicleSeriesOf(const RunData& run);

/// Each follower's tracking errors at the samples where they are finite (needs
/// a.has_formation); followers without such a sample are left out.
std::vector<ErrorSeries> ErrorSeriesOf(const RunData& run, const RunAnalysis& a);

/// Each directed link's delivered and dropped messages, ordered by (sender, receiver).
std::vector<LinkSeries> LinkSeriesOf(const RunData& run);

/// The channel figure's options for this run: the configured delay tau(t) every 10 ms (if
/// the run has a scenario), the run mode and control period for the panel's note.
ChannelOptions ChannelOptionsOf(const RunData& run, const RunAnalysis& a);

/// The scenario's [[event]] windows for the error figure: [at_s, end) with the end at the
/// event's end or the run's end `end_s`, labelled with the kind.
std::vector<EventWindow> EventWindowsOf(const RunData& run, double end_s);

/// The timeline's outages per link for the channel figure: link_down windows on their
/// links (every link when it names none), silent senders' and deaf receivers' windows on
/// their outgoing and incoming links (of every topology), ends clipped to `end_s`.
std::vector<LinkOutage> OutagesOf(const RunData& run, double end_s);

/// The delivered messages of links whose delay model in force at the send time is
/// acoustic, with their range from the logged states at the send time (messages whose
/// sender or receiver has no state at or before that time are left out), and the distinct
/// acoustic models. False if no link of the scenario is ever acoustic.
bool AcousticOf(const RunData& run, AcousticPoints* points, std::vector<AcousticModelLine>* models);

struct RunFigureOptions {
  int width_px = 0, height_px = 0;  // 0: each figure's default size
  bool linear_errors = false;       // tracking errors on a linear instead of a log axis
};

struct RunFigureReport {
  std::vector<std::string> written;   // paths of the PNGs written
  std::vector<std::string> skipped;   // one sentence per figure left out, and why
  std::vector<std::string> failures;  // "path: message" per figure not drawn or written
};

/// Writes trajectory.png, states.png, errors.png (needs the scenario's offsets and the
/// leader), channel.png (needs SHOAL_CHANNEL events) and, when a link's delay model is
/// acoustic, acoustic_delay.png into out_dir. False (with *err)
/// only if there is nothing to draw; figures that fail are listed in report->failures.
bool WriteRunFigures(const RunData& run, const std::string& out_dir, const RunFigureOptions& o,
                     RunFigureReport* report, std::string* err);

/// Creates out_dir if needed and checks that it is a writable directory, so that a bad
/// --out fails before the log is read. False with a message saying what to change.
bool PrepareOutputDir(const std::string& out_dir, std::string* err);

}  // namespace shoal::render
