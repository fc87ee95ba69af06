#include "common/change/change_detector.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "common/change/masked_correlation.h"
#include "common/image/image.h"

namespace placerec {

bool ChangeOptions::Check(std::string* error) const {
  auto fail = [error](const char* what) {
    *error = what;
    return false;
  };
  if (!(sensitivity > 0.0 && sensitivity <= 1.0))
    return fail("change sensitivity must be in (0, 1]");
  if (!(min_difference > 0.0 && max_difference >= min_difference)) {
    return fail("change differences must satisfy 0 < min <= max");
  }
  if (min_inliers_without_loop < 0) return fail("change min inliers without a loop must be >= 0");
  if (min_points < 4) return fail("change min_points must be at least 4 (a homography)");
  if (!(homography_threshold > 0.0 && homography_threshold < 0.5)) {
    return fail("change homography threshold must be in (0, 0.5) of the frame width");
  }
  if (!(min_inlier_share >= 0.0 && min_inlier_share <= 1.0)) {
    return fail("change min inlier share must be in [0, 1]");
  }
  if (!(edge_margin >= 0.0 && edge_margin < 0.5))
    return fail("change edge margin must be in [0, 0.5)");
  if (!(alignment_tolerance >= 0.0 && alignment_tolerance < 0.2)) {
    return fail("change alignment tolerance must be in [0, 0.2)");
  }
  if (!(min_area > 0.0 && max_area > min_area && max_area <= 1.0)) {
    return fail("change areas must satisfy 0 < min < max <= 1");
  }
  if (!(max_match_density >= 0.0)) return fail("change max match density must be >= 0");
  if (!(texture_weight >= 0.0)) return fail("change texture weight must be >= 0");
  if (!(support_radius >= 0.0 && support_radius <= 1.0)) {
    return fail("change support radius must be in [0, 1] of the frame width");
  }
  if (!(noise_spread >= 0.0)) return fail("change noise spread must be >= 0");
  if (!(grow_fraction > 0.0 && grow_fraction <= 1.0)) {
    return fail("change grow fraction must be in (0, 1]");
  }
  if (!(strong_spread >= 0.0 && strong_spread <= 100.0)) {
    return fail("change strong spread must be in [0, 100] robust deviations");
  }
  if (!(weak_mean >= 0.0 && weak_mean <= 1.0)) return fail("change weak mean must be in [0, 1]");
  if (!(weak_spread >= 0.0)) return fail("change weak spread must be >= 0");
  if (!(weak_min_area > 0.0 && weak_min_area <= 1.0)) {
    return fail("change weak min area must be in (0, 1]");
  }
  if (!(edge_band >= 0.0 && edge_band < 0.5)) return fail("change edge band must be in [0, 0.5)");
  if (!(max_edge_share > 0.0 && max_edge_share <= 1.0)) {
    return fail("change max edge share must be in (0, 1]");
  }
  if (!(texture_window > 0.0 && texture_window < 0.5)) {
    return fail("change texture window must be in (0, 0.5) of the frame width");
  }
  if (!(max_elsewhere_similarity > 0.0 && max_elsewhere_similarity <= 1.0)) {
    return fail("change elsewhere similarity must be in (0, 1]");
  }
  if (!(segment_difference >= 0.0)) return fail("change segment difference must be >= 0");
  if (!(segment_min_shared > 0.0 && segment_min_shared <= 1.0)) {
    return fail("change segment min shared must be in (0, 1]");
  }
  if (!(segment_min_side >= 0.0 && segment_min_side < 1.0)) {
    return fail("change segment min side must be in [0, 1) of the frame width");
  }
  if (max_changes < 1) return fail("change max_changes must be at least 1");
  if (max_references < 1) return fail("change max_references must be at least 1");
  if (!(min_class_confidence >= 0.0 && min_class_confidence <= 1.0)) {
    return fail("change min class confidence must be in [0, 1]");
  }
  if (!(reference_window_seconds >= 0.0 && reference_window_seconds <= 86400.0)) {
    return fail("change reference window must be in [0, 86400] seconds (a day)");
  }
  if (picture_width < 32 || picture_width > 4096) {
    return fail("change picture width must be in [32, 4096] pixels");
  }
  return true;
}

double ChangeOptions::Threshold() const {
  return max_difference - sensitivity * (max_difference - min_difference);
}

bool CompareAtRevisit(bool loop_closure, int verified_pairs, const ChangeOptions& options) {
  if (!options.enabled) return false;
  if (loop_closure) return true;
  return options.min_inliers_without_loop > 0 && verified_pairs >= options.min_inliers_without_loop;
}

const char* ChangeKindName(SceneChange::Kind kind) {
  return kind == SceneChange::Kind::kAppeared ? "appeared" : "disappeared";
}

namespace {

// CIE Lab (L in [0, 100], a and b around 0), float, lightly smoothed against JPEG noise.
cv::Mat SmoothedLab(const cv::Mat& bgr) {
  cv::Mat lab = ToLab(bgr);
  cv::GaussianBlur(lab, lab, cv::Size(3, 3), 0.8);
  return lab;
}

// The stored image's channels moved to the frame's mean and spread inside `mask` (a changed
// exposure or white balance is not a change); gains are kept within [1/3, 3].
cv::Mat MatchExposure(const cv::Mat& stored, const cv::Mat& frame, const cv::Mat& mask) {
  cv::Scalar stored_mean, stored_std, frame_mean, frame_std;
  cv::meanStdDev(stored, stored_mean, stored_std, mask);
  cv::meanStdDev(frame, frame_mean, frame_std, mask);
  std::vector<cv::Mat> channels;
  cv::split(stored, channels);
  for (int c = 0; c < 3; ++c) {
    const double gain =
        std::clamp(stored_std[c] > 1e-3 ? frame_std[c] / stored_std[c] : 1.0, 1.0 / 3.0, 3.0);
    channels[c].convertTo(channels[c], CV_32F, gain, frame_mean[c] - gain * stored_mean[c]);
  }
  cv::Mat matched;
  cv::merge(channels, matched);
  return matched;
}

// Per pixel, how far the frame lies outside the range of the stored values within `radius`
// pixels (Lab distance): misalignment of a few pixels and edges that moved do not count.
cv::Mat OutsideRange(const cv::Mat& frame, const cv::Mat& stored, int radius) {
  cv::Mat high, low;
  if (radius > 0) {
    const cv::Mat kernel =
        cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * radius + 1, 2 * radius + 1));
    cv::dilate(stored, high, kernel);
    cv::erode(stored, low, kernel);
  } else {
    high = stored;
    low = stored;
  }
  cv::Mat above = frame - high;
  cv::Mat below = low - frame;
  cv::Mat outside = cv::max(cv::max(above, below), 0.0);
  std::vector<cv::Mat> channels;
  cv::split(outside, channels);
  cv::Mat distance =
      channels[0].mul(channels[0]) + channels[1].mul(channels[1]) + channels[2].mul(channels[2]);
  cv::sqrt(distance, distance);
  return distance;
}

