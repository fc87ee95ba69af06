// Scene changes at a revisit (pipeline step after 9, seed §7.2.4): when a frame is matched to a
// stored place, the part of the view the two share is compared; what the frame shows there that
// the place did not (an object that appeared) and what the place showed that the frame does not
// (a landmark that disappeared) are the changes a patrol robot reports. The shared view comes from
// the geometric verification (loop_decision.h): a homography fitted to its inlier keypoint pairs
// maps the stored place's thumbnail into the frame, and dense optical flow then aligns what the
// homography leaves misplaced (parallax). Regions whose appearance differs beyond the
// sensitivity and that hold no verified match are changes; the robot's own motion (edges of the
// shared view, parallax around edges, a changed exposure) and objects that did match are not.
// The stored place's route neighbours that also matched serve as further references: a region is
// a change only when it differs from every one of them.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

namespace placerec {

struct ChangeOptions {
  // Look for changes at every matched place (insert or query).
  bool enabled = true;
  // A frame that is no loop closure is still compared with its best place when the geometric
  // verification kept at least this many inlier point pairs with it (a revisit whose score the
  // change itself, or the sequence, kept under the loop threshold); 0: only at loop closures.
  // 12: min_points, the pairs the detector's own homography needs; its rules (inlier share,
  // plausible scale) then decide whether the views are compared.
  int min_inliers_without_loop = 12;
  // How readily a difference becomes an alarm, in (0, 1]: the appearance difference a region
  // needs is max_difference - sensitivity * (max_difference - min_difference) CIE Lab units.
  double sensitivity = 0.5;
  double min_difference = 10.0;
  double max_difference = 40.0;
  // Verified point pairs the homography needs; fewer: the place is not checked.
  int min_points = 12;
  // RANSAC reprojection threshold of the homography, as a fraction of the frame's width.
  double homography_threshold = 0.03;
  // Share of the homography's fitted pairs that must be inliers (a view that a plane does not
  // describe, a strong parallax, is not checked).
  double min_inlier_share = 0.3;
  // The shared view is trimmed by this fraction of the frame width at its edges, where the
  // robot's motion brings new scene into view.
  double edge_margin = 0.05;
  // The shared view is where the homography holds: within this fraction of the frame width of a
  // verified point that fits it (0: the whole mapped view).
  double support_radius = 0.3;
  // After the homography, the stored view is aligned to the frame by dense optical flow (DIS,
  // Kroeger et al. 2016) within the shared view: the parallax of a scene that is not one plane
  // (corridor walls, a pillar before a facade) is then no difference, while a new object, which
  // has no counterpart in the stored view to flow to, stays one.
  bool flow_alignment = true;
  // Misalignment tolerated when comparing (fraction of the frame width): a pixel differs only by
  // what lies outside the range of the stored values around it.
  double alignment_tolerance = 0.02;
  // Texture counts too: the difference of local contrast (standard deviation of L in a window of
  // texture_window of the frame width) times texture_weight is a difference in Lab units.
  double texture_weight = 1.5;
  double texture_window = 0.05;
  // In a frame whose shared view differs throughout (a poor alignment, a changed light) a change
  // must also differ by the median difference plus this many robust standard deviations.
  double noise_spread = 4.0;
  // A change grows from pixels above the threshold through neighbours above this fraction of it
  // (whole objects rather than their most different parts).
  double grow_fraction = 0.4;
  // A region seeded above the threshold is a candidate outright only when its strongest pixel
  // differs by the threshold plus strong_spread robust deviations of the shared view's
  // difference; otherwise it must pass the weak test below. Where the homography and the flow
  // align the view only roughly (parallax across a wide path, near railings) the difference
  // spreads and many regions just cross the threshold, while a new object differs clearly
  // somewhere; in a well aligned view the spread is small and the rule asks little more than the
  // threshold (0: every seeded region is a candidate).
  double strong_spread = 6.0;
  // A grown region without such a peak is still a candidate when it covers at least
  // weak_min_area of the frame and its mean difference reaches weak_mean of the threshold and
  // stands weak_spread robust deviations above the frame's median difference: a large object
  // whose colours lie near its background's differs a little everywhere, in a view that is
  // otherwise aligned well (where the whole view differs, parallax makes such regions) (0: off).
  double weak_mean = 0.5;
  double weak_spread = 8.0;
  double weak_min_area = 0.01;
  // A region with more than max_edge_share of its pixels within edge_band (fraction of the frame
  // width) of the shared view's edge is explained by the motion: new scene entering the view, or
  // the parallax of near objects that the homography does not model.
  double edge_band = 0.05;
  double max_edge_share = 0.5;
  // A change covers at least min_area and at most max_area of the frame (fractions of its area);
  // larger differences are a changed view, not an object.
  double min_area = 0.004;
  double max_area = 0.25;
  // A region holding at least this share of the shared view's verified points per unit area
  // matched: what is there was seen before (an object that did match, or occludes nothing).
  double max_match_density = 0.35;
  // A region whose content shows in a stored view somewhere near its scale (normalised
  // correlation at least this) was moved there by the robot's motion, not put there (1: off).
  double max_elsewhere_similarity = 0.7;
  // Whole segments too: the frame's segments (its segmentation, seed Ch. 3) are compared by
  // their mean colour and mean local contrast against the aligned stored view's under the same
  // pixels; a segment whose means differ by at least segment_difference Lab units is a change
  // (the same rules of size, edge, matched points and elsewhere apply). Averaging over a whole
  // object finds what differs too little per pixel (an object whose colours lie near its
  // background's). 0: off.
  double segment_difference = 0.0;
  // ... when at least this share of the segment lies in the shared view, and its box is at least
  // segment_min_side of the frame width high and wide (a thin segment along a door frame or a
  // wall's edge differs where the alignment misses by a pixel, not because something came).
  double segment_min_shared = 0.7;
  double segment_min_side = 0.04;
  // At most this many changes per frame, most confident first.
  int max_changes = 5;
  // A change is named by an object class (seed Ch. 4) only when the classifier's confidence in
  // it is at least this; otherwise it is an "object". 0.5 is where the boosted sum turns
  // positive (ObjectLabel::confidence): the classifier votes for the class rather than against;
  // below it the best class is only the least unlikely one.
  double min_class_confidence = 0.5;
  // Matched places of the best place's route (same robot, within this many seconds of it) that
  // serve as further references, at most max_references of them in all.
  int max_references = 3;
  double reference_window_seconds = 3.0;
  // Width of the alarm pictures (frame with boxes, stored place), pixels.
  int picture_width = 320;

