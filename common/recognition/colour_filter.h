// The colour filter of seed §5.6: two objects have similar colour when their dominant colour
// invariants H differ by less than 0.2; a query object with several dominant colours only
// matches objects with several.
#pragma once

#include <string>

#include "common/objects/objects.h"

namespace placerec {

struct ColourFilterOptions {
  // Maximum difference of dominant H values (seed §5.6: 0.2).
  double tolerance = 0.2;
  // A multi-peak query only matches multi-peak objects (seed §5.6).
  bool multi_peak_needs_multi_peak = true;
  // Compare every dominant peak pair instead of only the highest peaks: the order of two
  // near-equal peaks flips with viewpoint, so any pair within tolerance counts.
  bool any_peak = true;

  bool Check(std::string* error) const;
};

// True when `candidate` may be the same object as `query` by colour. An unknown signature (too
// few usable pixels, or a frame without colour) is compatible with everything.
bool ColoursCompatible(const ColourSignature& query, const ColourSignature& candidate,
                       const ColourFilterOptions& options);

}  // namespace placerec
