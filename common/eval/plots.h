// Pictures people would rather look at than read: precision-recall curves and grouped bar
// charts of percentages.
#pragma once

#include <string>
#include <vector>

#include "common/eval/scoring.h"
#include "common/util/status.h"

namespace placerec {

struct PrCurve {
  std::string label;  // legend text, e.g. "placerec (R@100P 0.42, max F1 0.71)"
  RunScore score;
};

// Draws one or more PR curves (recall on x, precision on y, both 0..1, grid every 0.1) into a
// PNG of width x height pixels (200x150 to 8000x8000): each curve as the step function whose area
// is its average_precision, in its own colour, with a marker at its max-F1 point, and a legend
// inside the plot where it hides (almost) nothing, else below it. A curve with no points appears
// in the legend only. InvalidArgument for a bad size or an empty path, IoError when the file
// cannot be written.
Status WritePrCurvePng(const std::string& path, const std::string& title,
                       const std::vector<PrCurve>& curves, int width = 800, int height = 600);

// One series of a bar chart: a value per group, in percent (0..100; NaN: no bar).
struct BarSeries {
  std::string label;  // legend text
  std::vector<double> values;
};

// Draws a grouped bar chart of percentages into a PNG of width x height pixels (200x150 to
// 8000x8000): for each group (label below the axis, e.g. "building (394)") one bar per series
// in the series' own colour, its value printed above it, a y axis from 0 to 100 with a grid
// every 10, and the legend in a row under the title. InvalidArgument for a bad size, an empty
// path, no groups or series, a series whose value count differs from the group count, or a
// value outside 0..100; IoError when the file cannot be written.
Status WriteBarChartPng(const std::string& path, const std::string& title,
                        const std::string& y_label, const std::vector<std::string>& groups,
                        const std::vector<BarSeries>& series, int width = 800, int height = 500);

// Draws a confusion matrix into a PNG: one row per true class (`names`, with its segment count),
// one column per decided class, each cell the percent of the row's segments (row-normalised)
// printed and shaded from white (0) to dark blue (100); the diagonal is outlined. `counts` is
// names.size() rows of at least names.size() values (extra columns, e.g. "none", are left out
// of the picture but count in the row's total). The size follows the class count. InvalidArgument
// for no classes, a row count or row length that disagrees or an empty path; IoError when the
// file cannot be written.
Status WriteConfusionMatrixPng(const std::string& path, const std::string& title,
                               const std::vector<std::string>& names,
                               const std::vector<std::vector<int>>& counts);

}  // namespace placerec
