#include "common/recognition/colour_filter.h"

#include <cmath>

namespace placerec {

bool ColourFilterOptions::Check(std::string* error) const {
  if (tolerance < 0) {
    *error = "colour tolerance must be non-negative";
    return false;
  }
  return true;
}

bool ColoursCompatible(const ColourSignature& query, const ColourSignature& candidate,
                       const ColourFilterOptions& options) {
  if (!query.known() || !candidate.known()) return true;
  if (options.multi_peak_needs_multi_peak && query.multi_peak() && !candidate.multi_peak()) {
    return false;
  }
  if (!options.any_peak) {
    return std::abs(query.peaks[0] - candidate.peaks[0]) < options.tolerance;
  }
  for (float q : query.peaks) {
    for (float c : candidate.peaks) {
      if (std::abs(q - c) < options.tolerance) return true;
    }
  }
  return false;
}

}  // namespace placerec
