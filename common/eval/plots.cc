#include "common/eval/plots.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace placerec {
namespace {

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr int kShift = 4;  // fractional bits of the polyline and marker coordinates
constexpr double kOne = 1 << kShift;
constexpr int kMinWidth = 200;
constexpr int kMinHeight = 150;
constexpr int kMaxSide = 8000;

const cv::Scalar kWhite(255, 255, 255);
const cv::Scalar kText(40, 40, 40);
const cv::Scalar kAxis(90, 90, 90);
const cv::Scalar kGrid(230, 230, 230);
const cv::Scalar kLegendBorder(175, 175, 175);

// Ten well-separated colours (the "tab10" set of many plotting tools), in BGR order.
const cv::Scalar kPalette[] = {{180, 119, 31},  {14, 127, 255}, {44, 160, 44},   {40, 39, 214},
                               {189, 103, 148}, {75, 86, 140},  {194, 119, 227}, {127, 127, 127},
                               {34, 189, 188},  {207, 190, 23}};
constexpr int kPaletteSize = sizeof(kPalette) / sizeof(kPalette[0]);

struct Font {
  double scale = 0.5;
  int thickness = 1;

  // Width, and height above plus below the baseline.
  cv::Size Measure(const std::string& text) const {
    int baseline = 0;
    const cv::Size size = cv::getTextSize(text, kFont, scale, thickness, &baseline);
    return {size.width, size.height + baseline};
  }
  int Ascent() const {
    int baseline = 0;
    return cv::getTextSize("0", kFont, scale, thickness, &baseline).height;
  }
  // Draws `text` with its top-left corner (of the ascent box) at `top_left`.
  void Draw(cv::Mat& image, const std::string& text, cv::Point top_left,
            const cv::Scalar& colour) const {
    int baseline = 0;
    const cv::Size size = cv::getTextSize(text, kFont, scale, thickness, &baseline);
    cv::putText(image, text, {top_left.x, top_left.y + size.height}, kFont, scale, colour,
                thickness, cv::LINE_AA);
  }
};

// Maps data coordinates (0..1 with a small margin so that lines on 0 and 1 stay visible) to
// pixels of the plot area.
struct Axes {
  cv::Rect box;
  double lo = -0.02;
  double hi = 1.02;

  cv::Point2d ToPixel(double x, double y) const {
    x = std::isnan(x) ? 0.0 : std::clamp(x, 0.0, 1.0);
    y = std::isnan(y) ? 0.0 : std::clamp(y, 0.0, 1.0);
    return {box.x + (x - lo) / (hi - lo) * box.width,
            box.y + box.height - (y - lo) / (hi - lo) * box.height};
  }
  // The same point in fixed-point coordinates for drawing with kShift.
  cv::Point ToFixed(double x, double y) const {
    const cv::Point2d p = ToPixel(x, y);
    return {cvRound(p.x * kOne), cvRound(p.y * kOne)};
  }
};

std::string TickLabel(int tenths) {
  return std::to_string(tenths / 10) + "." + std::to_string(tenths % 10);
}

// The step curve whose area is the average precision: precision P_i holds from recall R_{i-1}
// to R_i, starting at recall 0.
std::vector<cv::Point2d> StepCurve(const RunScore& score) {
  std::vector<cv::Point2d> points;
  double recall = 0;
  for (const PrPoint& p : score.curve) {
    points.push_back({recall, p.precision});
    points.push_back({p.recall, p.precision});
    recall = p.recall;
  }
  return points;
}

bool HasMarker(const RunScore& score) { return !score.curve.empty() && score.max_f1 > 0; }

// Shortens `text` with "..." until it fits in `width` pixels.
std::string Fit(const std::string& text, const Font& font, int width) {
  if (font.Measure(text).width <= width) return text;
  std::string shortened = text;
  while (!shortened.empty() && font.Measure(shortened + "...").width > width) shortened.pop_back();
  return shortened + "...";
}

void DrawMarker(cv::Mat& image, cv::Point centre_fixed, int radius, const cv::Scalar& fill) {
  cv::circle(image, centre_fixed, radius << kShift, fill, cv::FILLED, cv::LINE_AA, kShift);
  cv::circle(image, centre_fixed, radius << kShift, kText, 1, cv::LINE_AA, kShift);
}

// The legend: one row per curve (a line sample, its max-F1 marker, the label), and a last row
// explaining the marker.
struct Legend {
  std::vector<std::string> labels;
  std::vector<bool> markers;  // per curve row
  Font font;
  int pad = 8;
  int sample = 30;  // length of the line sample, pixels
  int text_height = 0;
  int row = 0;
  cv::Size size;

