// Pictures people would rather look at than read: precision-recall curves.
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

}  // namespace placerec