// Local contrast: the standard deviation of L in a window of `size` pixels (texture, seed §5.5
// describes objects by their texture too): a plain patch pasted over a textured one, or the
// reverse, changes it even where the colours stay within the stored range.
cv::Mat LocalContrast(const cv::Mat& lab, int size) {
  cv::Mat l;
  cv::extractChannel(lab, l, 0);
  cv::Mat mean, mean_sq;
  cv::blur(l, mean, cv::Size(size, size));
  cv::blur(l.mul(l), mean_sq, cv::Size(size, size));
  cv::Mat variance = cv::max(mean_sq - mean.mul(mean), 0.0);
  cv::Mat deviation;
  cv::sqrt(variance, deviation);
  return deviation;
}

struct Fitted {
  cv::Mat homography;                     // place processed pixels -> frame processed pixels
  std::vector<cv::Point2f> frame_points;  // the inliers, frame processed pixels
};

bool FitHomography(const ChangeReference& reference, int frame_width, const ChangeOptions& options,
                   Fitted* fitted) {
  if (static_cast<int>(reference.point_pairs.size()) < options.min_points) return false;
  std::vector<cv::Point2f> frame_points, place_points;
  for (const auto& [f, p] : reference.point_pairs) {
    frame_points.push_back(f);
    place_points.push_back(p);
  }
  std::vector<unsigned char> inliers;
  cv::Mat h = cv::findHomography(place_points, frame_points, cv::RANSAC,
                                 options.homography_threshold * frame_width, inliers, 500, 0.995);
  if (h.empty()) return false;
  int count = 0;
  for (size_t i = 0; i < inliers.size(); ++i) {
    if (inliers[i] == 0) continue;
    ++count;
    fitted->frame_points.push_back(frame_points[i]);
  }
  if (count < options.min_points ||
      count < options.min_inlier_share * static_cast<double>(inliers.size())) {
    return false;
  }
  // A plausible view change: no mirror image, scale within a factor of 4.
  const double det =
      h.at<double>(0, 0) * h.at<double>(1, 1) - h.at<double>(0, 1) * h.at<double>(1, 0);
  if (!(det > 1.0 / 16.0 && det < 16.0)) return false;
  fitted->homography = h;
  return true;
}