  bool Check(std::string* error) const;
  // The Lab difference a region needs (see sensitivity).
  double Threshold() const;
};

// A stored place seen as a reference for the frame.
struct ChangeReference {
  cv::Mat thumbnail;    // BGR thumbnail of the place's frame
  int image_width = 0;  // width of the processed frame its points and boxes refer to (pixels)
  // Verified keypoint pairs (frame point, place point) in processed pixels of each frame.
  std::vector<std::pair<cv::Point2f, cv::Point2f>> point_pairs;
  // The place's stored landmarks (place pixels), their classes ("" unclassified) and how sure
  // the classifier was of each (a disappearance is named by its landmark's class when at least
  // min_class_confidence), with whether the frame matched them.
  std::vector<cv::Rect> landmark_boxes;
  std::vector<std::string> landmark_classes;
  std::vector<float> landmark_class_confidences;
  std::vector<bool> landmark_matched;
};

struct SceneChange {
  enum class Kind { kAppeared = 0, kDisappeared = 1 };
  Kind kind = Kind::kAppeared;
  cv::Rect box;                   // in the frame, processed pixels
  std::string object_class;       // "" when not classified
  float class_confidence = 0.0f;  // the classifier's, in [0, 1] (ObjectLabel::confidence)
  float confidence = 0.0f;        // of the change, in [0, 1]
};

// A grown region that differed but was judged no change, and the rule that said so ("weak": no
// pixel beyond the threshold plus strong_spread deviations and not enough for weak_mean; "size":
// its box larger than max_area; "edge", "matched", "elsewhere"; with segment_difference on,
// dropped segments too): what an evaluation reads to see why a change was missed. Specks under
// min_area are no candidates and are not listed.
struct DroppedRegion {
  cv::Rect box;  // in the frame, processed pixels
  std::string rule;
};

struct ChangeResult {
  bool checked = false;              // a shared view was found and compared
  std::string why_not;               // when not checked: why
  double shared_view = 0;            // share of the frame compared
  double threshold = 0;              // the Lab difference changes needed in this frame
  double median_difference = 0;      // over the shared view (Lab units)
  double difference_spread = 0;      // its robust standard deviation (1.4826 MAD)
  int references = 0;                // places compared against
  std::vector<SceneChange> changes;  // most confident first
  std::vector<DroppedRegion> dropped;
  cv::Mat difference;  // CV_32F per pixel of the frame's thumbnail (Lab units; 0 outside)
  cv::Mat shared;      // CV_8U per pixel of the frame's thumbnail: 255 where it was compared
};

// Compares the frame (its thumbnail and the size of its processed frame) with the references,
// the first being the matched place. Never throws for bad input: an unusable reference is
// skipped and the result says why nothing was checked.
// `segments` (optional): the frame's segment labels (CV_32S, any size covering the frame,
// e.g. SceneSegmentation::labels), for ChangeOptions::segment_difference.
ChangeResult DetectChanges(const cv::Mat& frame_thumbnail, const cv::Size& frame_size,
                           const std::vector<ChangeReference>& references,
                           const ChangeOptions& options, const cv::Mat& segments = cv::Mat());

// Whether a frame is compared with its best place: at a loop closure, or when the best place's
// verification kept at least options.min_inliers_without_loop inlier pairs (when that is set).
bool CompareAtRevisit(bool loop_closure, int verified_pairs, const ChangeOptions& options);

// "appeared" / "disappeared".
const char* ChangeKindName(SceneChange::Kind kind);

// The frame with the changes' boxes drawn (red appeared, yellow disappeared, with class and
// confidence), `width` pixels wide; boxes are in processed pixels of a frame `frame_size`.
cv::Mat DrawChanges(const cv::Mat& frame, const cv::Size& frame_size,
                    const std::vector<SceneChange>& changes, int width);

}  // namespace placerec