  bool empty() const { return labels.empty(); }
};

// Lays the legend out for at most `max_width` pixels: shrinks the font until the longest label
// fits, then cuts what still does not.
Legend MakeLegend(const std::vector<PrCurve>& curves, int max_width, double k) {
  Legend legend;
  for (const PrCurve& curve : curves) {
    legend.labels.push_back(curve.label);
    legend.markers.push_back(HasMarker(curve.score));
  }
  if (std::find(legend.markers.begin(), legend.markers.end(), true) != legend.markers.end()) {
    legend.labels.push_back("max F1");
  }
  legend.font = Font{0.5 * k, 1};
  legend.pad = std::max(4, cvRound(8 * k));
  legend.sample = std::max(16, cvRound(30 * k));
  auto widest = [&legend] {
    int w = 0;
    for (const std::string& label : legend.labels)
      w = std::max(w, legend.font.Measure(label).width);
    return w;
  };
  const int room = max_width - 3 * legend.pad - legend.sample;
  while (legend.font.scale > 0.3 && widest() > room) legend.font.scale *= 0.9;
  for (std::string& label : legend.labels) label = Fit(label, legend.font, room);
  legend.text_height = legend.font.Measure("Ag").height;
  legend.row = legend.text_height + legend.pad;
  legend.size = cv::Size(3 * legend.pad + legend.sample + widest(),
                         static_cast<int>(legend.labels.size()) * legend.row + legend.pad);
  return legend;
}

// How much `where` would hide: pixels of curve under it, plus a large penalty per max-F1 marker
// it covers or crowds.
double Hidden(const cv::Rect& where, const Axes& axes, const std::vector<PrCurve>& curves,
              const std::vector<std::vector<cv::Point2d>>& steps, int margin) {
  double hidden = 0;
  for (const std::vector<cv::Point2d>& step : steps) {
    for (size_t i = 1; i < step.size(); ++i) {
      const cv::Point2d from = axes.ToPixel(step[i - 1].x, step[i - 1].y);
      const cv::Point2d to = axes.ToPixel(step[i].x, step[i].y);
      const double length = cv::norm(to - from);
      const int samples = std::max(1, static_cast<int>(std::ceil(length / 2)));
      for (int s = 0; s <= samples; ++s) {
        const cv::Point2d p = from + (to - from) * (static_cast<double>(s) / samples);
        if (where.contains(cv::Point(cvRound(p.x), cvRound(p.y)))) hidden += length / (samples + 1);
      }
    }
  }
  const cv::Rect crowded(where.x - margin, where.y - margin, where.width + 2 * margin,
                         where.height + 2 * margin);
  for (const PrCurve& curve : curves) {
    if (!HasMarker(curve.score)) continue;
    const cv::Point2d m =
        axes.ToPixel(curve.score.recall_at_max_f1, curve.score.precision_at_max_f1);
    if (crowded.contains(cv::Point(cvRound(m.x), cvRound(m.y)))) hidden += 1e6;
  }
  return hidden;
}

// Of nine places in the plot area (corners, edge middles, centre), the one that hides least;
// lower left first, since PR curves usually start high on the left and fall to the right.
cv::Rect BestPlaceInside(const Legend& legend, const Axes& axes, const std::vector<PrCurve>& curves,
                         const std::vector<std::vector<cv::Point2d>>& steps, int inset,
                         double* hidden) {
  const cv::Rect& b = axes.box;
  const cv::Size& size = legend.size;
  const int x0 = b.x + inset;
  const int x1 = b.x + (b.width - size.width) / 2;
  const int x2 = b.br().x - inset - size.width;
  const int y0 = b.y + inset;
  const int y1 = b.y + (b.height - size.height) / 2;
  const int y2 = b.br().y - inset - size.height;
  const cv::Point places[] = {{x0, y2}, {x2, y2}, {x2, y0}, {x0, y0}, {x1, y2},
                              {x2, y1}, {x1, y0}, {x0, y1}, {x1, y1}};
  cv::Rect best(places[0], size);
  *hidden = -1;
  for (const cv::Point& place : places) {
    const cv::Rect candidate(place, size);
    const double h = Hidden(candidate, axes, curves, steps, inset);
    if (*hidden < 0 || h < *hidden) {
      *hidden = h;
      best = candidate;
    }
  }
  return best;
}

void DrawLegend(cv::Mat& image, const Legend& legend, const cv::Rect& where, double k) {
  // A slightly see-through box, so that a curve under it still shows faintly.
  cv::Mat under = image(where & cv::Rect(0, 0, image.cols, image.rows));
  cv::addWeighted(under, 0.12, cv::Mat(under.size(), under.type(), kWhite), 0.88, 0, under);
  cv::rectangle(image, where, kLegendBorder, 1, cv::LINE_AA);
  const int line_thickness = std::max(1, cvRound(2 * k));
  const int radius = std::max(3, cvRound(5 * k));
  const int pad = legend.pad;
  for (size_t i = 0; i < legend.labels.size(); ++i) {
    const int middle = where.y + pad + static_cast<int>(i) * legend.row + legend.text_height / 2;
    const cv::Point left(where.x + pad, middle);
    const cv::Point right(where.x + pad + legend.sample, middle);
    const cv::Point centre_fixed = ((left + right) / 2) * static_cast<int>(kOne);
    if (i < legend.markers.size()) {
      const cv::Scalar& colour = kPalette[i % kPaletteSize];
      cv::line(image, left, right, colour, line_thickness, cv::LINE_AA);
      if (legend.markers[i]) DrawMarker(image, centre_fixed, radius, colour);
    } else {
      DrawMarker(image, centre_fixed, radius, kWhite);
    }
    legend.font.Draw(image, legend.labels[i],
                     {where.x + 2 * pad + legend.sample, middle - legend.font.Ascent() / 2}, kText);
  }
}

Status WritePng(const std::string& path, const cv::Mat& image) {
  std::vector<uchar> bytes;
  try {
    if (!cv::imencode(".png", image, bytes)) return Status::Internal("PNG encoding failed");
  } catch (const cv::Exception& e) {
    return Status::Internal(std::string("PNG encoding failed: ") + e.what());
  }
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return Status::IoError("cannot write " + path + ": " + std::strerror(errno));
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
  out.close();
  if (!out) return Status::IoError("error while writing " + path + " (disk full?)");
  return Status::Ok();
}

// Sizes that grow with the picture: `base` is the picture size drawn at scale 1.
struct Scale {
  Scale(int width, int height, cv::Size base)
      : k(std::clamp(std::min(static_cast<double>(width) / base.width,
                              static_cast<double>(height) / base.height),
                     0.4, 4.0)),
        pad(std::max(4, cvRound(10 * k))),
        tick(std::max(3, cvRound(5 * k))) {}

