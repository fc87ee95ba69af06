// Exact SIFT descriptor matching with Lowe's ratio test, used to verify that two objects are the
// same (seed §5.3: at least six matched descriptors; §5.6: more than six).
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

namespace placerec {

// Squared Euclidean distance of two 128-byte SIFT descriptors, with the widest vector
// instructions the processor has (chosen once at start).
int SquaredDistance(const uint8_t* a, const uint8_t* b);

// SquaredDistance from `query` to every row of `rows` (CV_8U, 128 columns, any row step) into
// out[0..rows.rows): the same values, faster than one call per row.
void SquaredDistances(const uint8_t* query, const cv::Mat& rows, int* out);

// Every implementation of SquaredDistance this processor runs, by name, from the plain loop to
// the widest (the one SquaredDistance uses): for tests, which otherwise only see that one.
using SquaredDistanceFunction = int (*)(const uint8_t*, const uint8_t*);
std::vector<std::pair<std::string, SquaredDistanceFunction>> SquaredDistanceImplementations();

// A match of row `query` of one object's descriptors with row `train` of another's.
struct DescriptorMatch {
  int query = -1;
  int train = -1;
  int distance = 0;  // squared Euclidean
};

// For each query row, the nearest train row, kept when its distance is below ratio^2 times the
// second nearest (Lowe's ratio test on Euclidean distances) and, when several query rows pick
// the same train row, only the closest. Both matrices are CV_8U with 128 columns. A train
// matrix with one row passes every nearest match (there is no second neighbour).
std::vector<DescriptorMatch> MatchRatioTest(const cv::Mat& query, const cv::Mat& train,
                                            double ratio);

// Difference of two angles in degrees, in [-180, 180).
double AngleDifference(double a, double b);

// Which of the matches, given by their keypoints' orientation changes (degrees), turn within
// `tolerance` degrees of the most common change (the peak of a 10-degree histogram, smoothed
// with its neighbours): two views of a scene from upright cameras rotate their features alike,
// random matches do not. A tolerance <= 0 keeps every match.
std::vector<bool> ConsistentOrientation(const std::vector<double>& changes, double tolerance);

}  // namespace placerec