// The flow's patches (6 pixels) need a thumbnail at least twice as high and wide; a thinner one
// is compared as the homography maps it.
constexpr int kMinFlowSide = 12;

// Moves the warped stored view (and where it is valid) so that each frame pixel shows what the
// dense optical flow from the frame to the stored view finds there.
void AlignByFlow(const cv::Mat& frame_grey, cv::Mat* warped, cv::Mat* valid) {
  cv::Mat stored_grey;
  cv::cvtColor(*warped, stored_grey, cv::COLOR_BGR2GRAY);
  // Outside the stored view the frame's own pixels, so that the flow is not pulled to black.
  frame_grey.copyTo(stored_grey, *valid == 0);
  // The medium preset's finest level is half the thumbnail's resolution (finest scale 1; the flow
  // is upscaled to the thumbnail), with patches of 6 pixels every 3 there.
  cv::Ptr<cv::DISOpticalFlow> dis = cv::DISOpticalFlow::create(cv::DISOpticalFlow::PRESET_MEDIUM);
  dis->setPatchSize(6);
  dis->setPatchStride(3);
  cv::Mat flow;
  dis->calc(frame_grey, stored_grey, flow);
  cv::Mat map(flow.size(), CV_32FC2);
  for (int y = 0; y < flow.rows; ++y) {
    for (int x = 0; x < flow.cols; ++x) {
      const cv::Point2f f = flow.at<cv::Point2f>(y, x);
      map.at<cv::Point2f>(y, x) = cv::Point2f(x + f.x, y + f.y);
    }
  }
  cv::Mat moved, moved_valid;
  cv::remap(*warped, moved, map, cv::noArray(), cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  cv::remap(*valid, moved_valid, map, cv::noArray(), cv::INTER_NEAREST, cv::BORDER_CONSTANT);
  *warped = moved;
  *valid &= moved_valid;
}

// How far from where the homography maps it a region's content is looked for (fraction of the
// thumbnail's width).
constexpr double kElsewhereReach = 0.2;
// Grey levels of standard deviation a patch needs to be looked for elsewhere.
constexpr double kMinPatchDeviation = 6.0;
// Pixels a region needs at the stored view's scale to be looked for.
constexpr int kMinRegionPixels = 16;

// Whether the frame's content in `box` (thumbnail pixels; `region`: its own pixels in the box)
// shows in a compared stored view somewhere, at the scale the homography gives there, within a
// quarter of a scale: what the robot's motion moved by more than the alignment explains (the
// parallax of a near door or pillar) is there to be found; a new object is not.
bool SeenElsewhere(const cv::Mat& frame, const cv::Rect& box, const cv::Mat& region,
                   const std::vector<std::pair<cv::Mat, cv::Mat>>& compared, double similarity) {
  const cv::Mat patch = frame(box);
  if (patch.rows < 4 || patch.cols < 4) return false;
  // A plain patch has nothing to be found by: it matches every plain area equally.
  cv::Scalar mean, deviation;
  cv::meanStdDev(patch, mean, deviation, region);
  if (deviation[0] < kMinPatchDeviation) return false;
  const cv::Point2f centre(box.x + box.width * 0.5f, box.y + box.height * 0.5f);
  for (const auto& [thumbnail, h] : compared) {
    // The local scale of frame -> stored at the box's centre.
    const cv::Mat inverse = h.inv();
    std::vector<cv::Point2f> around = {centre, centre + cv::Point2f(1, 0),
                                       centre + cv::Point2f(0, 1)};
    std::vector<cv::Point2f> mapped;
    cv::perspectiveTransform(around, mapped, inverse);
    const cv::Point2f dx = mapped[1] - mapped[0], dy = mapped[2] - mapped[0];
    const double scale = std::sqrt(std::abs(dx.x * dy.y - dx.y * dy.x));
    if (!(scale > 0.1 && scale < 10.0)) continue;
    for (const double f : {0.8, 1.0, 1.25}) {
      const cv::Size size(static_cast<int>(std::lround(patch.cols * scale * f)),
                          static_cast<int>(std::lround(patch.rows * scale * f)));
      if (size.width < 4 || size.height < 4 || size.width > thumbnail.cols ||
          size.height > thumbnail.rows) {
        continue;
      }
      // Around where the homography puts the region: parallax moves content, but not far.
      const int reach = static_cast<int>(std::lround(kElsewhereReach * thumbnail.cols));
      const cv::Rect around_box =
          cv::Rect(cv::Point(static_cast<int>(mapped[0].x) - size.width / 2 - reach,
                             static_cast<int>(mapped[0].y) - size.height / 2 - reach),
                   cv::Size(size.width + 2 * reach, size.height + 2 * reach)) &
          cv::Rect(0, 0, thumbnail.cols, thumbnail.rows);
      if (around_box.width < size.width || around_box.height < size.height) continue;
      // Only the region's own pixels count, not what surrounds it in its box.
      cv::Mat resized, resized_region, scores;
      cv::resize(patch, resized, size, 0, 0, cv::INTER_AREA);
      cv::resize(region, resized_region, size, 0, 0, cv::INTER_NEAREST);
      if (cv::countNonZero(resized_region) < kMinRegionPixels) continue;
      MaskedCorrelation(thumbnail(around_box), resized, resized_region, &scores);
      // A flat stored window makes the masked correlation divide by nearly nothing: NaN, an
      // infinity or a value above 1 say nothing about the region and count as no match.
      cv::patchNaNs(scores, 0.0);
      cv::threshold(scores, scores, 1.0, 0.0, cv::THRESH_TOZERO_INV);
      double best = 0;
      cv::minMaxLoc(scores, nullptr, &best);
      if (best >= similarity) return true;
    }
  }
  return false;
}

// Per segment seen by this reference on at least options.segment_min_shared of its pixels: how
// far its mean Lab colour, or its mean local contrast times texture_weight, lies from the
// stored view's under the same pixels; each segment keeps the smallest over the references.
void SegmentDifferences(const cv::Mat& frame_lab, const cv::Mat& stored_lab,
                        const cv::Mat& frame_contrast, const cv::Mat& stored_contrast,
                        const cv::Mat& valid, const cv::Mat& segment_labels,
                        const std::vector<int>& segment_pixels, const ChangeOptions& options,
                        std::vector<double>* differences) {
  const size_t n = segment_pixels.size();
  std::vector<cv::Vec3d> frame_sum(n), stored_sum(n);
  std::vector<double> frame_texture(n, 0.0), stored_texture(n, 0.0);
  std::vector<int> seen(n, 0);
  for (int y = 0; y < segment_labels.rows; ++y) {
    const int* label = segment_labels.ptr<int>(y);
    const uint8_t* in_view = valid.ptr<uint8_t>(y);
    const cv::Vec3f* f = frame_lab.ptr<cv::Vec3f>(y);
    const cv::Vec3f* st = stored_lab.ptr<cv::Vec3f>(y);
    const float* fc = frame_contrast.ptr<float>(y);
    const float* sc = stored_contrast.ptr<float>(y);
    for (int x = 0; x < segment_labels.cols; ++x) {
      const int s = label[x];
      if (s < 0 || in_view[x] == 0) continue;
      frame_sum[s] += cv::Vec3d(f[x]);
      stored_sum[s] += cv::Vec3d(st[x]);
      frame_texture[s] += fc[x];
      stored_texture[s] += sc[x];
      ++seen[s];
    }
  }
  for (size_t s = 0; s < n; ++s) {
    if (seen[s] == 0 || seen[s] < options.segment_min_shared * segment_pixels[s]) continue;
    const double count = seen[s];
    const double colour = cv::norm((frame_sum[s] - stored_sum[s]) / count);
    const double texture =
        std::abs(frame_texture[s] - stored_texture[s]) / count * options.texture_weight;
    const double difference = std::max(colour, texture);
    double& kept = (*differences)[s];
    kept = kept < 0 ? difference : std::min(kept, difference);
  }
}

cv::Rect Scaled(const cv::Rect& box, double scale) {
  return cv::Rect(cv::Point(static_cast<int>(std::floor(box.x * scale)),
                            static_cast<int>(std::floor(box.y * scale))),
                  cv::Point(static_cast<int>(std::ceil(box.br().x * scale)),
                            static_cast<int>(std::ceil(box.br().y * scale))));
}

double IoU(const cv::Rect& a, const cv::Rect& b) {
  const double inter = (a & b).area();
  const double uni = a.area() + b.area() - inter;
  return uni > 0 ? inter / uni : 0.0;
}

}  // namespace

