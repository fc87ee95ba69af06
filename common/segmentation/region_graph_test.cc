#include "common/segmentation/region_graph.h"

#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

namespace placerec {
namespace {

using Neighbours = std::vector<std::pair<int, int>>;

// 0 0 1 1
// 0 0 1 1
// 2 2 2 1
cv::Mat SmallLabels() {
  return (cv::Mat_<int>(3, 4) << 0, 0, 1, 1,  //
          0, 0, 1, 1,                         //
          2, 2, 2, 1);
}

TEST(RegionGraphTest, HandMadeLabels) {
  const cv::Mat labels = SmallLabels();
  cv::Mat lab(labels.size(), CV_32FC3);
  for (int y = 0; y < labels.rows; ++y) {
    for (int x = 0; x < labels.cols; ++x) {
      const float l = static_cast<float>(labels.at<int>(y, x));
      lab.at<cv::Vec3f>(y, x) = cv::Vec3f(10.0f * l + x, -l, 2.0f * y);
    }
  }
  const RegionGraph graph = BuildRegionGraph(labels, 3, lab);
  ASSERT_EQ(graph.size(), 3);

  EXPECT_EQ(graph.regions[0].area, 4);
  EXPECT_EQ(graph.regions[1].area, 5);
  EXPECT_EQ(graph.regions[2].area, 3);
  // Region 0: 4 border edges, 2 with region 1, 2 with region 2.
  EXPECT_EQ(graph.regions[0].perimeter, 8);
  // Region 1: 6 border edges, 2 with region 0, 2 with region 2.
  EXPECT_EQ(graph.regions[1].perimeter, 10);
  // Region 2: 4 border edges, 2 with region 0, 2 with region 1.
  EXPECT_EQ(graph.regions[2].perimeter, 8);

  EXPECT_EQ(graph.neighbours[0], (Neighbours{{1, 2}, {2, 2}}));
  EXPECT_EQ(graph.neighbours[1], (Neighbours{{0, 2}, {2, 2}}));
  EXPECT_EQ(graph.neighbours[2], (Neighbours{{0, 2}, {1, 2}}));
  EXPECT_EQ(graph.SharedBoundary(0, 1), 2);
  EXPECT_EQ(graph.SharedBoundary(1, 0), 2);
  EXPECT_EQ(graph.SharedBoundary(1, 2), 2);
  EXPECT_EQ(graph.SharedBoundary(0, 0), 0);

  EXPECT_EQ(graph.regions[0].box, cv::Rect(0, 0, 2, 2));
  EXPECT_EQ(graph.regions[1].box, cv::Rect(2, 0, 2, 3));
  EXPECT_EQ(graph.regions[2].box, cv::Rect(0, 2, 3, 1));
  EXPECT_DOUBLE_EQ(graph.regions[0].centroid.x, 0.5);
  EXPECT_DOUBLE_EQ(graph.regions[0].centroid.y, 0.5);
  EXPECT_DOUBLE_EQ(graph.regions[1].centroid.x, 2.6);  // (2 + 3 + 2 + 3 + 3) / 5
  EXPECT_DOUBLE_EQ(graph.regions[1].centroid.y, 0.8);  // (0 + 0 + 1 + 1 + 2) / 5
  EXPECT_DOUBLE_EQ(graph.regions[2].centroid.x, 1.0);
  EXPECT_DOUBLE_EQ(graph.regions[2].centroid.y, 2.0);

  // Mean Lab: L = 10 * label + mean x, a = -label, b = 2 * mean y.
  EXPECT_FLOAT_EQ(graph.regions[1].mean_lab[0], 12.6f);
  EXPECT_FLOAT_EQ(graph.regions[1].mean_lab[1], -1.0f);
  EXPECT_FLOAT_EQ(graph.regions[1].mean_lab[2], 1.6f);
  EXPECT_FLOAT_EQ(graph.regions[2].mean_lab[0], 21.0f);
  EXPECT_FLOAT_EQ(graph.regions[2].mean_lab[2], 4.0f);
}

TEST(RegionGraphTest, BoundaryLemmaForAMergedPair) {
  // L(d(A u B)) = L(dA) + L(dB) - 2 L(dAB) (seed Lemma 1), checked on the merged labels.
  const cv::Mat labels = SmallLabels();
  const RegionGraph graph = BuildRegionGraph(labels, 3, cv::Mat());
  cv::Mat merged = labels.clone();
  merged.setTo(0, labels == 1);
  merged.setTo(1, labels == 2);
  const RegionGraph merged_graph = BuildRegionGraph(merged, 2, cv::Mat());
  EXPECT_EQ(merged_graph.regions[0].area, 9);
  EXPECT_EQ(merged_graph.regions[0].perimeter, 14);
  EXPECT_EQ(
      merged_graph.regions[0].perimeter,
      graph.regions[0].perimeter + graph.regions[1].perimeter - 2 * graph.SharedBoundary(0, 1));
  EXPECT_EQ(merged_graph.SharedBoundary(0, 1), 4);
}

TEST(RegionGraphTest, EnclosedRegionAndAbsentIds) {
  // A 2x2 hole in a 4x4 frame; id 2 is not used.
  cv::Mat labels(4, 4, CV_32S, cv::Scalar(0));
  labels(cv::Rect(1, 1, 2, 2)).setTo(3);
  const RegionGraph graph = BuildRegionGraph(labels, 4, cv::Mat());
  EXPECT_EQ(graph.regions[0].area, 12);
  EXPECT_EQ(graph.regions[0].perimeter, 16 + 8);
  EXPECT_EQ(graph.regions[3].perimeter, 8);
  EXPECT_EQ(graph.regions[3].box, cv::Rect(1, 1, 2, 2));
  EXPECT_DOUBLE_EQ(graph.regions[0].centroid.x, 1.5);
  EXPECT_EQ(graph.SharedBoundary(0, 3), 8);
  EXPECT_EQ(graph.regions[2].area, 0);
  EXPECT_EQ(graph.regions[2].perimeter, 0);
  EXPECT_TRUE(graph.neighbours[2].empty());
  EXPECT_TRUE(graph.neighbours[1].empty());
  EXPECT_EQ(graph.SharedBoundary(1, 2), 0);
  // Without a Lab image the means are zero.
  EXPECT_EQ(graph.regions[0].mean_lab, cv::Vec3f(0, 0, 0));
}

TEST(RegionGraphTest, RandomLabelsAreConsistent) {
  // Blocky random labels: every perimeter is its border edges plus its shared boundaries, the
  // lists are symmetric and sorted, and the lemma holds for every adjacent pair.
  cv::RNG rng(7);
  cv::Mat coarse(6, 8, CV_32S);
  rng.fill(coarse, cv::RNG::UNIFORM, 0, 9);
  cv::Mat labels;
  cv::resize(coarse, labels, cv::Size(40, 30), 0, 0, cv::INTER_NEAREST);
  // Sprinkle single pixels so that thin boundaries occur too.
  for (int i = 0; i < 60; ++i) {
    labels.at<int>(rng.uniform(0, 30), rng.uniform(0, 40)) = rng.uniform(0, 9);
  }
  const int n = 9;
  const RegionGraph graph = BuildRegionGraph(labels, n, cv::Mat());
  int total_area = 0;
  for (int a = 0; a < n; ++a) {
    total_area += graph.regions[a].area;
    int border = 0;
    for (int x = 0; x < labels.cols; ++x) {
      border += (labels.at<int>(0, x) == a) + (labels.at<int>(labels.rows - 1, x) == a);
    }
    for (int y = 0; y < labels.rows; ++y) {
      border += (labels.at<int>(y, 0) == a) + (labels.at<int>(y, labels.cols - 1) == a);
    }
    int shared = 0;
    for (size_t i = 0; i < graph.neighbours[a].size(); ++i) {
      const auto [b, length] = graph.neighbours[a][i];
      if (i > 0) {
        EXPECT_LT(graph.neighbours[a][i - 1].first, b);
      }
      EXPECT_NE(a, b);
      EXPECT_EQ(graph.SharedBoundary(b, a), length);
      shared += length;
      if (b < a) continue;
      cv::Mat merged = labels.clone();
      merged.setTo(a, labels == b);
      const RegionGraph merged_graph = BuildRegionGraph(merged, n, cv::Mat());
      EXPECT_EQ(merged_graph.regions[a].perimeter,
                graph.regions[a].perimeter + graph.regions[b].perimeter - 2 * length)
          << a << " " << b;
    }
    EXPECT_EQ(graph.regions[a].perimeter, border + shared) << a;
  }
  EXPECT_EQ(total_area, 40 * 30);
}

}  // namespace
}  // namespace placerec
