// Pipeline steps 1-6 for one frame, without any state: scale, SIFT, segmentation, colour
// invariant and objects. Segmentation is pluggable: Perceptual Organization (seed Ch. 3) by
// default, superpixels alone as the lighter alternative, with nothing downstream changing.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "common/features/features.h"
#include "common/image/image.h"
#include "common/objects/objects.h"
#include "common/organization/scene_organizer.h"
#include "common/segmentation/segmentation.h"
#include "common/segmentation/superpixels.h"
#include "common/util/status.h"
#include "common/util/timer.h"

namespace placerec {

// Produces the segmentation objects are cut from.
class Segmenter {
 public:
  virtual ~Segmenter() = default;
  // `filter_bank` (may be null) receives the image's 20-d filter bank (ComputeFilterBank,
  // CV_32FC(20)) and `textons` (may be null) its texton map when the segmenter computes them,
  // and are left empty otherwise.
  virtual SceneSegmentation Segment(const WorkingImage& image, cv::Mat* filter_bank = nullptr,
                                    TextonMap* textons = nullptr) const = 0;
  virtual std::string name() const = 0;
  // Width of the working image Segment expects (pixels; 0: the frame's own).
  virtual int working_width() const = 0;
};

// Improved superpixels (seed §3.6) as the segmentation, every segment structured.
class SuperpixelSegmenter : public Segmenter {
 public:
  explicit SuperpixelSegmenter(const SuperpixelOptions& options) : options_(options) {}
  SceneSegmentation Segment(const WorkingImage& image, cv::Mat* filter_bank = nullptr,
                            TextonMap* textons = nullptr) const override;
  std::string name() const override { return "superpixels"; }
  int working_width() const override { return options_.working_width; }

 private:
  SuperpixelOptions options_;
};

// Perceptual Organization (seed Ch. 3): superpixels, background identification, grouping of the
// structured parts into objects. Background regions keep their class, so that objects.h can
// leave them out of the landmarks.
class OrganizationSegmenter : public Segmenter {
 public:
  explicit OrganizationSegmenter(SceneOrganizer organizer) : organizer_(std::move(organizer)) {}
  SceneSegmentation Segment(const WorkingImage& image, cv::Mat* filter_bank = nullptr,
                            TextonMap* textons = nullptr) const override {
    return organizer_.Segment(image, nullptr, filter_bank, textons);
  }
  std::string name() const override { return "organization"; }
  int working_width() const override { return organizer_.options().superpixels.working_width; }

