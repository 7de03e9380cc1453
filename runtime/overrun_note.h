// A real-time loop's overrun as the process writes it to its output, one line each, and as
// shoal run reads it back: to tell the ticks the machine itself held (its witness,
// launcher/machine_witness.h) from those the process lost on its own, the verdict needs to
// know when each overrun happened, to the millisecond; the health reports say only in
// which second.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>

namespace shoal {

struct OverrunNote {
  std::int64_t tick = 0;
  /// When the tick was due: CLOCK_MONOTONIC ns, and s from the process's tick 0 (its phase
  /// included). A reader on the same kernel takes the first: the second rests on the
  /// process's own conversion of a wall-clock start time (--t0-unix-ns), which a step of
  /// the wall clock between two processes' starts shifts.
  std::int64_t due_ns = 0;
  double due_s = 0.0;
  double woke_s = 0.0;  // how late the loop woke for it
  double done_s = 0.0;  // when its step ended, s after it was due (above one period)
};

/// A process writes at most this many; after them one line says that more followed.
inline constexpr int kOverrunNotes = 200;
inline constexpr const char* kOverrunNotesEnd = "overrun: more than the notes above follow";

inline std::string FormatOverrunNote(const OverrunNote& n) {
  char text[160];
  std::snprintf(text, sizeof(text),
                "overrun: tick %lld due at t = %.6f s (CLOCK_MONOTONIC %lld ns), woke %.3f ms "
                "late, done %.3f ms after it was due",
                static_cast<long long>(n.tick), n.due_s, static_cast<long long>(n.due_ns),
                n.woke_s * 1e3, n.done_s * 1e3);
  return text;
}

/// `line` without its newline; false unless it is a note of FormatOverrunNote's.
inline bool ParseOverrunNote(const std::string& line, OverrunNote* n) {
  long long tick = 0, due_ns = 0;
  double due = 0, woke_ms = 0, done_ms = 0;
  int end = 0;
  if (std::sscanf(line.c_str(),
                  "overrun: tick %lld due at t = %lf s (CLOCK_MONOTONIC %lld ns), woke %lf ms "
                  "late, done %lf ms after it was due%n",
                  &tick, &due, &due_ns, &woke_ms, &done_ms, &end) != 5 ||
      end != static_cast<int>(line.size())) {
    return false;
  }
  *n = {tick, due_ns, due, woke_ms * 1e-3, done_ms * 1e-3};
  return true;
}

/// The channel emulator's counterpart: in real time it notes its releases whose messages
/// left more than kLateReleaseNoteS after they were due (the run verdict's limit on the
/// release error's p99, launcher/run_report.h), at most kOverrunNotes notes, so that the
/// verdict can tell releases the machine held from those the emulator was late for on its
/// own (LateReleaseNotes). Read back into an OverrunNote: tick 0, woke_s and done_s the
/// time from the first release the note covers until its last went out.
inline constexpr double kLateReleaseNoteS = 0.02;
inline constexpr const char* kLateReleaseNotesEnd =
    "late release: more than the notes above follow";

inline std::string FormatLateReleaseNote(std::int64_t due_ns, double due_s, double late_s) {
  char text[128];
  std::snprintf(text, sizeof(text),
                "late release: due at t = %.6f s (CLOCK_MONOTONIC %lld ns), sent %.3f ms late",
                due_s, static_cast<long long>(due_ns), late_s * 1e3);
  return text;
}

/// `line` without its newline; false unless it is a note of FormatLateReleaseNote's.
inline bool ParseLateReleaseNote(const std::string& line, OverrunNote* n) {
  long long due_ns = 0;
  double due = 0, late_ms = 0;
  int end = 0;
  if (std::sscanf(line.c_str(),
                  "late release: due at t = %lf s (CLOCK_MONOTONIC %lld ns), sent %lf ms late%n",
                  &due, &due_ns, &late_ms, &end) != 3 ||
      end != static_cast<int>(line.size())) {
    return false;
  }
  *n = {0, due_ns, due, late_ms * 1e-3, late_ms * 1e-3};
  return true;
}

/// Late releases gathered into notes. A stall holds back every release due while it lasts,
/// and under a delay model that gives each message its own delay that is one release per
/// message (thousands a second at 64 followers): a late release due before the open
/// note's last one went out joins that note, so that one stall is one note, as it is one
/// overrun per loop.
class LateReleaseNotes {
 public:
  /// A release due at due_ns (CLOCK_MONOTONIC; due_s from tick 0) whose last message went
  /// out at sent_ns. Returns a line to write (the note it closed), or "".
  std::string Add(std::int64_t due_ns, double due_s, std::int64_t sent_ns) {
    if (static_cast<double>(sent_ns - due_ns) <= kLateReleaseNoteS * 1e9) return "";
    if (open_ && due_ns <= sent_ns_) {
      sent_ns_ = sent_ns > sent_ns_ ? sent_ns : sent_ns_;
      return "";
    }
    std::string line = Finish();
    open_ = true;
    due_ns_ = due_ns;
    due_s_ = due_s;
    sent_ns_ = sent_ns;
    return line;
  }
  /// The open note's line (then closed), or "" if none is open or the notes are spent:
  /// kOverrunNotes notes, then kLateReleaseNotesEnd once.
  std::string Finish() {
    if (!open_) return "";
    open_ = false;
    if (written_ > kOverrunNotes) return "";
    return ++written_ > kOverrunNotes
               ? std::string(kLateReleaseNotesEnd)
               : FormatLateReleaseNote(due_ns_, due_s_, static_cast<double>(sent_ns_ - due_ns_) * 1e-9);
  }

 private:
  bool open_ = false;
  std::int64_t due_ns_ = 0, sent_ns_ = 0;
  double due_s_ = 0.0;
  int written_ = 0;
};

}  // namespace shoal