  // The title's font, `size` at scale 1, shrunk until the title fits across the picture.
  Font TitleFont(const std::string& title, double size, int width) const {
    Font font{size * k, std::max(1, cvRound(2 * k))};
    while (font.scale > 0.3 && font.Measure(title).width > width - 2 * pad) font.scale *= 0.9;
    return font;
  }

  Font TickFont() const { return {0.45 * k, 1}; }

  double k;
  int pad;
  int tick;
};

// Draws `text` turned to read bottom to top, its left edge at x and centred on centre_y
// (skipped when it would not fit in the picture).
void DrawTurnedLabel(cv::Mat& image, const std::string& text, const Font& font, int x,
                     int centre_y) {
  const cv::Size size = font.Measure(text);
  cv::Mat strip(size.height, size.width, CV_8UC3, kWhite);
  font.Draw(strip, text, {0, 0}, kText);
  cv::Mat turned;
  cv::rotate(strip, turned, cv::ROTATE_90_COUNTERCLOCKWISE);
  const cv::Rect at(x, centre_y - turned.rows / 2, turned.cols, turned.rows);
  if ((at & cv::Rect(0, 0, image.cols, image.rows)) == at) turned.copyTo(image(at));
}

Status CheckPicture(const std::string& what, const std::string& path, int width, int height) {
  if (width < kMinWidth || height < kMinHeight || width > kMaxSide || height > kMaxSide) {
    return Status::InvalidArgument(
        what + " size " + std::to_string(width) + "x" + std::to_string(height) + " is outside " +
        std::to_string(kMinWidth) + "x" + std::to_string(kMinHeight) + " .. " +
        std::to_string(kMaxSide) + "x" + std::to_string(kMaxSide));
  }
  if (path.empty()) return Status::InvalidArgument(what + " path is empty");
  return Status::Ok();
}

}  // namespace

