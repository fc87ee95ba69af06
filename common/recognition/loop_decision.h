// Loop decision (pipeline step 9, seed §5.7 step 6): the places whose landmarks matched this
// frame's objects are the candidates; the best of them are checked for a consistent epipolar
// geometry (an addition to the seed: a fundamental matrix fitted with RANSAC to the place-level
// descriptor matches) and ranked by the number of geometric inliers.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "common/recognition/landmark_index.h"
#include "common/recognition/types.h"

namespace placerec {

// Which of the querying robot's own places may answer is decided before ranking, by its recent
// past (recent_past.h); other robots' places always may (the map is shared).
struct LoopDecisionOptions {
  // Fit a fundamental matrix with RANSAC to each candidate place's matched keypoints and score
  // the place by its inliers. Off: the score is the number of matched descriptors.
  bool geometric_verification = true;
  // Before the geometric fit, keep only matches whose keypoint orientations differ by within
  // this many degrees of the place's most common difference: two views of a scene from upright
  // cameras rotate their features alike, random matches do not. 0 keeps every match.
  double orientation_tolerance = 20.0;
  // The fundamental matrix is fitted with OpenCV's USAC (LO-RANSAC with SPRT, deterministic
  // seed), chosen over plain RANSAC for speed at the same selectivity
  // (docs/experiments/2026-11-22-flann-and-ransac.md).
  // RANSAC inlier distance to the epipolar line, pixels of the processed frame.
  double ransac_threshold = 3.0;
  double ransac_confidence = 0.999;
  int ransac_iterations = 500;
  // Places with fewer orientation-consistent matches than this are not checked (score 0).
  int min_verification_points = 10;
  // A place scores the geometric inliers of each of its landmarks up to this many (0: no cap),
  // so that one object seen in two places (a newspaper stand, a poster) does not make a loop:
  // the seed asks for about half of a frame's landmarks to match (§5.7 step 6).
  int max_inliers_per_landmark = 10;
  // ... and at most this many inliers per cell of a grid over the query frame (cells of
  // inlier_cell_size pixels; 0: no cap). Inliers crowded on one distant structure say little
  // about where along the route the robot is; inliers spread over the frame do.
  int max_inliers_per_cell = 0;
  int inlier_cell_size = 48;
  // Places verified geometrically, best by matched descriptors first; and at most as many
  // again among the best place's localization neighbours, nearest in time first.
  int max_verified_places = 20;
  // Localization among the best place's neighbours (same robot, taken within this many seconds
  // of it, so that the neighbourhood is the same at any frame rate; score
  // at least `localization_score_fraction` of the best and above `noise_inliers`): the answer is
  // the neighbour whose matched features have the same scale as in the query (median log scale
  // ratio closest to 0), i.e. the frame taken at the same distance from the scene. Neighbouring
  // frames share most matches, and distant structure matches equally well from several of
  // them, so the best score alone often answers a few frames too early or too late.
  // 0 answers with the best place.
  double localization_window_seconds = 3.0;
  double localization_score_fraction = 0.5;
  // With at least three such neighbours whose log scale ratio changes by at least this much per
  // second, the answer is the neighbour nearest the time where the fitted ratio crosses 0.
  double min_scale_slope = 0.01;
  // Inliers a wrong place typically reaches by chance; only the excess weighs in localization.
  double noise_inliers = 8.0;
  // Places returned in the answer, best first.
  int max_matches = 5;
  // A frame is a loop closure when its best place scores at least this.
  double min_score = 20.0;

  bool Check(std::string* error) const;
};

struct PlaceMatch {
  Place place;
  double score = 0;  // inliers, or matched descriptors without verification
  // This frame's own score; `score` differs from it once sequence support (sequence_support.h)
  // has averaged in the robot's earlier frames, `supporting_frames` of which matched the route.
  double frame_score = 0;
  int supporting_frames = 0;
  int matched_landmarks = 0;  // the place's landmarks matched by this frame's objects
  // Place-level descriptor matches before the geometric check: every match of the place for the
  // places the index matched exactly (LandmarkIndexOptions::exact_places), those the neighbour
  // lists hold for the others.
  int matched_descriptors = 0;
  int inliers = -1;  // geometric inliers; -1 when not verified
  // Median over the inliers of log(query keypoint size / stored keypoint size), each size taken
  // relative to its frame's width: 0 when the query was taken as far from the scene.
  double log_scale = 0;
  std::vector<std::pair<int, LandmarkId>> object_pairs;  // (query object, landmark)
  std::vector<cv::Rect> landmark_boxes;  // per object pair: the landmark's box in its frame
  // Matched keypoint positions (query frame, place's frame) that are geometric inliers, or all
  // matches without verification.
  std::vector<std::pair<cv::Point2f, cv::Point2f>> point_pairs;
  std::vector<LandmarkId> point_landmarks;  // the stored landmark of each point pair
  // Object classes (seed Ch. 4) of the place's landmarks that matched (an object pair or an
  // inlier point), with how many landmarks of each: most first, then by name. Landmarks without
  // a class are not counted.
  std::vector<std::pair<std::string, int>> landmark_classes;
};

// PlaceMatch::landmark_classes: the classes of the match's object pairs and inlier points.
std::vector<std::pair<std::string, int>> MatchedClasses(const PlaceMatch& match,
                                                        const LandmarkIndex& index);

// Ranks the candidate places of `found`, best first, at most options.max_matches of them.
// `query_keypoints[o][r]` is the keypoint of row r of query object o; `place_of(id)` looks a place
// up (nullptr when unknown, which cannot happen for places in the index).
// `query_width` is the processed query frame's width in pixels (0: unknown).
std::vector<PlaceMatch> RankPlaces(const IndexResult& found,
                                   const std::vector<std::vector<cv::KeyPoint>>& query_keypoints,
                                   int query_width, const LandmarkIndex& index,
                                   const std::function<const Place*(PlaceId)>& place_of,
                                   const LoopDecisionOptions& options);

}  // namespace placerec
