// Summary statistics for timings and counts.
#pragma once

#include <utility>
#include <vector>

namespace placerec {

// Percentile q in [0, 100] with linear interpolation between order statistics, as
// numpy.percentile's default; 0 when empty. NaN values are ignored; q outside [0, 100] is
// clamped.
double Percentile(std::vector<double> values, double q);
inline double Median(std::vector<double> values) { return Percentile(std::move(values), 50.0); }

}  // namespace placerec
