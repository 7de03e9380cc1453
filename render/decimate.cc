#include "render/decimate.h"

#include <algorithm>
#include <cmath>

namespace shoal::render {

bool IsSortedX(const double* x, std::size_t n) {
  double last = -INFINITY;
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(x[i])) continue;
    if (x[i] < last) return false;
    last = x[i];
  }
  return true;
}

namespace {

// Collects one column's first, min, max and last points and emits them in index order.
class ColumnAccumulator {
 public:
  explicit ColumnAccumulator(IndexRuns* out) : out_(out) {}

  void Add(std::uint32_t i, double y, long column) {
    if (!open_ || column != column_) {
      Flush();
      open_ = true;
      column_ = column;
      first_ = min_ = max_ = last_ = i;
      ymin_ = ymax_ = y;
      return;
    }
    last_ = i;
    if (y < ymin_) {
      ymin_ = y;
      min_ = i;
    }
    if (y > ymax_) {
      ymax_ = y;
      max_ = i;
    }
  }

  void Flush() {
    if (!open_) return;
    std::uint32_t k[4] = {first_, min_, max_, last_};
    std::sort(k, k + 4);
    for (int j = 0; j < 4; ++j) {
      if (j > 0 && k[j] == k[j - 1]) continue;
      out_->index.push_back(k[j]);
    }
    open_ = false;
  }

  void EndRun() {
    Flush();
    run_open_ = false;
  }

  void BeginRunIfNeeded() {
    if (run_open_) return;
    out_->start.push_back(out_->index.size());
    run_open_ = true;
  }

 private:
  IndexRuns* out_;
  bool open_ = false;
  bool run_open_ = false;
  long column_ = 0;
  std::uint32_t first_ = 0, min_ = 0, max_ = 0, last_ = 0;
  double ymin_ = 0.0, ymax_ = 0.0;
};

// Drops empty runs (a run opened but nothing emitted cannot happen, but keep it tidy).
void DropEmptyRuns(IndexRuns* r) {
  IndexRuns out;
  out.index = std::move(r->index);
  for (std::size_t k = 0; k < r->start.size(); ++k) {
    const std::size_t end = k + 1 < r->start.size() ? r->start[k + 1] : out.index.size();
    if (end > r->start[k]) out.start.push_back(r->start[k]);
  }
  *r = std::move(out);
}

}  // namespace

IndexRuns DecimateMinMax(const double* x, const double* y, std::size_t n, double x0,
                         double px_per_x, int columns) {
  IndexRuns runs;
  ColumnAccumulator acc(&runs);
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(x[i]) || !std::isfinite(y[i])) {
      acc.EndRun();
      continue;
    }
    const double c = std::floor((x[i] - x0) * px_per_x);
    long column;
    if (!(c >= 0.0)) {
      column = -1;
    } else if (c >= columns) {
      column = columns;
    } else {
      column = static_cast<long>(c);
    }
    acc.BeginRunIfNeeded();
    acc.Add(static_cast<std::uint32_t>(i), y[i], column);
  }
  acc.EndRun();
  DropEmptyRuns(&runs);
  return runs;
}

IndexRuns DecimateByDistance(const double* px, const double* py, std::size_t n, double min_px) {
  IndexRuns runs;
  bool open = false;
  double lx = 0.0, ly = 0.0;
  std::uint32_t pending = 0;
  bool has_pending = false;  // last point of the run, not yet kept
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(px[i]) || !std::isfinite(py[i])) {
      if (has_pending) runs.index.push_back(pending);
      has_pending = false;
      open = false;
      continue;
    }
    if (!open) {
      runs.start.push_back(runs.index.size());
      runs.index.push_back(static_cast<std::uint32_t>(i));
      lx = px[i];
      ly = py[i];
      open = true;
      has_pending = false;
      continue;
    }
    if (std::max(std::fabs(px[i] - lx), std::fabs(py[i] - ly)) >= min_px) {
      runs.index.push_back(static_cast<std::uint32_t>(i));
      lx = px[i];
      ly = py[i];
      has_pending = false;
    } else {
      pending = static_cast<std::uint32_t>(i);
      has_pending = true;
    }
  }
  if (has_pending) runs.index.push_back(pending);
  return runs;
}

std::vector<std::uint32_t> DecimateScatter(const double* px, const double* py, std::size_t n,
                                           double w, double h, double cell_px,
                                           std::vector<std::uint32_t>* counts) {
  std::vector<std::uint32_t> kept;
  if (counts) counts->clear();
  if (!(w > 0) || !(h > 0) || !(cell_px > 0)) return kept;
  const long cols = static_cast<long>(std::ceil(w / cell_px));
  const long rows = static_cast<long>(std::ceil(h / cell_px));
  // Per cell: 0 = empty, else 1 + position of its point in `kept`.
  std::vector<std::uint32_t> slot(static_cast<std::size_t>(cols * rows), 0);
  for (std::size_t i = 0; i < n; ++i) {
    if (!(px[i] >= 0.0 && px[i] < w && py[i] >= 0.0 && py[i] < h)) continue;
    const long c = std::min(cols - 1, static_cast<long>(px[i] / cell_px));
    const long r = std::min(rows - 1, static_cast<long>(py[i] / cell_px));
    std::uint32_t& s = slot[static_cast<std::size_t>(r * cols + c)];
    if (s != 0) {
      if (counts) ++(*counts)[s - 1];
      continue;
    }
    kept.push_back(static_cast<std::uint32_t>(i));
    if (counts) counts->push_back(1);
    s = static_cast<std::uint32_t>(kept.size());
  }
  return kept;
}

void SimplifyPolyline(std::vector<float>* xs, std::vector<float>* ys, float tol) {
  std::vector<float>& x = *xs;
  std::vector<float>& y = *ys;
  const std::size_t n = x.size();
  if (n < 3) return;
  std::size_t out = 1;  // x[0] stays
  std::size_t anchor = 0;
  // Cone of admissible directions from the anchor, as an angle interval relative to `base`.
  bool constrained = false;
  double base = 0.0, lo = 0.0, hi = 0.0;
  std::size_t last = 0;  // last point accepted into the current segment
  const auto restart = [&](std::size_t a) {
    anchor = a;
    constrained = false;
  };
  for (std::size_t i = 1; i < n; ++i) {
    const double dx = x[i] - x[anchor], dy = y[i] - y[anchor];
    const double d = std::hypot(dx, dy);
    bool inside = true;
    if (d > tol) {
      const double dir = std::atan2(dy, dx);
      const double half = std::asin(std::min(1.0, tol / d));
      if (!constrained) {
        base = dir;
        lo = -half;
        hi = half;
        constrained = true;
      } else {
        const double rel = std::remainder(dir - base, 2.0 * M_PI);
        if (rel < lo || rel > hi) {
          inside = false;
        } else {
          lo = std::max(lo, rel - half);
          hi = std::min(hi, rel + half);
        }
      }
    }
    if (inside) {
      last = i;
      continue;
    }
    // The previous point ends the segment and anchors the next one.
    x[out] = x[last];
    y[out] = y[last];
    ++out;
    restart(last);
    --i;  // re-examine this point from the new anchor
  }
  x[out] = x[n - 1];
  y[out] = y[n - 1];
  ++out;
  x.resize(out);
  y.resize(out);
}

}  // namespace shoal::render
