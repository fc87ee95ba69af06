#include "common/pipeline/flags.h"

#include <istream>
#include <ostream>
#include <string>

#include "common/organization/organizer_flags.h"
#include "common/recognition/landmark_index.h"
#include "common/segmentation/superpixel_flags.h"

namespace placerec {

std::ostream& operator<<(std::ostream& os, RecognitionMode value) {
  return os << (value == RecognitionMode::kDefault ? "default" : "seed");
}

std::istream& operator>>(std::istream& is, RecognitionMode& value) {
  std::string text;
  is >> text;
  if (text == "default") {
    value = RecognitionMode::kDefault;
  } else if (text == "seed") {
    value = RecognitionMode::kSeed;
  } else {
    is.setstate(std::ios::failbit);
  }
  return is;
}

std::ostream& operator<<(std::ostream& os, QueryObjects value) {
  return os << (value == QueryObjects::kAll ? "all" : "landmarks");
}

std::istream& operator>>(std::istream& is, QueryObjects& value) {
  std::string text;
  is >> text;
  if (text == "all") {
    value = QueryObjects::kAll;
  } else if (text == "landmarks") {
    value = QueryObjects::kLandmarks;
  } else {
    is.setstate(std::ios::failbit);
  }
  return is;
}

std::ostream& operator<<(std::ostream& os, IndexSearch value) {
  return os << (value == IndexSearch::kFlann ? "flann" : "exhaustive");
}

std::istream& operator>>(std::istream& is, IndexSearch& value) {
  std::string text;
  is >> text;
  if (text == "flann") {
    value = IndexSearch::kFlann;
  } else if (text == "exhaustive") {
    value = IndexSearch::kExhaustive;
  } else {
    is.setstate(std::ios::failbit);
  }
  return is;
}

std::ostream& operator<<(std::ostream& os, DescriptorSearch value) {
  return os << (value == DescriptorSearch::kHnsw ? "hnsw" : "flann");
}

std::istream& operator>>(std::istream& is, DescriptorSearch& value) {
  std::string text;
  is >> text;
  if (text == "hnsw") {
    value = DescriptorSearch::kHnsw;
  } else if (text == "flann") {
    value = DescriptorSearch::kFlann;
  } else {
    is.setstate(std::ios::failbit);
  }
  return is;
}

std::ostream& operator<<(std::ostream& os, SegmentationMethod value) {
  return os << (value == SegmentationMethod::kOrganization ? "organization" : "superpixels");
}

std::istream& operator>>(std::istream& is, SegmentationMethod& value) {
  std::string text;
  is >> text;
  if (text == "organization") {
    value = SegmentationMethod::kOrganization;
  } else if (text == "superpixels") {
    value = SegmentationMethod::kSuperpixels;
  } else {
    is.setstate(std::ios::failbit);
  }
  return is;
}

void AddRecognizerFlags(FlagParser* p, RecognizerOptions* o) {
  AnalyzerOptions& a = o->analyzer;
  p->Add("segmentation", &a.segmentation,
         "organization (Perceptual Organization, seed Ch. 3) or superpixels (coarse superpixels "
         "as objects)");
  AddOrganizerFlags(p, &a.organization);
  p->Add("max-image-width", &a.max_image_width,
         "frames wider than this, or of more pixels than its square, are scaled down before "
         "SIFT (pixels; 0 keeps the size, as the seed did; 960, the widest frames the defaults "
         "were chosen on, processes an HD camera's frames or a phone's photos as those)");
  p->Add("small-frame-width", &a.small_frame_width,
         "frames narrower than this (pixels) are scaled up to upscaled-width before SIFT and "
         "segmentation, so that small cameras give objects of enough keypoints (0: keep the "
         "size; not in the seed, which ran on full-size frames)");
  p->Add("upscaled-width", &a.upscaled_width,
         "the width small frames are scaled up to (pixels); a frame taller than twice its width "
         "is scaled up less, to at most 2 x upscaled-width^2 pixels");
  p->Add("sift-max-features", &a.features.max_features, "keep the strongest N keypoints (0: all)");
  p->Add("sift-octave-layers", &a.features.octave_layers, "SIFT scale-space layers per octave");
  p->Add("sift-contrast-threshold", &a.features.contrast_threshold,
         "SIFT DoG contrast threshold (lower finds more keypoints on plain scenes)");
  p->Add("sift-edge-threshold", &a.features.edge_threshold, "SIFT edge-response threshold");
  p->Add("sift-sigma", &a.features.sigma, "SIFT first-octave Gaussian sigma");
  p->Add("sift-min-keypoints-per-mp", &a.features.min_keypoints_per_megapixel,
         "frames with fewer keypoints per megapixel run again at the low contrast threshold "
         "(0: never, as in the seed)");
  p->Add("sift-low-contrast-threshold", &a.features.low_contrast_threshold,
         "contrast threshold of the retry on plain frames (not in the seed)");
  AddSuperpixelFlags(p, &a.superpixels, "", "--segmentation superpixels (objects; k 1200)");
  p->Add("h-min-intensity", &a.colour.min_intensity,
         "colour invariant: ignore pixels darker than this (eq. 5.6 D, 0..1)");
  p->Add("h-min-denominator", &a.colour.min_denominator,
         "colour invariant: ignore pixels with |D_ll| below this fraction of D");
  p->Add("h-max", &a.colour.max_abs_h, "colour invariant H is clamped to [-h-max, h-max]");
  p->Add("min-frame-chroma", &a.min_frame_chroma,
         "frames with less mean Lab chroma are treated as grey (no colour filter)");
  p->Add("object-min-keypoints", &a.objects.min_keypoints,
         "a segment is an object with at least this many keypoints (§5.7: more than 8)");
  p->Add("objects-include-background", &a.objects.include_background,
         "background segments (sky, road, tree, grass, water) may be objects too when "
         "textured (the seed keeps them out: false)");
  p->Add("h-bin-width", &a.objects.colour.bin_width, "H histogram bin width");
  p->Add("h-peak-fraction", &a.objects.colour.peak_fraction,
         "dominant H peaks are within this fraction of the highest (§5.6: 0.8)");
  p->Add("h-peak-separation", &a.objects.colour.min_peak_separation,
         "dominant peaks closer than this are one colour");
  p->Add("landmark-history", &o->landmarks.history_frames,
         "previous frames of the same robot an object is compared with (§5.7: 3)");
  p->Add("landmark-min-matches", &o->landmarks.matching.min_matches,
         "matched descriptors that make an object a landmark (§5.3: 6)");
  p->Add("landmark-ratio", &o->landmarks.matching.ratio, "ratio test for landmark selection");
  p->Add("landmark-knn", &o->landmarks.matching.knn,
         "nearest neighbours per descriptor when comparing with previous frames");
  p->Add("landmark-min-votes", &o->landmarks.matching.min_votes,
         "neighbour votes an object pair needs before verification (landmarks)");
  p->Add("landmark-flann-checks", &o->landmarks.flann.checks,
         "FLANN leaves checked per descriptor when comparing with previous frames");
  p->Add("landmark-exhaustive", &o->landmarks.matching.exhaustive_verification,
         "verify voted object pairs with the exact ratio test over all rows (landmarks)");
  p->Add("query-objects", &o->query_objects,
         "objects looked up in the map: all | landmarks (the seed, §5.7)");
  p->Add("max-query-descriptors", &o->max_query_descriptors,
         "look up at most this many descriptors per frame, strongest first (0: all)");
  p->Add("query-unassigned", &o->query_unassigned_keypoints,
         "also look up keypoints outside every object (place-level matching only; the seed: "
         "false)");
  p->Add("min-descriptors-per-place", &o->min_descriptors_per_place,
         "plain places top up their landmarks' tracked descriptors to this many (0: tracked only)");
  p->Add("store-tracked-only", &o->store_tracked_descriptors_only,
         "store only the landmark descriptors that matched into previous frames (the seed "
         "stores all of a new landmark's: false)");
  p->Add("index-search", &o->index.search,
         "verification: flann (approximate nearest neighbours vote, from the index "
         "--descriptor-search builds) | exhaustive (every candidate, §5.6 literally)");
  p->Add("use-count-range", &o->index.use_count_range,
         "restrict candidates by SIFT count (range tree, §5.6)");
  p->Add("count-range-low", &o->index.count_range_low,
         "candidates have at least this times the query's SIFT count (§5.6: 2/3)");
  p->Add("count-range-high", &o->index.count_range_high,
         "candidates have at most this times the query's SIFT count (§5.6: 4/3)");
  p->Add("use-colour-filter", &o->index.use_colour_filter,
         "restrict candidates by dominant colour invariant (§5.6)");
  p->Add("colour-tolerance", &o->index.colour.tolerance, "dominant H difference (§5.6: 0.2)");
  p->Add("multi-peak-needs-multi-peak", &o->index.colour.multi_peak_needs_multi_peak,
         "a multi-colour query only matches multi-colour objects (§5.6)");
  p->Add("match-ratio", &o->index.matching.ratio, "ratio test for retrieval");
  p->Add("match-min", &o->index.matching.min_matches,
         "matched descriptors that make two objects the same (§5.6: more than 6)");
  p->Add("match-knn", &o->index.matching.knn, "nearest neighbours per query descriptor");
  p->Add("match-min-votes", &o->index.matching.min_votes,
         "neighbour votes a candidate pair needs before verification");
  p->Add("match-exhaustive", &o->index.matching.exhaustive_verification,
         "verify voted object pairs with the exact ratio test over all rows");
  p->Add(
      "vote-places", &o->index.vote_places,
      "also verify the places most query descriptors have neighbours in (0: object matches only)");
  p->Add("exact-places", &o->index.exact_places,
         "match every query descriptor again exactly against the candidate places with the "
         "most matches from the neighbour lists, at most this many: in a large map, or where "
         "many descriptors look alike, a revisited place's own matches are crowded out of the "
         "nearest neighbours (0, the default: none, as in the seed; 3 is measured in "
         "docs/results.md: more loop closures at full size, wrong ones on small frames)");
  p->Add("exact-route-neighbours", &o->index.exact_route_neighbours,
         "each place of --exact-places also brings this many candidate places of its robot on "
         "either side along the route, matched exactly too (not in the seed)");
  p->Add("exact-max-comparisons", &o->index.exact_max_comparisons,
         "descriptor comparisons (query descriptors times a place's) the exact matching of "
         "--exact-places may take per frame; a place that would pass them keeps its matches "
         "from the nearest neighbours");
  p->Add("vote-window-seconds", &o->index.vote_window_seconds,
         "a robot's places taken within this many seconds count as one location for the votes "
         "(a voted place brings at most the " +
             std::to_string(LandmarkIndex::kMaxVoteNeighbours) + " nearest in time as candidates)");
  p->Add("descriptor-search", &o->index.flann.method,
         "nearest neighbours of the map's descriptors: hnsw (a graph; cost grows with the "
         "logarithm of the map) | flann (a k-d tree; cost grows with the map)");
  p->Add("flann-checks", &o->index.flann.checks,
         "FLANN leaves checked per query descriptor (--descriptor-search flann)");
  p->Add("hnsw-links", &o->index.flann.hnsw_links,
         "links per descriptor in the search graph (hnswlib M; more: slower, closer to exact)");
  p->Add("hnsw-build-candidates", &o->index.flann.hnsw_build_candidates,
         "candidates kept while linking a new descriptor (hnswlib ef_construction)");
  p->Add("hnsw-search-candidates", &o->index.flann.hnsw_search_candidates,
         "candidates kept while searching (hnswlib ef; at least --match-knn are used)");
  p->Add("sequence-frames", &o->sequence.frames,
         "earlier frames of the robot that may support a candidate place matched in step along "
         "the same route; the score is the mean over them (0: each frame alone, as in the seed)");
  p->Add("sequence-spacing-seconds", &o->sequence.min_spacing_seconds,
         "supporting frames are at least this far apart in capture time");
  p->Add("sequence-tolerance-seconds", &o->sequence.tolerance_seconds,
         "a supporting frame's place lies within this many seconds of where the route predicts");
  p->Add("sequence-max-age-seconds", &o->sequence.max_age_seconds,
         "earlier frames older than this do not support");
  p->Add("min-same-robot-gap-seconds", &o->recent_past.min_gap_seconds,
         "a robot's own places count only this many seconds (capture time) back (§5.7 step 6; "
         "the seed counts frames, which depends on the frame rate)");
  p->Add("away-seconds", &o->recent_past.away_seconds,
         "... and only once the robot's frames have not seen their view for this many seconds");
  p->Add("resume-within-seconds", &o->recent_past.resume_within_seconds,
         "after a server restart, a robot whose last stored place is at most this old (capture "
         "time) takes it (and those up to --away-seconds before it) as its recent views again; "
         "silent longer, it begins a new session (not in the seed)");
  p->Add("recent-past-descriptors", &o->recent_past.descriptors_per_frame,
         "strongest keypoints per frame compared with the robot's recent views");
  p->Add("recent-past-min-matches", &o->recent_past.min_matches_seen,
         "orientation-consistent ratio-test matches that mean a frame still sees a view");
  p->Add("recent-past-new-view-fraction", &o->recent_past.new_view_fraction,
         "a frame matching less than this fraction of its compared keypoints begins a new view");
  p->Add("duplicate-fraction", &o->recent_past.duplicate_fraction,
         "a frame sharing this fraction of its compared keypoints with the robot's last distinct "
         "frame shows nothing new: answered, not stored (1 stores every frame; not in the seed)");
  p->Add("geometric-verification", &o->loop.geometric_verification,
         "score places by fundamental-matrix RANSAC inliers (the seed counts matched "
         "landmarks, §5.7: false)");
  p->Add("orientation-tolerance", &o->loop.orientation_tolerance,
         "keep matches whose orientation change is this close to the place's usual one "
         "(degrees; 0 keeps all, as the seed)");
  p->Add("max-inliers-per-landmark", &o->loop.max_inliers_per_landmark,
         "a place scores at most this many inliers per landmark (0: no cap; not in the seed)");
  p->Add("max-inliers-per-cell", &o->loop.max_inliers_per_cell,
         "a place scores at most this many inliers per grid cell of the query frame (0: no cap)");
  p->Add("inlier-cell-size", &o->loop.inlier_cell_size, "grid cell size for that cap (pixels)");
  p->Add("ransac-threshold", &o->loop.ransac_threshold,
         "RANSAC epipolar distance in pixels of the processed frame");
  p->Add("max-verified-places", &o->loop.max_verified_places,
         "candidate places checked geometrically per frame");
  p->Add("localization-window-seconds", &o->loop.localization_window_seconds,
         "answer with the best place's neighbour (same robot, taken within this many seconds) "
         "whose features have the query's scale (0: the best place; not in the seed)");
  p->Add("localization-score-fraction", &o->loop.localization_score_fraction,
         "neighbours considered for localization score at least this fraction of the best");
  p->Add("min-scale-slope", &o->loop.min_scale_slope,
         "localize where the neighbours' log scale ratio crosses 0 when it changes this much "
         "per second");
  p->Add("noise-inliers", &o->loop.noise_inliers,
         "inliers a wrong place reaches by chance; weaker neighbours are not considered");
  p->Add("recognition", &o->mode,
         "default | seed: the seed's recognition (§5.7 steps 5-6: landmarks looked up by their "
         "objects alone, an object database whose objects keep the scenes they were seen at, a "
         "loop where about half the landmarks match and the landmark counts are close)");
  p->Add("seed-matched-fraction", &o->seed.min_matched_fraction,
         "--recognition seed: share of the frame's landmarks that must match a place (§5.7: "
         "around 50%)");
  p->Add("seed-count-ratio", &o->seed.min_count_ratio,
         "--recognition seed: the smaller landmark count is at least this share of the larger "
         "(§5.7: 'close'; the seed gives no number)");
  p->Add("object-classes", &o->classes.enabled,
         "classify the landmarks a frame stores with the object classifiers (seed Ch. 4); the "
         "map keeps each landmark's class and answers name the matched landmarks' classes");
  p->Add("object-models", &o->classes.models_dir,
         "object classifiers (placerec-train objects; default: the shipped models/objects/all)");
  p->Add("drop-movable", &o->classes.drop_movable,
         "leave landmarks of movable classes (car, body, face, bicycle, animals, ...) out of the "
         "map (seed §7.2.3; the seed's experiments store every landmark)");
  p->Add("min-movable-confidence", &o->classes.min_movable_confidence,
         "... when the classifier is at least this sure of the class (0..1)");
  p->Add("max-matches", &o->loop.max_matches, "places returned per frame");
  p->Add("loop-min-score", &o->loop.min_score,
         "a frame is a loop closure when its best place scores at least this");
  p->Add("thumbnail-width", &a.thumbnail_width,
         "every stored place keeps a JPEG thumbnail this wide (pixels; 0: none), the stored view "
         "alarms, tools and scene-change detection show and compare");
  p->Add("change-detection", &o->change.enabled,
         "at a recognised place, report objects that appeared or landmarks that disappeared in the "
         "view the frame shares with the place (seed §7.2.4); alarms go to PLACEREC_CHANGE");
  p->Add("change-min-inliers", &o->change.min_inliers_without_loop,
         "compare a frame that is no loop closure with its best place too when the geometric "
         "check kept at least this many inlier point pairs with it (0: only at loop closures)");
  p->Add("change-sensitivity", &o->change.sensitivity,
         "how readily a difference is a scene change, in (0, 1]: a region must differ by "
         "change-max-difference - s * (change-max-difference - change-min-difference) CIE Lab "
         "units");
  p->Add("change-min-difference", &o->change.min_difference,
         "Lab difference a change needs at sensitivity 1");
  p->Add("change-max-difference", &o->change.max_difference,
         "Lab difference a change needs at sensitivity 0");
  p->Add("change-min-area", &o->change.min_area,
         "smallest scene change reported, as a share of the frame's area");
  p->Add("change-min-points", &o->change.min_points,
         "verified point pairs that must fit one homography before a place is compared");
  p->Add("change-min-inlier-share", &o->change.min_inlier_share,
         "compare a place only when this share of the verified point pairs fits one homography "
         "(a view that a plane does not describe is not compared)");
  p->Add("change-min-class-confidence", &o->change.min_class_confidence,
         "name a change's object class only when the classifier is at least this sure of it "
         "(0.5: its boosted sum is positive); otherwise the change is an 'object'");
  p->Add("change-max-references", &o->change.max_references,
         "stored views compared with a frame: the matched place and its route neighbours among "
         "the matches (a pixel differs only when every view that sees it differs)");
  p->Add("change-reference-window", &o->change.reference_window_seconds,
         "route neighbours of the matched place compared too: the same robot's places within "
         "this many seconds of it");
  p->Add("change-support-radius", &o->change.support_radius,
         "compare only within this share of the frame width of a verified point that fits the "
         "homography (0: the whole mapped view)");
  p->Add("change-flow", &o->change.flow_alignment,
         "align the stored view to the frame by dense optical flow after the homography, so that "
         "the parallax of a scene that is no plane is not a change");
  p->Add("change-elsewhere", &o->change.max_elsewhere_similarity,
         "a region whose content shows in the stored view at about its scale (normalised "
         "correlation at least this) is the robot's motion, not a change (1: off)");
  p->Add("change-noise-spread", &o->change.noise_spread,
         "a change must also differ by the frame's median difference plus this many robust "
         "standard deviations");
  p->Add("change-grow-fraction", &o->change.grow_fraction,
         "a change grows from pixels above the threshold through neighbours above this fraction "
         "of it");
  p->Add("change-strong-spread", &o->change.strong_spread,
         "a region seeded above the threshold is a change candidate outright only when its "
         "strongest pixel differs by the threshold plus this many robust deviations of the "
         "view's difference, otherwise it must pass --change-weak-mean (a roughly aligned view "
         "makes regions that just cross the threshold; 0: every seeded region; the seed gives "
         "no value, docs/results.md 'Scene changes')");
  p->Add("change-weak-mean", &o->change.weak_mean,
         "a region with no pixel above the threshold is still a change candidate when it covers "
         "--change-weak-min-area of the frame and its mean difference reaches this share of the "
         "threshold and --change-weak-spread robust deviations above the frame's median "
         "difference: a large object whose colours lie near its background's (0: off; "
         "docs/results.md 'Scene changes')");
  p->Add("change-weak-spread", &o->change.weak_spread,
         "robust deviations above the frame's median difference a region needs for "
         "--change-weak-mean");
  p->Add("change-weak-min-area", &o->change.weak_min_area,
         "smallest share of the frame a region needs for --change-weak-mean");
  p->Add("change-segment-difference", &o->change.segment_difference,
         "a segment of the frame whose mean colour or mean local contrast differs from the "
         "stored view's under it by at least this many Lab units is a change (0: off, the "
         "default; 10 finds more objects whose colours lie near their background's and raises "
         "more false alarms, docs/results.md 'Scene changes')");
  p->Add("change-edge-band", &o->change.edge_band,
         "regions lying mostly within this share of the frame width of the shared view's edge "
         "are the robot's motion, not changes");
}

}  // namespace placerec
