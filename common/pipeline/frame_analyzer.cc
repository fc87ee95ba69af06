#include "common/pipeline/frame_analyzer.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include <opencv2/imgproc.hpp>

#include "common/organization/filter_bank.h"
#include "common/util/logging.h"
#include "common/util/stage.h"

namespace placerec {

SceneSegmentation SuperpixelSegmenter::Segment(const WorkingImage& image, cv::Mat* filter_bank,
                                               TextonMap* textons) const {
  if (filter_bank != nullptr) filter_bank->release();
  if (textons != nullptr) *textons = TextonMap();
  return ComputeSuperpixels(image, options_);
}

bool AnalyzerOptions::Check(std::string* error) const {
  if (max_image_width != 0 && max_image_width < 64) {
    *error = "max_image_width must be 0 (keep) or at least 64 pixels";
    return false;
  }
  if (small_frame_width < 0 || upscaled_width < 64 || upscaled_width > 4096 ||
      small_frame_width > upscaled_width) {
    *error =
        "small_frame_width must be in [0, upscaled_width] (0: keep small frames) and "
        "upscaled_width in [64, 4096] pixels";
    return false;
  }
  if (min_frame_chroma < 0) {
    *error = "min_frame_chroma must be non-negative";
    return false;
  }
  if (thumbnail_width < 0 || thumbnail_width > 1024 || preview_width < 0 || preview_width > 4096) {
    *error = "thumbnail_width must be in [0, 1024] and preview_width in [0, 4096] pixels";
    return false;
  }
  return features.Check(error) && superpixels.Check(error) && organization.Check(error) &&
         colour.Check(error) && objects.Check(error);
}

StatusOr<std::unique_ptr<Segmenter>> MakeSegmenter(const AnalyzerOptions& options) {
  std::unique_ptr<Segmenter> segmenter;
  if (options.segmentation == SegmentationMethod::kSuperpixels) {
    segmenter = std::make_unique<SuperpixelSegmenter>(options.superpixels);
    return segmenter;
  }
  StatusOr<SceneOrganizer> organizer = SceneOrganizer::Create(options.organization);
  if (!organizer.ok()) {
    // The command that trains the file the message names (models/README.md).
    const std::string& message = organizer.status().message();
    const char* command = message.find("grouping") != std::string::npos   ? "grouping"
                          : message.find("boundary") != std::string::npos ? "boundary"
                                                                          : "background";
    return Status(organizer.status().code(),
                  "Perceptual Organization segmentation: " + message +
                      " (restore the shipped models (git checkout models) or train it with "
                      "placerec-train " +
                      command +
                      ", point --models-dir or PLACEREC_MODELS at good models, or use "
                      "--segmentation superpixels)");
  }
  segmenter = std::make_unique<OrganizationSegmenter>(std::move(*organizer));
  return segmenter;
}

int ProcessedWidthCap(cv::Size size, int max_image_width) {
  if (max_image_width <= 0 || size.width <= 0 || size.height <= 0) return 0;
  // The width whose frame holds max_image_width^2 pixels at the frame's aspect ratio, bounded
  // in double: for a cap near INT_MAX it exceeds every int.
  const double budget = static_cast<double>(max_image_width) * max_image_width;
  const double affordable = std::floor(std::sqrt(budget * size.width / size.height));
  return static_cast<int>(std::max(1.0, std::min<double>(max_image_width, affordable)));
}

FrameAnalyzer::FrameAnalyzer(const AnalyzerOptions& options, std::unique_ptr<Segmenter> segmenter)
    : options_(options), segmenter_(std::move(segmenter)) {
  if (!segmenter_) {
    StatusOr<std::unique_ptr<Segmenter>> made = MakeSegmenter(options_);
    CHECK(made.ok()) << made.status().message();
    segmenter_ = std::move(*made);
  }
}

namespace {

double MeanChroma(const cv::Mat& lab) {
  double sum = 0;
  for (int y = 0; y < lab.rows; ++y) {
    const cv::Vec3f* row = lab.ptr<cv::Vec3f>(y);
    for (int x = 0; x < lab.cols; ++x) sum += std::hypot(row[x][1], row[x][2]);
  }
  return lab.total() > 0 ? sum / static_cast<double>(lab.total()) : 0.0;
}

}  // namespace

FrameObservation FrameAnalyzer::Analyze(const cv::Mat& bgr) const {
  CHECK_EQ(bgr.type(), CV_8UC3);
  FrameObservation observation;
  observation.original_size = bgr.size();
  Timer timer;
  std::optional<ScopedStage> stage(std::in_place, "resize");
  const cv::Mat frame =
      FitWidth(bgr, bgr.cols < options_.small_frame_width ? options_.upscaled_width : 0,
               ProcessedWidthCap(bgr.size(), options_.max_image_width), &observation.scale);
  observation.processed_size = frame.size();
  // Pictures `width` wide, at most twice as tall (a tall, narrow frame gets a narrower one).
  const auto scaled_to = [&frame](int width) {
    cv::Mat small;
    if (width <= 0) return small;
    int height = std::max(
        1, static_cast<int>(std::lround(static_cast<double>(frame.rows) * width / frame.cols)));
    if (height > 2 * width) {
      height = 2 * width;
      width = std::max(
          1, static_cast<int>(std::lround(static_cast<double>(frame.cols) * height / frame.rows)));
    }
    cv::resize(frame, small, cv::Size(width, height), 0, 0, cv::INTER_AREA);
    return small;
  };
  observation.thumbnail = scaled_to(options_.thumbnail_width);
  observation.preview = scaled_to(options_.preview_width);
  observation.timings.emplace_back("resize", timer.ElapsedMs());

  timer.Restart();
  stage.emplace("sift");
  observation.features = ExtractFeatures(frame, options_.features);
  observation.timings.emplace_back("sift", timer.ElapsedMs());

  timer.Restart();
  stage.emplace("segmentation");
  const WorkingImage working = MakeWorkingImage(frame, segmenter_->working_width());
  observation.segmentation =
      segmenter_->Segment(working, options_.keep_filter_bank ? &observation.filter_bank : nullptr,
                          options_.keep_filter_bank ? &observation.textons : nullptr);
  if (options_.keep_filter_bank && observation.filter_bank.empty()) {
    observation.filter_bank = ComputeFilterBank(working.lab);
  }
  observation.timings.emplace_back("segmentation", timer.ElapsedMs());

  timer.Restart();
  stage.emplace("objects");
  cv::Mat h_valid;
  const cv::Mat h = ColourInvariantH(working.bgr, options_.colour, &h_valid);
  observation.colourless = MeanChroma(working.lab) < options_.min_frame_chroma;
  observation.objects = ExtractObjects(observation.features, observation.segmentation, h, h_valid,
                                       options_.colour.max_abs_h, options_.objects);
  if (observation.colourless) {
    for (SceneObject& object : observation.objects) object.colour = ColourSignature();
  }
  observation.timings.emplace_back("objects", timer.ElapsedMs());
  return observation;
}

}  // namespace placerec