Status WritePrCurvePng(const std::string& path, const std::string& title,
                       const std::vector<PrCurve>& curves, int width, int height) {
  PLACEREC_RETURN_IF_ERROR(CheckPicture("PR plot", path, width, height));

  // Everything scales with the picture; 800x600 is scale 1.
  const Scale scale(width, height, cv::Size(800, 600));
  const double k = scale.k;
  const int pad = scale.pad;
  const int tick = scale.tick;
  const Font title_font = scale.TitleFont(title, 0.75, width);
  const Font tick_font = scale.TickFont();
  const Font label_font{0.6 * k, 1};

  const cv::Size title_size = title_font.Measure(title);
  const cv::Size tick_size = tick_font.Measure("0.0");
  const cv::Size label_size = label_font.Measure("precision");
  const int top = pad + (title.empty() ? 0 : title_size.height + pad);
  const int left = pad + label_size.height + pad + tick_size.width + tick + pad / 2;
  int bottom = tick + pad / 2 + tick_size.height + pad + label_size.height + pad;
  const int right = 2 * pad + tick_size.width / 2;
  Axes axes;
  axes.box = cv::Rect(left, top, width - left - right, height - top - bottom);

  // The curves as steps; the legend goes inside the plot area where it hides (almost) nothing,
  // otherwise below the plot when there is room for it.
  std::vector<std::vector<cv::Point2d>> steps;
  double curve_length = 0;
  for (const PrCurve& curve : curves) {
    steps.push_back(StepCurve(curve.score));
    for (size_t i = 1; i < steps.back().size(); ++i) {
      curve_length += cv::norm(axes.ToPixel(steps.back()[i].x, steps.back()[i].y) -
                               axes.ToPixel(steps.back()[i - 1].x, steps.back()[i - 1].y));
    }
  }
  const int inset = std::max(6, cvRound(12 * k));
  const Legend legend = MakeLegend(curves, axes.box.width - 2 * inset, k);
  cv::Rect legend_at;
  if (!legend.empty()) {
    double hidden = 0;
    legend_at = BestPlaceInside(legend, axes, curves, steps, inset, &hidden);
    const int below = legend.size.height + pad;
    if (hidden > 0.01 * curve_length && axes.box.height - below >= axes.box.width / 3) {
      bottom += below;
      axes.box.height -= below;
      legend_at = cv::Rect(cv::Point(axes.box.x + axes.box.width / 2 - legend.size.width / 2,
                                     height - pad - legend.size.height),
                           legend.size);
    }
  }

  cv::Mat image(height, width, CV_8UC3, kWhite);
  const cv::Rect& box = axes.box;

  // Grid, ticks and tick labels every 0.1.
  for (int i = 0; i <= 10; ++i) {
    const double v = i / 10.0;
    const int x = cvRound(axes.ToPixel(v, 0).x);
    const int y = cvRound(axes.ToPixel(0, v).y);
    cv::line(image, {x, box.y + 1}, {x, box.br().y - 2}, kGrid, 1, cv::LINE_AA);
    cv::line(image, {box.x + 1, y}, {box.br().x - 2, y}, kGrid, 1, cv::LINE_AA);
    cv::line(image, {x, box.br().y - 1}, {x, box.br().y - 1 + tick}, kAxis, 1, cv::LINE_AA);
    cv::line(image, {box.x - tick, y}, {box.x, y}, kAxis, 1, cv::LINE_AA);
    const std::string text = TickLabel(i);
    const cv::Size size = tick_font.Measure(text);
    tick_font.Draw(image, text, {x - size.width / 2, box.br().y + tick + pad / 2}, kText);
    tick_font.Draw(image, text, {box.x - tick - pad / 2 - size.width, y - tick_font.Ascent() / 2},
                   kText);
  }
  cv::rectangle(image, box, kAxis, 1, cv::LINE_AA);

  // Axis labels; "precision" is drawn on its own strip and turned to read bottom to top.
  label_font.Draw(image, "recall",
                  {box.x + box.width / 2 - label_font.Measure("recall").width / 2,
                   box.br().y + tick + pad / 2 + tick_size.height + pad},
                  kText);
  DrawTurnedLabel(image, "precision", label_font, pad, box.y + box.height / 2);

  if (!title.empty()) {
    title_font.Draw(image, title, {width / 2 - title_size.width / 2, pad}, kText);
  }

  // Curves, then their max-F1 markers on top, then the legend.
  const int line_thickness = std::max(1, cvRound(2 * k));
  for (size_t i = 0; i < curves.size(); ++i) {
    std::vector<cv::Point> fixed;
    for (const cv::Point2d& p : steps[i]) fixed.push_back(axes.ToFixed(p.x, p.y));
    if (!fixed.empty()) {
      cv::polylines(image, fixed, false, kPalette[i % kPaletteSize], line_thickness, cv::LINE_AA,
                    kShift);
    }
  }
  const int radius = std::max(3, cvRound(5 * k));
  for (size_t i = 0; i < curves.size(); ++i) {
    const RunScore& score = curves[i].score;
    if (!HasMarker(score)) continue;
    DrawMarker(image, axes.ToFixed(score.recall_at_max_f1, score.precision_at_max_f1), radius,
               kPalette[i % kPaletteSize]);
  }
  if (!legend.empty()) DrawLegend(image, legend, legend_at, k);

  return WritePng(path, image);
}