 private:
  SceneOrganizer organizer_;
};

enum class SegmentationMethod {
  kOrganization,  // Perceptual Organization (seed Ch. 3), the default
  kSuperpixels,   // improved superpixels alone (seed §3.6), coarser, every segment structured
};

struct AnalyzerOptions {
  // Frames wider than this, or of more pixels than its square, are scaled down (pixels) before
  // SIFT (ProcessedWidthCap); 0 keeps the frame's size, as the seed, which ran on its camera's
  // frames. 960: the widest frames the defaults were chosen on (Gardens Point), so that an HD
  // camera or a phone's photo is processed as those frames were, at their cost.
  int max_image_width = 960;
  // Frames narrower than small_frame_width (a cheap camera's 160 or 320 px) are scaled up
  // (bicubic) to upscaled_width before SIFT and segmentation: they then yield keypoints at the
  // scales the seed's thresholds assume (objects of more than 8 keypoints, seed §5.3;
  // superpixel sizes, §3.6) instead of a few dozen per frame. Not in the seed, which ran on
  // full-size frames; small_frame_width 0 keeps small frames as they are. max_image_width wins
  // where the two disagree.
  int small_frame_width = 400;
  int upscaled_width = 640;
  FeatureOptions features;
  SegmentationMethod segmentation = SegmentationMethod::kOrganization;
  // kOrganization: the initial partition, models and grouping parameters (the recognition
  // preset: the seed's grouping without the learned merging that `placerec-eval segment` uses).
  SceneOrganizerOptions organization = SceneOrganizerOptions::ForRecognition();
  // kSuperpixels: superpixels serve as the objects, so they are four times coarser than the
  // seed's initial partition (k 1200 instead of 300 at 640x480): segments of that size hold
  // enough keypoints to be matched as objects.
  SuperpixelOptions superpixels = [] {
    SuperpixelOptions o;
    o.k = 1200.0;
    return o;
  }();
  ColourInvariantOptions colour;
  // Background segments are objects too when textured (more than 8 keypoints, like any object):
  // sky and plain road hold too few keypoints to qualify, a textured wall, floor or hedge does.
  // One default for every place: indoors the background classes cover most of what a corridor
  // shows. The seed keeps background out of the landmarks (§3.7, §5.7 step 3).
  ObjectOptions objects = [] {
    ObjectOptions o;
    o.include_background = true;
    return o;
  }();
  // A frame whose mean chroma (CIE Lab sqrt(a^2 + b^2)) is below this carries no colour (a
  // grey-level camera, seen at night): its objects get no colour signature, so the colour
  // filter lets them through instead of calling everything grey.
  double min_frame_chroma = 1.0;
  // Keep the working image's filter bank in the observation (object classification reads it);
  // computed when the segmenter does not compute one (superpixels).
  bool keep_filter_bank = false;
  // Width of the place thumbnail kept with every stored place (pixels; the stored view that
  // alarms, matches, tools and scene-change detection use, seed §7.2.4). 0 keeps none (and
  // turns scene-change detection off for the places stored meanwhile).
  int thumbnail_width = 160;
  // Width of the frame picture a scene-change alarm shows (pixels; 0: none).
  int preview_width = 320;

  bool Check(std::string* error) const;
};

struct FrameObservation {
  cv::Size original_size;   // pixels of the decoded frame
  cv::Size processed_size;  // after small-frame upscaling and max_image_width
  double scale = 1.0;       // processed / original
  Features features;        // keypoints in processed pixels
  SceneSegmentation segmentation;
  // The working image's filter bank (CV_32FC(20), ComputeFilterBank) for object classification:
  // the segmentation's own, or computed when keep_filter_bank asks for it.
  cv::Mat filter_bank;
  // The segmentation's texton map of that filter bank (kept with it; empty when the segmenter
  // computes none): classification reads its ids instead of assigning them again. Whoever
  // replaces filter_bank must replace or clear this too.
  TextonMap textons;
  std::vector<SceneObject> objects;  // boxes in processed pixels
  bool colourless = false;
  // The processed frame scaled to thumbnail_width and preview_width (BGR; empty when 0).
  cv::Mat thumbnail;
  cv::Mat preview;
  StageTimings timings;  // milliseconds per stage
};

// The segmenter `options.segmentation` names; kOrganization loads the trained models
// (options.organization.models_dir) and fails with a message saying what is missing.
StatusOr<std::unique_ptr<Segmenter>> MakeSegmenter(const AnalyzerOptions& options);

// The widest a frame of `size` is processed under `max_image_width` (0: no bound): at most
// max_image_width wide and max_image_width^2 pixels, so that a portrait or tall frame costs no
// more than a square one at the cap.
int ProcessedWidthCap(cv::Size size, int max_image_width);

class FrameAnalyzer {
 public:
  // When `segmenter` is null, MakeSegmenter(options) builds it; a failure to load the models is
  // then fatal, so callers that want to report it call MakeSegmenter themselves.
  explicit FrameAnalyzer(const AnalyzerOptions& options,
                         std::unique_ptr<Segmenter> segmenter = nullptr);

  // Thread-safe; `bgr` is a decoded 8-bit BGR frame.
  FrameObservation Analyze(const cv::Mat& bgr) const;

  const AnalyzerOptions& options() const { return options_; }
  const Segmenter& segmenter() const { return *segmenter_; }

 private:
  AnalyzerOptions options_;
  std::unique_ptr<Segmenter> segmenter_;
};

}  // namespace placerec
