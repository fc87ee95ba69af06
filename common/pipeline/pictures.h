// Pictures for people: a query frame beside the frame it was matched with, matched objects
// outlined and inlier matches drawn; and a segmentation overlay.
#pragma once

#include <string>

#include <opencv2/core.hpp>

#include "common/pipeline/frame_analyzer.h"
#include "common/recognition/loop_decision.h"

namespace placerec {

// `query` and `reference` are the original frames; `observation` is the query's analysis
// (object masks and boxes in processed pixels); landmark boxes and point pairs in `match` are in
// the processed pixels of their own frames, and `reference_scale` is the reference frame's
// processed / original factor. `caption` is written above the pair.
cv::Mat DrawMatchPicture(const cv::Mat& query, const FrameObservation& observation,
                         const cv::Mat& reference, double reference_scale, const PlaceMatch& match,
                         const std::string& caption);

// The frame at the segmentation's working size with segment boundaries in white and segments
// tinted: background classes in fixed colours (sky blue, tree and grass green, road grey, water
// cyan), structured segments in random hues.
cv::Mat DrawSegmentationOverlay(const cv::Mat& frame, const SceneSegmentation& segmentation);

// The processed frame with its segmentation overlay scaled up, keypoints as dots (red inside an
// object, yellow elsewhere) and objects outlined with their SIFT count and dominant H.
cv::Mat DrawAnalysis(const cv::Mat& frame, const FrameObservation& observation);

}  // namespace placerec