Status WriteBarChartPng(const std::string& path, const std::string& title,
                        const std::string& y_label, const std::vector<std::string>& groups,
                        const std::vector<BarSeries>& series, int width, int height) {
  PLACEREC_RETURN_IF_ERROR(CheckPicture("bar chart", path, width, height));
  if (groups.empty() || series.empty()) {
    return Status::InvalidArgument("bar chart needs at least one group and one series");
  }
  for (const BarSeries& s : series) {
    if (s.values.size() != groups.size()) {
      return Status::InvalidArgument("bar chart series '" + s.label + "' has " +
                                     std::to_string(s.values.size()) + " values for " +
                                     std::to_string(groups.size()) + " groups");
    }
    for (const double v : s.values) {
      if (!std::isnan(v) && (v < 0 || v > 100)) {
        return Status::InvalidArgument("bar chart value " + std::to_string(v) + " of '" + s.label +
                                       "' is outside 0..100");
      }
    }
  }

  // Everything scales with the picture; 800x500 is scale 1.
  const Scale scale(width, height, cv::Size(800, 500));
  const int pad = scale.pad;
  const int tick = scale.tick;
  const Font title_font = scale.TitleFont(title, 0.7, width);
  const Font tick_font = scale.TickFont();
  const Font label_font{0.55 * scale.k, 1};
  Font group_font{0.45 * scale.k, 1};
  Font value_font{0.38 * scale.k, 1};

  // The legend row: a colour box and the label per series.
  const int swatch = label_font.Ascent();
  int legend_width = 0;
  for (const BarSeries& s : series) {
    legend_width += swatch + pad / 2 + label_font.Measure(s.label).width + 2 * pad;
  }
  const cv::Size tick_size = tick_font.Measure("100");
  const int top = pad + (title.empty() ? 0 : title_font.Measure(title).height + pad) +
                  label_font.Measure("Ag").height + pad;
  const int left = pad + (y_label.empty() ? 0 : label_font.Measure(y_label).height + pad) +
                   tick_size.width + tick + pad / 2;
  const int bottom = tick + pad / 2 + group_font.Measure("Ag").height + pad;
  const cv::Rect box(left, top, width - left - 2 * pad, height - top - bottom);
  if (box.width < 10 || box.height < 10) {
    return Status::InvalidArgument("bar chart of " + std::to_string(width) + "x" +
                                   std::to_string(height) + " has no room for its plot");
  }
  auto y_of = [&box](double value) {
    return box.br().y - 1 - cvRound(value / 100.0 * (box.height - 1));
  };

  cv::Mat image(height, width, CV_8UC3, kWhite);
  for (int v = 0; v <= 100; v += 10) {
    const int y = y_of(v);
    cv::line(image, {box.x + 1, y}, {box.br().x - 2, y}, kGrid, 1, cv::LINE_AA);
    cv::line(image, {box.x - tick, y}, {box.x, y}, kAxis, 1, cv::LINE_AA);
    const std::string text = std::to_string(v);
    tick_font.Draw(
        image, text,
        {box.x - tick - pad / 2 - tick_font.Measure(text).width, y - tick_font.Ascent() / 2},
        kText);
  }

  // Bars: each group gets an equal slot, its bars fill the middle 80 % of it.
  const double slot = static_cast<double>(box.width) / groups.size();
  const double bar = 0.8 * slot / series.size();
  const int label_room = std::max(1, cvRound(slot) - 2);
  while (group_font.scale > 0.25) {
    int widest = 0;
    for (const std::string& g : groups) widest = std::max(widest, group_font.Measure(g).width);
    if (widest <= label_room) break;
    group_font.scale *= 0.9;
  }
  while (value_font.scale > 0.25 && value_font.Measure("100.0").width > bar) {
    value_font.scale *= 0.9;
  }
  const bool show_values = value_font.Measure("100.0").width <= bar + 2 * pad / 3;
  for (size_t g = 0; g < groups.size(); ++g) {
    const double x0 = box.x + g * slot + 0.1 * slot;
    for (size_t s = 0; s < series.size(); ++s) {
      const double v = series[s].values[g];
      if (std::isnan(v)) continue;
      const int xa = cvRound(x0 + s * bar);
      const int xb = std::max(xa + 1, cvRound(x0 + (s + 1) * bar) - 1);
      const int y = y_of(v);
      cv::rectangle(image, cv::Rect(cv::Point(xa, y), cv::Point(xb, box.br().y)),
                    kPalette[s % kPaletteSize], cv::FILLED);
      if (show_values) {
        char text[16];
        std::snprintf(text, sizeof(text), "%.1f", v);
        const cv::Size size = value_font.Measure(text);
        value_font.Draw(image, text, {(xa + xb) / 2 - size.width / 2, y - size.height - 2}, kText);
      }
    }
    const std::string label = Fit(groups[g], group_font, label_room);
    group_font.Draw(image, label,
                    {cvRound(box.x + (g + 0.5) * slot) - group_font.Measure(label).width / 2,
                     box.br().y + tick + pad / 2},
                    kText);
  }
  cv::rectangle(image, box, kAxis, 1, cv::LINE_AA);

  if (!y_label.empty()) DrawTurnedLabel(image, y_label, label_font, pad, box.y + box.height / 2);
  int y = pad;
  if (!title.empty()) {
    title_font.Draw(image, title, {width / 2 - title_font.Measure(title).width / 2, y}, kText);
    y += title_font.Measure(title).height + pad;
  }
  int x = std::max(pad, width / 2 - legend_width / 2);
  for (size_t s = 0; s < series.size(); ++s) {
    cv::rectangle(image, cv::Rect(x, y, swatch, swatch), kPalette[s % kPaletteSize], cv::FILLED);
    x += swatch + pad / 2;
    const std::string label = Fit(series[s].label, label_font, std::max(1, width - pad - x));
    label_font.Draw(image, label, {x, y}, kText);
    x += label_font.Measure(label).width + 2 * pad;
  }
  return WritePng(path, image);
}

