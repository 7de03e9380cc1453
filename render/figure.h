// Off-screen figures as plain data, rendered to PNG with OSMesa (library shoal_render).
//
// The library knows nothing about logs or LCM: a caller fills a Figure2D (a grid of x-y
// panels) or a Figure3D (trajectories and formation snapshots) with numbers and calls
// RenderPng. Geometry is drawn by OpenGL in an OSMesa context (llvmpipe, headless) into a
// 4x multisampled framebuffer; text is drawn on the CPU with stb_truetype (DejaVu Sans) and
// composited onto the read-back image; the PNG is written by stb_image_write.
//
// Sizes. Every size below that is given in "px" (line widths, marker sizes) is in pixels
// of a figure at scale 1. A figure's scale is chosen from its size, so that text, lines
// and markers keep their proportions at any --size: scale = sqrt(W*H / (1600*1000)) for
// a Figure2D and sqrt(W*H / (1400*1000)) for a Figure3D (clamped to [0.75, 3]), unless
// Figure2D::scale / Figure3D::scale is set (> 0).
//
// Long series. Time series are decimated inside the library to at most four points per
// pixel column (first, minimum, maximum, last: spikes are kept); scatter points to one
// per marker-sized cell; 3-D polylines to points at least a third of a pixel apart on the
// screen. Callers pass full-rate data.
//
// Errors never crash: RenderPng / RenderImage return false and say what is wrong and how
// to fix it (bad size, mismatched or empty series, nothing drawable, no OSMesa context,
// missing font, unwritable path).
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace shoal::render {

/// sRGB colour, components in [0, 1]; a < 1 blends over what is underneath.
struct Color {
  float r = 0.0f, g = 0.0f, b = 0.0f, a = 1.0f;
};

/// Colour from 0xRRGGBB.
Color Hex(std::uint32_t rgb, float alpha = 1.0f);

/// One fixed colour per vehicle id, the same in every figure: the leader (id 0) is near
/// black; followers 1..7 take the Okabe-Ito colour-blind-safe set (blue, vermillion,
/// bluish green, reddish purple, orange, sky blue, dark yellow); ids 8..16 brown, red,
/// buff, purple, dark teal, green, salmon, dark green, wine (16 colours pairwise at least
/// 20 CIELAB Delta-E apart); beyond that the sequence repeats. Negative ids: mid grey.
Color VehicleColor(int vehicle_id);

/// "leader" for id 0, "follower <id>" otherwise.
std::string VehicleName(int vehicle_id);

enum class LineStyle { kSolid, kDashed, kDotted, kNone };

/// kRing: a hollow circle.
enum class Marker { kNone, kCircle, kRing, kSquare, kDiamond, kTriangle, kCross, kPlus, kVBar };

/// Where a panel's legend goes.
///   kAuto: the inside corner (or top/bottom centre) that hides the fewest data points;
///          outside, right of the plot area, if every inside place would hide data.
///   kInside: the best inside place even if it hides some data.
///   kOutside: right of the plot area.   kNone: no legend.
enum class LegendPlacement { kAuto, kInside, kOutside, kNone };

/// One legend line: a sample of the series' line and/or marker and its label.
struct LegendEntry {
  std::string label;
  Color color;
  LineStyle line = LineStyle::kSolid;
  Marker marker = Marker::kNone;
  float line_width_px = 2.0f;  // the sample is drawn at most 5 px wide
};

/// An x-y data series. x and y have the same length (at least one point). A NaN or
/// infinite value (or one beyond +-1e300) breaks the line; on a log axis, so does a value
/// <= 0 (or below 1e-300). x need not be sorted, but sorted x (time series) is decimated
/// per pixel column and is much faster.
struct Series {
  std::string label;  // legend text; empty: not in the legend
  std::vector<double> x, y;
  Color color;
  LineStyle line = LineStyle::kSolid;  // kNone: markers only (scatter)
  float line_width_px = 2.0f;
  Marker marker = Marker::kNone;
  float marker_size_px = 7.0f;  // outer diameter
};

/// A horizontal (Panel::hlines) or vertical (Panel::vlines) line across the plot area at
/// a data value, e.g. a tolerance or the convergence time.
struct RefLine {
  double value = 0.0;
  Color color{0.35f, 0.35f, 0.35f, 1.0f};
  LineStyle line = LineStyle::kDashed;
  float line_width_px = 1.5f;
  std::string label;  // legend text; empty: not in the legend
};

/// An explicit tick (e.g. a category axis). Value in data units.
struct Tick {
  double value = 0.0;
  std::string label;
};

constexpr double kAutoRange = std::numeric_limits<double>::quiet_NaN();

struct Axis {
  std::string label;        // e.g. "x", "position error"
  std::string unit;         // e.g. "m"; shown as "x [m]"; empty: no brackets
  bool log = false;         // base-10 log scale; decades labelled 10ⁿ
  double min = kAutoRange;  // fixed range; NaN: from the data (y padded by 4 %; x tight
                            // for time series, padded for curves and markers)
  double max = kAutoRange;
  std::vector<Tick> ticks;  // explicit ticks; empty: automatic 1-2-5 ticks
  /// Values grow leftwards (x) or downwards (y), e.g. a depth drawn as it is in the sea.
  bool reversed = false;
};

/// A shaded x interval of a panel (e.g. the window of a scenario event): a translucent
/// rectangle from x0 to x1 over the plot's whole height, or over [y0, y1] (data units) when
/// both are finite. Drawn over the grid, under the reference lines and the data; it does
/// not widen the axes' ranges. The label (if any) is written in small text at its top
/// left, inside the plot. A band with a non-finite x0 or x1 is not drawn.
struct Band {
  double x0 = 0.0, x1 = 0.0;
  double y0 = kAutoRange, y1 = kAutoRange;
  Color color{0.5f, 0.5f, 0.5f, 0.15f};
  std::string label;
};

struct Panel {
  std::string title;
  /// A short explanation in smaller grey text on a line under the title (e.g. what the
  /// plotted quantity means in this run); empty: none. Kept to one line: long text is
  /// shrunk to fit the plot's width.
  std::string note;
  Axis x, y;
  std::vector<Series> series;
  std::vector<RefLine> hlines, vlines;
  std::vector<Band> bands;
  LegendPlacement legend = LegendPlacement::kAuto;
};

/// A figure: a title, an optional figure-wide legend (drawn in one row under the title,
/// e.g. one entry per vehicle for a grid of panels) and panels laid out row by row in
/// `columns` columns.
struct Figure2D {
  int width_px = 1600;
  int height_px = 1000;
  std::string title;
  int columns = 1;
  std::vector<Panel> panels;
  /// One x range for every panel (the union of their data); x tick labels and the x axis
  /// label only under the bottom panel of each column.
  bool link_x = false;
  std::vector<LegendEntry> legend;
  float scale = 0.0f;  // 0: from the figure size (see the top of this file)
  std::string font_path = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";
  std::string bold_font_path = "/usr/share/fonts/truetype/dejavu/DejaVuSans-Bold.ttf";
};

using Point3 = std::array<double, 3>;

/// A 3-D polyline (a trajectory). A NaN coordinate breaks the line.
struct Polyline3D {
  std::string label;  // legend text; empty: not in the legend
  std::vector<Point3> points;
  Color color;
  LineStyle line = LineStyle::kSolid;
  float line_width_px = 2.5f;
  bool mark_start = true;  // hollow circle (Marker::kRing) around the first point
  bool mark_end = true;    // filled square (Marker::kSquare) at the last point
};

/// The formation at one instant: a marker at each vehicle's position and segments
/// between pairs of them (indices into `points`).
struct Snapshot {
  std::string label;  // drawn next to points[0], e.g. "t = 120 s"; empty: none
  std::vector<Point3> points;
  std::vector<Color> colors;  // one per point; empty: all mid grey
  std::vector<std::pair<int, int>> edges;
  Color edge_color{0.3f, 0.3f, 0.3f, 0.75f};
  float edge_width_px = 1.5f;
  float marker_size_px = 9.0f;
};

/// A 3-D figure with a perspective camera fitted to the data's bounding box, the three
/// back panes of the box with grid lines, ticks and labels in the data's unit along three
/// edges, optional shadows of the trajectories on the floor, a legend and a title.
struct Figure3D {
  int width_px = 1400;
  int height_px = 1000;
  std::string title;
  std::vector<Polyline3D> lines;
  std::vector<Snapshot> snapshots;
  std::vector<LegendEntry> extra_legend;  // appended after the lines' entries
  /// Axis labels for the data's first, second and third coordinates, and their unit.
  std::string x_label = "x (north)";
  std::string y_label = "y (east)";
  std::string z_label = "z (down)";
  std::string unit = "m";
  /// The data is NED (x north, y east, z down): the third coordinate is drawn pointing
  /// down the screen (up is up) and the picture stays right-handed (not mirrored). Its
  /// tick labels are the data's values (depth grows downwards). false: z is up.
  bool z_down = true;
  /// With z_down: the sea surface, the plane z = 0, drawn light and translucent when it
  /// lies inside the box (the box is not enlarged to reach it).
  bool sea_surface = true;
  /// Camera: bearing (degrees from +x towards +y; for NED data the compass bearing) of the
  /// camera seen from the centre of the data, and its elevation above the horizontal
  /// (degrees). NaN azimuth (default): 300 degrees, unless the data's horizontal extent has
  /// a clear main direction (principal axes differ by more than 1.5x), in which case the
  /// camera looks at 60 degrees to that direction, so that a long straight run is seen
  /// from the side rather than end-on.
  double azimuth_deg = kAutoRange;
  double elevation_deg = 22.0;
  /// true: one metre is as long on every axis, except that an axis whose range is less
  /// than a quarter of the largest is stretched to a quarter (so a flat run is not a
  /// line). false: the box is a cube. A stretched axis says so in its title, e.g.
  /// "z (down) [m], stretched ×10" (the factor relative to the longest axis).
  bool equal_aspect = true;
  bool floor_shadows = true;  // light grey projections of the lines onto the floor
  float scale = 0.0f;         // 0: from the figure size
  std::string font_path = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";
  std::string bold_font_path = "/usr/share/fonts/truetype/dejavu/DejaVuSans-Bold.ttf";
};

/// An 8-bit RGBA image, rows top to bottom.
struct Image {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgba;
};

/// Renders into memory. False with a message in *err (if err is not null) on bad input or
/// when no OSMesa context can be created; never throws.
bool RenderImage(const Figure2D& figure, Image* out, std::string* err);
bool RenderImage(const Figure3D& figure, Image* out, std::string* err);

/// Renders and writes a PNG. False with a message on any failure (as RenderImage, and
/// when the file cannot be written).
bool RenderPng(const Figure2D& figure, const std::string& path, std::string* err);
bool RenderPng(const Figure3D& figure, const std::string& path, std::string* err);

bool WritePng(const Image& image, const std::string& path, std::string* err);

/// "WxH" (or "WXH") in pixels, each a decimal of at most 8 digits: false for anything else,
/// a number past an int's range too (which sscanf's %d would wrap). Callers check the range.
bool ParseImageSize(const std::string& text, int* width, int* height);

/// Checks a figure without rendering it: false with a message naming the panel and
/// series at fault and how to fix it.
bool Validate(const Figure2D& figure, std::string* err);
bool Validate(const Figure3D& figure, std::string* err);

}  // namespace shoal::render
