#include "campaign/points.h"

#include <cmath>
#include <cstdint>
#include <numeric>

#include "core/rng.h"

namespace shoal {
namespace {

/// One value of an axis, as text and as JSON.
struct AxisValue {
  std::string text;
  nlohmann::json json;
};

AxisValue FloatValue(double v) { return {TomlFloatText(v), v}; }

AxisValue IntValue(std::int64_t v) { return {std::to_string(v), v}; }

/// from/to at fraction t in [0, 1], evenly or log spaced; the ends are exact.
double Interpolate(const CampaignAxis& a, double t) {
  if (t <= 0) return a.from;
  if (t >= 1) return a.to;
  if (a.log) return std::exp(std::log(a.from) + t * (std::log(a.to) - std::log(a.from)));
  return a.from + t * (a.to - a.from);
}

/// The grid values of an axis, in order.
std::vector<AxisValue> GridValues(const CampaignAxis& a) {
  std::vector<AxisValue> out;
  switch (a.kind) {
    case CampaignAxis::Kind::kValues:
      for (std::size_t i = 0; i < a.values.size(); ++i) out.push_back({a.values[i], a.json_values[i]});
      break;
    case CampaignAxis::Kind::kFromTo:
      for (std::int64_t i = 0; i < a.steps; ++i) {
        const double t = a.steps == 1 ? 0.0 : static_cast<double>(i) / static_cast<double>(a.steps - 1);
        out.push_back(FloatValue(Interpolate(a, t)));
      }
      break;
    case CampaignAxis::Kind::kRange:
      for (std::int64_t v = a.range_lo; v <= a.range_hi; ++v) out.push_back(IntValue(v));
      break;
  }
  return out;
}

std::vector<CampaignPoint> GridPoints(const Campaign& c) {
  std::vector<std::vector<AxisValue>> values;
  for (const CampaignAxis& axis : c.axes) values.push_back(GridValues(axis));
  const std::int64_t count = PointCount(c);
  std::vector<CampaignPoint> points(static_cast<std::size_t>(count));
  for (std::int64_t p = 0; p < count; ++p) {
    CampaignPoint& point = points[static_cast<std::size_t>(p)];
    point.index = p;
    point.values.resize(values.size());
    point.json.resize(values.size());
    // Mixed radix with the last axis the fastest digit.
    std::int64_t rest = p;
    for (std::size_t a = values.size(); a-- > 0;) {
      const std::int64_t n = static_cast<std::int64_t>(values[a].size());
      const AxisValue& v = values[a][static_cast<std::size_t>(rest % n)];
      rest /= n;
      point.values[a] = v.text;
      point.json[a] = v.json;
    }
  }
  return points;
}

/// Uniform integer in [0, k), without modulo bias (rejection of the top partial block).
std::uint64_t Below(Rng* rng, std::uint64_t k) {
  const std::uint64_t limit = UINT64_MAX - UINT64_MAX % k;
  std::uint64_t x = rng->Next();
  while (x >= limit) x = rng->Next();
  return x % k;
}

constexpr std::uint64_t kLhsStream = 0x4c4853;  // "LHS": a stream of its own per axis

/// Latin hypercube: for each axis, the n points fall one in each of n equal strata of
/// [0, 1), in an order shuffled by Fisher-Yates; the position inside the stratum is
/// uniform. from/to axes map it continuously (log-uniform with log); values and range
/// axes choose the value whose share of [0, 1) holds it.
std::vector<CampaignPoint> LhsPoints(const Campaign& c) {
  const std::int64_t n = c.samples;
  std::vector<CampaignPoint> points(static_cast<std::size_t>(n));
  for (std::int64_t p = 0; p < n; ++p) {
    points[static_cast<std::size_t>(p)].index = p;
    points[static_cast<std::size_t>(p)].values.resize(c.axes.size());
    points[static_cast<std::size_t>(p)].json.resize(c.axes.size());
  }
  std::vector<std::int64_t> strata(static_cast<std::size_t>(n));
  for (std::size_t a = 0; a < c.axes.size(); ++a) {
    const CampaignAxis& axis = c.axes[a];
    Rng rng(c.seed, kLhsStream, a);
    std::iota(strata.begin(), strata.end(), 0);
    for (std::size_t i = strata.size(); i > 1; --i) {
      std::swap(strata[i - 1], strata[Below(&rng, i)]);
    }
    const std::vector<AxisValue> choices =
        axis.kind == CampaignAxis::Kind::kFromTo ? std::vector<AxisValue>{} : GridValues(axis);
    for (std::int64_t p = 0; p < n; ++p) {
      const double u = (static_cast<double>(strata[static_cast<std::size_t>(p)]) + rng.Uniform()) /
                       static_cast<double>(n);
      AxisValue v;
      if (axis.kind == CampaignAxis::Kind::kFromTo) {
        v = FloatValue(Interpolate(axis, u));
      } else {
        const std::size_t k = std::min(choices.size() - 1,
                                       static_cast<std::size_t>(u * static_cast<double>(choices.size())));
        v = choices[k];
      }
      points[static_cast<std::size_t>(p)].values[a] = v.text;
      points[static_cast<std::size_t>(p)].json[a] = v.json;
    }
  }
  return points;
}

}  // namespace

std::vector<CampaignPoint> MakePoints(const Campaign& c) {
  return c.sampling == CampaignSampling::kLhs ? LhsPoints(c) : GridPoints(c);
}

}  // namespace shoal