ChangeResult DetectChanges(const cv::Mat& frame_thumbnail, const cv::Size& frame_size,
                           const std::vector<ChangeReference>& references,
                           const ChangeOptions& options, const cv::Mat& segments) {
  ChangeResult result;
  if (frame_thumbnail.empty() || frame_thumbnail.type() != CV_8UC3 || frame_size.width <= 0 ||
      frame_size.height <= 0) {
    result.why_not = "no picture of the frame";
    return result;
  }
  const int width = frame_thumbnail.cols;
  const int height = frame_thumbnail.rows;
  const double to_thumb = static_cast<double>(width) / frame_size.width;
  const cv::Mat frame_lab = SmoothedLab(frame_thumbnail);
  const int radius =
      static_cast<int>(std::lround(options.alignment_tolerance * static_cast<double>(width)));
  const int margin =
      static_cast<int>(std::lround(options.edge_margin * static_cast<double>(width)));
  const int contrast_window =
      std::max(3, static_cast<int>(std::lround(options.texture_window * width)) | 1);
  const cv::Mat frame_contrast = LocalContrast(frame_lab, contrast_window);
  cv::Mat frame_grey;
  cv::cvtColor(frame_thumbnail, frame_grey, cv::COLOR_BGR2GRAY);

  cv::Mat difference(height, width, CV_32F, cv::Scalar(1e9));
  cv::Mat shared = cv::Mat::zeros(height, width, CV_8U);
  std::vector<cv::Point2f> matched_points;  // verified points of the frame, thumbnail pixels
  // The references compared: their thumbnails in grey and homographies (thumbnail -> frame
  // thumbnail).
  std::vector<std::pair<cv::Mat, cv::Mat>> compared;
  // Stored landmarks mapped into the frame (thumbnail pixels) that the frame did not match.
  struct UnmatchedLandmark {
    cv::Rect box;
    std::string name;  // "" when not named (see ChangeReference)
    float confidence = 0;
  };
  std::vector<UnmatchedLandmark> unmatched_landmarks;
  // The frame's segments at the thumbnail's size, and per segment the smallest difference of its
  // means over the references that see enough of it (negative: none does).
  cv::Mat segment_labels;
  int segment_count = 0;
  if (options.segment_difference > 0 && !segments.empty() && segments.type() == CV_32S) {
    cv::resize(segments, segment_labels, frame_thumbnail.size(), 0, 0, cv::INTER_NEAREST);
    double most = 0;
    cv::minMaxLoc(segment_labels, nullptr, &most);
    // Labels are 0..n-1 (negative ones belong to no segment); ids beyond one per thumbnail pixel
    // are no segmentation of this frame and are not compared.
    if (most >= 0 && most < static_cast<double>(segment_labels.total())) {
      segment_count = static_cast<int>(most) + 1;
    } else {
      segment_labels.release();
    }
  }
  std::vector<double> segment_difference(static_cast<size_t>(segment_count), -1.0);
  std::vector<int> segment_pixels(static_cast<size_t>(segment_count), 0);
  for (int y = 0; y < segment_labels.rows; ++y) {
    for (int x = 0; x < segment_labels.cols; ++x) {
      const int s = segment_labels.at<int>(y, x);
      if (s >= 0) ++segment_pixels[s];
    }
  }
  for (const ChangeReference& reference : references) {
    if (static_cast<int>(result.references) >= options.max_references) break;
    if (reference.thumbnail.empty() || reference.thumbnail.type() != CV_8UC3 ||
        reference.image_width <= 0) {
      if (result.why_not.empty()) result.why_not = "the place has no thumbnail";
      continue;
    }
    Fitted fitted;
    if (!FitHomography(reference, frame_size.width, options, &fitted)) {
      if (result.why_not.empty()) result.why_not = "no homography between the views";
      continue;
    }
    const double place_to_thumb =
        static_cast<double>(reference.thumbnail.cols) / reference.image_width;
    cv::Mat scale_place = cv::Mat::eye(3, 3, CV_64F);
    scale_place.at<double>(0, 0) = scale_place.at<double>(1, 1) = 1.0 / place_to_thumb;
    cv::Mat scale_frame = cv::Mat::eye(3, 3, CV_64F);
    scale_frame.at<double>(0, 0) = scale_frame.at<double>(1, 1) = to_thumb;
    const cv::Mat h = scale_frame * fitted.homography * scale_place;  // thumb -> thumb

    cv::Mat warped, valid;
    cv::warpPerspective(reference.thumbnail, warped, h, frame_thumbnail.size(), cv::INTER_LINEAR,
                        cv::BORDER_CONSTANT);
    cv::warpPerspective(cv::Mat(reference.thumbnail.size(), CV_8U, cv::Scalar(255)), valid, h,
                        frame_thumbnail.size(), cv::INTER_NEAREST, cv::BORDER_CONSTANT);
    // The edges of the shared view are the place's: where the motion brings new scene into the
    // frame, the stored view ends. The frame's own border is none where the place sees beyond it
    // (erosion leaves the image border alone).
    if (margin > 0) {
      cv::erode(
          valid, valid,
          cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * margin + 1, 2 * margin + 1)));
    }
    // Only where the homography holds: near points that fit it. Elsewhere (near walls, doors
    // that the robot passes) the parallax of the scene's depth makes differences of its own.
    if (options.support_radius > 0) {
      std::vector<cv::Point> at;
      for (const cv::Point2f& p : fitted.frame_points) {
        at.emplace_back(static_cast<int>(p.x * to_thumb), static_cast<int>(p.y * to_thumb));
      }
      const int r = std::max(1, static_cast<int>(std::lround(options.support_radius * width)));
      valid &= DilatePoints(
          at, valid.size(),
          cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * r + 1, 2 * r + 1)));
    }
    if (cv::countNonZero(valid) < options.min_area * width * height) {
      if (result.why_not.empty()) result.why_not = "the views share too little";
      continue;
    }
    if (options.flow_alignment && std::min(width, height) >= kMinFlowSide) {
      AlignByFlow(frame_grey, &warped, &valid);
    }
    const cv::Mat stored_lab = MatchExposure(SmoothedLab(warped), frame_lab, valid);
    cv::Mat outside = OutsideRange(frame_lab, stored_lab, radius);
    cv::Mat stored_contrast;
    if (options.texture_weight > 0 || segment_count > 0) {
      stored_contrast = LocalContrast(stored_lab, contrast_window);
    }
    if (options.texture_weight > 0) {
      cv::Mat texture;
      cv::absdiff(frame_contrast, stored_contrast, texture);
      outside = cv::max(outside, texture * options.texture_weight);
    }
    if (segment_count > 0) {
      SegmentDifferences(frame_lab, stored_lab, frame_contrast, stored_contrast, valid,
                         segment_labels, segment_pixels, options, &segment_difference);
    }
    // Per pixel the smallest difference among the references that see it.
    cv::Mat inside_valid;
    outside.copyTo(inside_valid);
    inside_valid.setTo(1e9, valid == 0);
    difference = cv::min(difference, inside_valid);
    shared |= valid;
    ++result.references;
    cv::Mat stored_grey;
    cv::cvtColor(reference.thumbnail, stored_grey, cv::COLOR_BGR2GRAY);
    compared.emplace_back(stored_grey, h);
    for (const cv::Point2f& p : fitted.frame_points) {
      matched_points.emplace_back(p.x * to_thumb, p.y * to_thumb);
    }
    // Stored landmarks the frame did not match, where the place would show them.
    for (size_t i = 0; i < reference.landmark_boxes.size(); ++i) {
      if (i < reference.landmark_matched.size() && reference.landmark_matched[i]) continue;
      const cv::Rect& box = reference.landmark_boxes[i];
      std::vector<cv::Point2f> corners = {cv::Point2f(box.x, box.y), cv::Point2f(box.br().x, box.y),
                                          cv::Point2f(box.br().x, box.br().y),
                                          cv::Point2f(box.x, box.br().y)};
      std::vector<cv::Point2f> mapped;
      cv::perspectiveTransform(corners, mapped, fitted.homography);
      cv::Rect in_frame =
          cv::boundingRect(mapped) & cv::Rect(0, 0, frame_size.width, frame_size.height);
      if (in_frame.area() <= 0) continue;
      UnmatchedLandmark unmatched;
      unmatched.box = Scaled(in_frame, to_thumb);
      unmatched.confidence = i < reference.landmark_class_confidences.size()
                                 ? reference.landmark_class_confidences[i]
                                 : 0.f;
      if (i < reference.landmark_classes.size() &&
          unmatched.confidence >= options.min_class_confidence) {
        unmatched.name = reference.landmark_classes[i];
      }
      unmatched_landmarks.push_back(std::move(unmatched));
    }
  }
  if (result.references == 0) return result;
  const int shared_pixels = cv::countNonZero(shared);
  if (shared_pixels == 0) {
    // The alignment left no pixel the two views share: nothing to compare (and no median).
    result.why_not = "the views share too little";
    return result;
  }
  result.checked = true;
  result.why_not.clear();
  result.shared_view = static_cast<double>(shared_pixels) / (width * height);
  difference.setTo(0, shared == 0);
  result.difference = difference;
  result.shared = shared;

  // Regions that differ beyond the threshold: the sensitivity's, or more in a frame whose shared
  // view differs throughout (a poor alignment, a changed light): the median difference plus
  // noise_spread robust deviations. Seeds above it grow through pixels above grow_fraction of it.
  std::vector<float> values;
  values.reserve(static_cast<size_t>(shared_pixels));
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      if (shared.at<uint8_t>(y, x) != 0) values.push_back(difference.at<float>(y, x));
    }
  }
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  const double median = values[values.size() / 2];
  for (float& v : values) v = static_cast<float>(std::abs(v - median));
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  const double spread = 1.4826 * values[values.size() / 2];
  const double threshold = std::max(options.Threshold(), median + options.noise_spread * spread);
  result.threshold = threshold;
  result.median_difference = median;
  result.difference_spread = spread;
  const cv::Mat small = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(3, 3));
  cv::Mat seeds = (difference > threshold) & shared;
  cv::morphologyEx(seeds, seeds, cv::MORPH_OPEN, small);
  cv::Mat grown = (difference > options.grow_fraction * threshold) & shared;
  cv::morphologyEx(grown, grown, cv::MORPH_CLOSE, small, cv::Point(-1, -1), 2);
  cv::Mat labels, stats, centroids;
  const int count = cv::connectedComponentsWithStats(grown, labels, stats, centroids, 8, CV_32S);
  std::vector<bool> seeded(static_cast<size_t>(count), false);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      if (seeds.at<uint8_t>(y, x) != 0) seeded[labels.at<int>(y, x)] = true;
    }
  }
  // Distance of each shared pixel to the edge of the shared view (pixels).
  cv::Mat to_edge;
  cv::distanceTransform(shared, to_edge, cv::DIST_L2, 3);
  const double edge_band = std::max(1.0, options.edge_band * width);
  // Verified points per pixel of the shared view: the density a seen region has.
  const double density =
      shared_pixels > 0 ? static_cast<double>(matched_points.size()) / shared_pixels : 0.0;
  const double frame_area = static_cast<double>(width) * height;
  // Whether a candidate (its pixels `in_component`, `area` of them, within `box`) is explained by
  // the robot's motion or was seen at the place; otherwise the change it makes.
  const auto drop = [&](const cv::Rect& box, const char* rule) {
    result.dropped.push_back(
        {Scaled(box, 1.0 / to_thumb) & cv::Rect(0, 0, frame_size.width, frame_size.height), rule});
  };
  // `differs`: the candidate's strongest pixel difference (a region) or its mean (a segment),
  // against the `needed` one.
  const auto judge = [&](const cv::Mat& in_component, const cv::Rect& box, int area, double differs,
                         double needed, std::vector<SceneChange>* changes) {
    // A speck is no candidate (nor listed, as a weak one is not); a region too large is dropped.
    if (area < options.min_area * frame_area) return;
    if (box.area() > options.max_area * frame_area) return drop(box, "size");
    // Along the edge of the shared view: what the motion brought into view, or the parallax of
    // near objects there.
    if (cv::countNonZero(in_component & (to_edge < edge_band)) > options.max_edge_share * area) {
      return drop(box, "edge");
    }
    // Matched content inside: what is there was seen at the place.
    int inside = 0;
    for (const cv::Point2f& p : matched_points) {
      const int x = static_cast<int>(p.x), y = static_cast<int>(p.y);
      if (x >= 0 && y >= 0 && x < width && y < height && in_component.at<uint8_t>(y, x) != 0) {
        ++inside;
      }
    }
    if (inside > 0 && inside >= options.max_match_density * density * area) {
      return drop(box, "matched");
    }
    if (options.max_elsewhere_similarity < 1.0 &&
        SeenElsewhere(frame_grey, box, in_component(box), compared,
                      options.max_elsewhere_similarity)) {
      return drop(box, "elsewhere");
    }
    // Confidence: how far beyond what it needed the candidate differs (twice the need counts
    // fully; a weak region, which nowhere reaches it, counts nothing), and how large it is.
    const double strength = std::clamp((differs - needed) / needed, 0.0, 1.0);
    const double size = std::clamp(area / (0.02 * frame_area), 0.0, 1.0);
    SceneChange change;
    change.confidence = static_cast<float>(0.5 + 0.25 * strength + 0.25 * size);
    change.box = Scaled(box, 1.0 / to_thumb) & cv::Rect(0, 0, frame_size.width, frame_size.height);
    // A stored landmark that was not matched where the region lies: it disappeared.
    double best = 0.3;
    for (const UnmatchedLandmark& landmark : unmatched_landmarks) {
      const double overlap = IoU(landmark.box, box);
      if (overlap >= best) {
        best = overlap;
        change.kind = SceneChange::Kind::kDisappeared;
        change.object_class = landmark.name;
        change.class_confidence = landmark.confidence;
      }
    }
    changes->push_back(change);
  };
  for (int c = 1; c < count; ++c) {
    const cv::Rect box(stats.at<int>(c, cv::CC_STAT_LEFT), stats.at<int>(c, cv::CC_STAT_TOP),
                       stats.at<int>(c, cv::CC_STAT_WIDTH), stats.at<int>(c, cv::CC_STAT_HEIGHT));
    const int area = stats.at<int>(c, cv::CC_STAT_AREA);
    // A region that differs, but nowhere by the threshold plus strong_spread deviations, differs
    // too little unless it is large, its mean reaches weak_mean of the threshold and stands
    // weak_spread robust deviations above the view's median difference (ChangeOptions::weak_mean).
    const bool may_be_weak = options.weak_mean > 0 && area >= options.weak_min_area * frame_area;
    if (!seeded[c] && !may_be_weak) {
      if (area >= options.min_area * frame_area) drop(box, "weak");
      continue;
    }
    const cv::Mat in_component = labels == c;
    // A seeded region whose strongest pixel only just crosses the threshold is judged as weak.
    double peak = 0.0;
    cv::minMaxLoc(difference, nullptr, &peak, nullptr, nullptr, in_component);
    const bool strong = seeded[c] && peak >= threshold + options.strong_spread * spread;
    if (!strong && !may_be_weak) {
      if (area >= options.min_area * frame_area) drop(box, "weak");
      continue;
    }
    const double mean = cv::mean(difference, in_component)[0];
    if (!strong &&
        (mean < options.weak_mean * threshold || mean < median + options.weak_spread * spread)) {
      if (area >= options.min_area * frame_area) drop(box, "weak");
      continue;
    }
    judge(in_component, box, area, peak, threshold, &result.changes);
  }
  // Whole segments whose means differ, where no region found them already.
  std::vector<SceneChange> by_segment;
  for (int s = 0; s < segment_count; ++s) {
    if (segment_difference[s] < options.segment_difference) continue;
    const cv::Mat in_segment = (segment_labels == s) & shared;
    const int area = cv::countNonZero(in_segment);
    if (area == 0) continue;
    const cv::Rect box = cv::boundingRect(in_segment);
    if (std::min(box.width, box.height) < options.segment_min_side * width) continue;
    judge(in_segment, box, area, segment_difference[s], options.segment_difference, &by_segment);
  }
  for (const SceneChange& change : by_segment) {
    const bool known = std::any_of(
        result.changes.begin(), result.changes.end(),
        [&change](const SceneChange& found) { return IoU(found.box, change.box) >= 0.3; });
    if (!known) result.changes.push_back(change);
  }
  std::sort(result.changes.begin(), result.changes.end(),
            [](const SceneChange& a, const SceneChange& b) { return a.confidence > b.confidence; });
  if (static_cast<int>(result.changes.size()) > options.max_changes) {
    result.changes.resize(options.max_changes);
  }
  return result;
}

