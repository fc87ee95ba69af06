#include "common/recognition/descriptor_matching.h"

#include <algorithm>
#include <climits>

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

}  // namespace placerec
