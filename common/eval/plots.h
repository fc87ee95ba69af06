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

// Draws one or more PR curves (recall on x, precision on y, both 0..1) with axes, grid, title
// and legend into a PNG of width x height pixels.
Status WritePrCurvePng(const std::string& path, const std::string& title,
                       const std::vector<PrCurve>& curves, int width = 800, int height = 600);

}  // namespace placerec
