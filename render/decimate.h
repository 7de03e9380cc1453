// Reduction of long series to what a raster can show (pure functions, no rendering).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace shoal::render {

/// Runs of point indices to draw as connected polylines; a run ends at a non-finite x or
/// y and at the end of the data.
struct IndexRuns {
  std::vector<std::uint32_t> index;  // indices into the series, ascending
  std::vector<std::size_t> start;    // start[r] = first position in `index` of run r
  std::size_t runs() const { return start.size(); }
  std::size_t run_size(std::size_t r) const {
    return (r + 1 < start.size() ? start[r + 1] : index.size()) - start[r];
  }
};

/// True if x is non-decreasing over its finite values.
bool IsSortedX(const double* x, std::size_t n);

/// Min/max ("M4") decimation of a series with non-decreasing x onto pixel columns:
/// column c holds the points with floor((x - x0) * px_per_x) == c for 0 <= c < columns,
/// everything left of the view is one column and everything right of it another. Each
/// column keeps its first, lowest, highest and last point (in index order), so a line
/// through the kept points covers exactly the pixels the full series would, spikes
/// included: at most 4 * (columns + 2) points per run.
IndexRuns DecimateMinMax(const double* x, const double* y, std::size_t n, double x0,
                         double px_per_x, int columns);

/// Decimation for any point order (e.g. 3-D projections, unsorted x): keeps a point when it
/// is at least `min_px` away (max-norm, in pixels) from the last kept one, and the last
/// point of every run. px, py are pixel coordinates.
IndexRuns DecimateByDistance(const double* px, const double* py, std::size_t n, double min_px);

/// Scatter points: the first point in each `cell_px`-sized cell of a w x h pixel area
/// (points outside [0, w) x [0, h) are dropped), in index order. px, py are pixel
/// coordinates. If `counts` is not null, counts[k] is the number of points that fell into
/// the cell of kept point k (to draw translucent markers as dense as the data).
std::vector<std::uint32_t> DecimateScatter(const double* px, const double* py, std::size_t n,
                                           double w, double h, double cell_px,
                                           std::vector<std::uint32_t>* counts = nullptr);

/// Simplifies a polyline in pixel coordinates in place: drops points whose removal moves
/// the line by less than `tolerance_px` (the sleeve-fitting algorithm of Zhao and Saalfeld,
/// 1997: a point is kept when the direction to it leaves the cone of directions that keep
/// every skipped point within the tolerance of the new segment). Linear time. The first
/// and last points are always kept.
void SimplifyPolyline(std::vector<float>* x, std::vector<float>* y, float tolerance_px);

}  // namespace shoal::render