cv::Mat DrawChanges(const cv::Mat& frame, const cv::Size& frame_size,
                    const std::vector<SceneChange>& changes, int width) {
  if (frame.empty() || frame_size.width <= 0 || width <= 0) return cv::Mat();
  cv::Mat picture;
  const double scale = static_cast<double>(width) / frame.cols;
  cv::resize(frame, picture,
             cv::Size(width, std::max(1, static_cast<int>(std::lround(frame.rows * scale)))), 0, 0,
             cv::INTER_AREA);
  if (picture.channels() == 1) cv::cvtColor(picture, picture, cv::COLOR_GRAY2BGR);
  const double to_picture = static_cast<double>(width) / frame_size.width;
  for (const SceneChange& change : changes) {
    const cv::Scalar colour = change.kind == SceneChange::Kind::kAppeared ? cv::Scalar(0, 0, 255)
                                                                          : cv::Scalar(0, 220, 255);
    const cv::Rect box = Scaled(change.box, to_picture);
    cv::rectangle(picture, box, colour, 2, cv::LINE_AA);
    char text[64];
    std::snprintf(text, sizeof(text), "%s%s%.2f", change.object_class.c_str(),
                  change.object_class.empty() ? "" : " ", change.confidence);
    cv::putText(picture, text, cv::Point(box.x, std::max(10, box.y - 3)), cv::FONT_HERSHEY_SIMPLEX,
                0.4, colour, 1, cv::LINE_AA);
  }
  return picture;
}

}  // namespace placerec
