#include "common/eval/stats.h"

#include <algorithm>
#include <cmath>

namespace placerec {

double Percentile(std::vector<double> values, double q) {
  values.erase(std::remove_if(values.begin(), values.end(), [](double v) { return std::isnan(v); }),
               values.end());
  if (values.empty()) return 0.0;
  if (!(q >= 0.0)) q = 0.0;  // also NaN
  if (q > 100.0) q = 100.0;
  std::sort(values.begin(), values.end());
  // numpy.percentile(method="linear"): virtual index (n - 1) * q / 100 between order statistics,
  // interpolated from the nearer end for accuracy the way numpy's _lerp does.
  const double index = (q / 100.0) * static_cast<double>(values.size() - 1);
  const size_t below = static_cast<size_t>(std::floor(index));
  const size_t above = std::min(below + 1, values.size() - 1);
  const double t = index - static_cast<double>(below);
  if (t == 0.0) return values[below];
  const double a = values[below];
  const double b = values[above];
  const double difference = b - a;
  return t >= 0.5 ? b - difference * (1.0 - t) : a + difference * t;
}

}  // namespace placerec