Status WriteConfusionMatrixPng(const std::string& path, const std::string& title,
                               const std::vector<std::string>& names,
                               const std::vector<std::vector<int>>& counts) {
  if (path.empty()) return Status::InvalidArgument("confusion matrix path is empty");
  const int n = static_cast<int>(names.size());
  if (n == 0 || static_cast<int>(counts.size()) != n) {
    return Status::InvalidArgument("confusion matrix needs one row per class, got " +
                                   std::to_string(counts.size()) + " rows for " +
                                   std::to_string(n) + " classes");
  }
  for (const std::vector<int>& row : counts) {
    if (static_cast<int>(row.size()) < n) {
      return Status::InvalidArgument("confusion matrix row shorter than the class count");
    }
  }
  const Font label_font{0.45, 1};
  const Font cell_font{0.35, 1};
  const Font title_font{0.6, 1};
  const int cell = 34;
  const int pad = 10;
  std::vector<std::string> row_labels;
  int label_width = 0;
  for (int r = 0; r < n; ++r) {
    int total = 0;
    for (const int v : counts[r]) total += v;
    row_labels.push_back(names[r] + " (" + std::to_string(total) + ")");
    label_width = std::max(label_width, label_font.Measure(row_labels.back()).width);
  }
  int column_height = 0;
  for (const std::string& name : names) {
    column_height = std::max(column_height, label_font.Measure(name).width);
  }
  const int title_height = title_font.Measure("Ag").height + pad;
  const int left = pad + label_width + pad;
  const int top = pad + title_height + column_height + pad;
  const int width = std::min(kMaxSide, left + n * cell + pad);
  const int height = std::min(kMaxSide, top + n * cell + pad);
  cv::Mat image(height, width, CV_8UC3, kWhite);
  title_font.Draw(image, title, {pad, pad}, kText);
  for (int c = 0; c < n; ++c) {
    DrawTurnedLabel(image, names[c], label_font, left + c * cell + (cell - label_font.Ascent()) / 2,
                    top - pad - label_font.Measure(names[c]).width / 2);
  }
  for (int r = 0; r < n; ++r) {
    int total = 0;
    for (const int v : counts[r]) total += v;
    label_font.Draw(image, row_labels[r],
                    {left - pad - label_font.Measure(row_labels[r]).width,
                     top + r * cell + (cell - label_font.Ascent()) / 2},
                    kText);
    for (int c = 0; c < n; ++c) {
      const double percent = total == 0 ? 0.0 : 100.0 * counts[r][c] / total;
      const double shade = percent / 100.0;
      // White to a dark blue (BGR 140, 60, 20).
      const cv::Scalar fill(255 - shade * (255 - 140), 255 - shade * (255 - 60),
                            255 - shade * (255 - 20));
      const cv::Rect box(left + c * cell, top + r * cell, cell, cell);
      cv::rectangle(image, box, fill, cv::FILLED);
      cv::rectangle(image, box, kGrid, 1);
      if (counts[r][c] > 0) {
        char text[16];
        std::snprintf(text, sizeof(text), "%.0f", percent);
        const cv::Size size = cell_font.Measure(text);
        cell_font.Draw(image, text,
                       {box.x + (cell - size.width) / 2, box.y + (cell - cell_font.Ascent()) / 2},
                       shade > 0.55 ? kWhite : kText);
      }
    }
    cv::rectangle(image, cv::Rect(left + r * cell, top + r * cell, cell, cell), kAxis, 2);
  }
  return WritePng(path, image);
}

}  // namespace placerec
