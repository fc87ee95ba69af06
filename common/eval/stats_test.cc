#include "common/eval/stats.h"

#include <gtest/gtest.h>

namespace placerec {
namespace {

// Expected values are numpy.percentile's (default method "linear").
TEST(StatsTest, PercentileMatchesNumpy) {
  EXPECT_EQ(Percentile({}, 50), 0.0);
  EXPECT_EQ(Percentile({7}, 0), 7.0);
  EXPECT_EQ(Percentile({7}, 99), 7.0);
  // np.percentile([[10, 7, 4], [3, 2, 1]], 50) == 3.5 (numpy's own docs example)
  EXPECT_EQ(Percentile({10, 7, 4, 3, 2, 1}, 50), 3.5);
  EXPECT_EQ(Percentile({10, 7, 4, 3, 2, 1}, 0), 1.0);
  EXPECT_EQ(Percentile({10, 7, 4, 3, 2, 1}, 100), 10.0);
  // Index 0.9 * 5 = 4.5 between 7 and 10.
  EXPECT_DOUBLE_EQ(Percentile({10, 7, 4, 3, 2, 1}, 90), 8.5);
  // np.percentile([1, 2, 3, 4], 25) == 1.75; ([1, 2, 3, 4], 75) == 3.25
  EXPECT_DOUBLE_EQ(Percentile({4, 3, 2, 1}, 25), 1.75);
  EXPECT_DOUBLE_EQ(Percentile({1, 2, 3, 4}, 75), 3.25);
  // np.percentile([15, 20, 35, 40, 50], 40) == 29.0 (index 1.6 between 20 and 35)
  EXPECT_DOUBLE_EQ(Percentile({15, 20, 35, 40, 50}, 40), 29.0);
  EXPECT_EQ(Median({5, 1, 3}), 3.0);
  EXPECT_EQ(Median({5, 1, 3, 2}), 2.5);
}

}  // namespace
}  // namespace placerec
