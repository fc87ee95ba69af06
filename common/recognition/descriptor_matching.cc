#include "common/recognition/descriptor_matching.h"

#include <algorithm>
#include <climits>
#include <cmath>

#include "common/features/features.h"
#include "common/util/logging.h"

namespace placerec {

int SquaredDistance(const uint8_t* a, const uint8_t* b) {
  int sum = 0;
  for (int i = 0; i < kDescriptorSize; ++i) {
    const int d = static_cast<int>(a[i]) - static_cast<int>(b[i]);
    sum += d * d;
  }
  return sum;
}

std::vector<DescriptorMatch> MatchRatioTest(const cv::Mat& query, const cv::Mat& train,
                                            double ratio) {
  CHECK(query.empty() || (query.type() == CV_8U && query.cols == kDescriptorSize));
  CHECK(train.empty() || (train.type() == CV_8U && train.cols == kDescriptorSize));
  std::vector<DescriptorMatch> matches;
  if (query.empty() || train.empty()) return matches;
  const double ratio_squared = ratio * ratio;
  // best[t]: index into `matches` of the match that currently owns train row t.
  std::vector<int> owner(train.rows, -1);
  for (int q = 0; q < query.rows; ++q) {
    const uint8_t* qd = query.ptr<uint8_t>(q);
    int best = INT_MAX;
    int second = INT_MAX;
    int best_row = -1;
    for (int t = 0; t < train.rows; ++t) {
      const int d = SquaredDistance(qd, train.ptr<uint8_t>(t));
      if (d < best) {
        second = best;
        best = d;
        best_row = t;
      } else if (d < second) {
        second = d;
      }
    }
    if (second != INT_MAX && best >= ratio_squared * second) continue;
    const int current = owner[best_row];
    if (current >= 0) {
      if (matches[current].distance <= best) continue;
      matches[current] = {q, best_row, best};
      continue;
    }
    owner[best_row] = static_cast<int>(matches.size());
    matches.push_back({q, best_row, best});
  }
  return matches;
}

double AngleDifference(double a, double b) {
  double d = std::fmod(a - b, 360.0);
  if (d < -180) d += 360;
  if (d >= 180) d -= 360;
  return d;
}

std::vector<bool> ConsistentOrientation(const std::vector<double>& changes, double tolerance) {
  if (tolerance <= 0 || changes.empty()) return std::vector<bool>(changes.size(), true);
  constexpr int kBins = 36;
  std::vector<double> histogram(kBins, 0.0);
  for (const double change : changes) {
    const double d = AngleDifference(change, 0.0) + 180.0;  // [0, 360)
    histogram[static_cast<int>(d / 10.0) % kBins] += 1.0;
  }
  int peak = 0;
  double best = -1;
  for (int b = 0; b < kBins; ++b) {
    const double v =
        histogram[(b + kBins - 1) % kBins] + 2 * histogram[b] + histogram[(b + 1) % kBins];
    if (v > best) {
      best = v;
      peak = b;
    }
  }
  const double mode = peak * 10.0 + 5.0 - 180.0;
  std::vector<bool> kept(changes.size());
  for (size_t i = 0; i < changes.size(); ++i) {
    kept[i] = std::abs(AngleDifference(changes[i], mode)) <= tolerance;
  }
  return kept;
}

}  // namespace placerec
