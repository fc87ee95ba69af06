// Pictures of placerec-eval segment: the overlay of one image's segmentation and the chart of
// a run's object-level accuracy.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "common/segmentation/segmentation.h"
#include "common/util/status.h"

namespace placerec {

// Left: the image with background classes tinted and structured segments outlined in their own
// colours. Right: the ground-truth objects in random colours (or the segments when `objects` is
// empty). Below both, a legend strip. `segments` CV_32S ids into `classes`, `objects` CV_32S
// (0 = none) or empty, both the size of `bgr`.
cv::Mat DrawSegmentOverlay(const cv::Mat& bgr, const cv::Mat& segments,
                           const std::vector<SegmentClass>& classes, const cv::Mat& objects);

// Writes `path`: a bar chart of the mean object IoU over every scored object and per class (most
// objects first) of `report` (segmentation.json with "perceptual_organization"), the
// segmentation under test (`method`, the legend text) beside the best superpixel setting when
// the report has one.
Status WriteSegmentSummaryChart(const nlohmann::json& report, const std::string& method,
                                const std::string& path);

}  // namespace placerec
