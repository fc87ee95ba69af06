#include "common/training/boundary_training.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>

#include <opencv2/imgproc.hpp>

#include "common/organization/filter_bank.h"
#include "common/segmentation/superpixels.h"
#include "common/training/background_training.h"
#include "common/training/labelled_dataset.h"
#include "common/util/paths.h"
#include "common/util/progress.h"
#include "common/util/timer.h"

namespace placerec {
namespace {

// Sets *error to "<field> must not be empty" when `value` is.
bool CheckNotEmpty(const char* field, const std::string& value, std::string* error) {
  if (!value.empty()) return true;
  *error = std::string(field) + " must not be empty";
  return false;
}

struct PixelSample {
  cv::Mat features;  // rows of kBoundaryFeatures
  std::vector<int> labels;
  int images = 0;
  double crack_pixels = 0;  // summed over images

  int positives() const { return static_cast<int>(std::count(labels.begin(), labels.end(), 1)); }
};

// Draws up to `per_label` boundary and non-boundary pixels from the superpixel cracks of one
// image and appends their features to `sample`.
Status SampleImage(const BoundaryTrainingConfig& config, const std::string& id,
                   std::mt19937_64* rng, PixelSample* sample) {
  StatusOr<LabelledImage> image = ReadLabelledImage(config.dataset, id);
  if (!image.ok()) return image.status();
  if (image->objects.empty()) {
    return Status::InvalidArgument(config.dataset + ": image " + id +
                                   " has no objects/ layer to learn boundaries from");
  }
  const WorkingImage working =
      MakeWorkingImage(image->bgr, config.organizer.superpixels.working_width);
  const SceneSegmentation superpixels = ComputeSuperpixels(working, config.organizer.superpixels);
  const cv::Mat bank = ComputeFilterBank(working.lab);
  const cv::Mat objects = LayerAtSize(image->objects, working.bgr.size());
  // Pixels next to a pixel of another ground-truth object (both labelled).
  const cv::Mat boundaries = CrackPixels(objects, /*ignore_unlabelled=*/true);
  cv::Mat distance;
  if (cv::countNonZero(boundaries) == 0) {
    distance = cv::Mat(objects.size(), CV_32F, cv::Scalar(1e6f));
  } else {
    cv::Mat not_boundary = boundaries == 0;
    cv::distanceTransform(not_boundary, distance, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  }
  const cv::Mat cracks = CrackPixels(superpixels.labels);
  std::vector<cv::Point> positives;
  std::vector<cv::Point> negatives;
  for (int y = 0; y < cracks.rows; ++y) {
    const uint8_t* c = cracks.ptr<uint8_t>(y);
    const int* o = objects.ptr<int>(y);
    const float* d = distance.ptr<float>(y);
    for (int x = 0; x < cracks.cols; ++x) {
      if (c[x] == 0 || o[x] <= 0) continue;
      if (d[x] <= config.positive_distance) {
        positives.emplace_back(x, y);
      } else if (d[x] >= config.negative_distance) {
        negatives.emplace_back(x, y);
      }
    }
  }
  sample->crack_pixels += cv::countNonZero(cracks);
  ++sample->images;
  float row[kBoundaryFeatures];
  for (auto* points : {&positives, &negatives}) {
    std::shuffle(points->begin(), points->end(), *rng);
    const size_t n = std::min(points->size(), static_cast<size_t>(config.samples_per_image));
    for (size_t i = 0; i < n; ++i) {
      BoundaryPixelFeatures(bank, (*points)[i].x, (*points)[i].y, row);
      sample->features.push_back(cv::Mat(1, kBoundaryFeatures, CV_32F, row));
      sample->labels.push_back(points == &positives ? 1 : 0);
    }
  }
  return Status::Ok();
}

StatusOr<PixelSample> SampleImages(const BoundaryTrainingConfig& config,
                                   const std::vector<std::string>& ids, const char* what,
                                   std::mt19937_64* rng) {
  PixelSample sample;
  ProgressLine progress(ids.size(), kLogProgressEvery);
  for (size_t i = 0; i < ids.size(); ++i) {
    PLACEREC_RETURN_IF_ERROR(SampleImage(config, ids[i], rng, &sample));
    if (config.progress) {
      progress.Report(i + 1, "%s: pixels from %zu/%zu images: %d", what, i + 1, ids.size(),
                      sample.features.rows);
    }
  }
  return sample;
}

// Recall on object boundaries, on the rest, and their mean (balanced accuracy), in percent.
nlohmann::json Accuracy(const BoundaryModel& model, const PixelSample& sample) {
  int tp = 0;
  int tn = 0;
  const int positives = sample.positives();
  const int negatives = sample.features.rows - positives;
  for (int r = 0; r < sample.features.rows; ++r) {
    const bool boundary = model.Score(sample.features.ptr<float>(r)) > 0;
    tp += boundary && sample.labels[r];
    tn += !boundary && !sample.labels[r];
  }
  const double boundary_recall = positives > 0 ? 100.0 * tp / positives : 0.0;
  const double inside_recall = negatives > 0 ? 100.0 * tn / negatives : 0.0;
  return {{"images", sample.images},
          {"pixels", sample.features.rows},
          {"boundary_pixels", positives},
          {"boundary_recall", boundary_recall},
          {"inside_recall", inside_recall},
          {"balanced_accuracy", 0.5 * (boundary_recall + inside_recall)}};
}

}  // namespace

bool BoundaryTrainingConfig::Check(std::string* error) const {
  if (!CheckNotEmpty("dataset", dataset, error) || !CheckNotEmpty("split", split, error) ||
      !CheckNotEmpty("out", out, error)) {
    return false;
  }
  if (holdout < 0) {
    *error = "holdout must be at least 0, got " + std::to_string(holdout);
    return false;
  }
  if (samples_per_image < 1) {
    *error = "samples_per_image must be at least 1, got " + std::to_string(samples_per_image);
    return false;
  }
  if (!(positive_distance >= 0.0 && negative_distance > positive_distance)) {
    *error =
        "positive_distance and negative_distance must satisfy 0 <= positive_distance < "
        "negative_distance, got " +
        std::to_string(positive_distance) + " and " + std::to_string(negative_distance);
    return false;
  }
  return leave_out_fold.Check(error) && boost.Check(error) && organizer.Check(error);
}

StatusOr<nlohmann::json> TrainBoundaryModel(const BoundaryTrainingConfig& config) {
  std::string error;
  if (!config.boost.Check(&error) || !config.organizer.superpixels.Check(&error)) {
    return Status::InvalidArgument(error);
  }
  if (config.samples_per_image < 1 || config.holdout < 0 ||
      !(config.positive_distance >= 0 && config.negative_distance > config.positive_distance)) {
    return Status::InvalidArgument(
        "boundary training: samples_per_image >= 1, holdout >= 0 and 0 <= positive_distance < "
        "negative_distance");
  }
  if (config.out.empty()) return Status::InvalidArgument("boundary training needs --out");
  StatusOr<std::vector<std::string>> ids = ReadSplit(config.dataset, config.split);
  if (!ids.ok()) return ids.status();
  if (static_cast<int>(ids->size()) <= config.holdout) {
    return Status::InvalidArgument("the holdout leaves no training image");
  }
  std::vector<std::string> eval_ids;
  if (!config.eval_split.empty()) {
    StatusOr<std::vector<std::string>> eval = ReadSplit(config.dataset, config.eval_split);
    if (!eval.ok()) return eval.status();
    eval_ids = std::move(*eval);
  }
  if (!MakeDirectories(config.out))
    return Status::IoError("cannot create or write in " + config.out);

  Timer timer;
  std::mt19937_64 rng(config.seed);
  std::vector<std::string> train_ids;
  const size_t after_holdout = ids->size() - static_cast<size_t>(config.holdout);
  for (size_t i = 0; i < after_holdout; ++i) {
    if (config.leave_out_fold.empty() ||
        FoldOf(i, after_holdout, config.leave_out_fold.count) != config.leave_out_fold.index) {
      train_ids.push_back((*ids)[static_cast<size_t>(config.holdout) + i]);
    }
  }
  StatusOr<PixelSample> train = SampleImages(config, train_ids, "training", &rng);
  if (!train.ok()) return train.status();
  const int positives = train->positives();
  const int negatives = train->features.rows - positives;
  if (positives == 0 || negatives == 0) {
    return Status::InvalidArgument("training needs pixels on and off object boundaries");
  }
  const double sampling_seconds = timer.ElapsedMs() / 1000.0;
  // Both labels weigh alike.
  std::vector<float> weights(train->labels.size(), 1.0f);
  for (size_t r = 0; r < weights.size(); ++r) {
    if (train->labels[r]) weights[r] = static_cast<float>(negatives) / positives;
  }
  if (config.progress) {
    std::fprintf(stderr, "boosting on %d pixels (%d on object boundaries)\n", train->features.rows,
                 positives);
  }
  timer.Restart();
  const BoundaryModel model =
      BoundaryModel::Train(train->features, train->labels, weights, config.boost);
  const double boosting_seconds = timer.ElapsedMs() / 1000.0;

  nlohmann::json accuracy;
  accuracy["training"] = Accuracy(model, *train);
  if (config.holdout > 0) {
    const std::vector<std::string> held(ids->begin(), ids->begin() + config.holdout);
    StatusOr<PixelSample> sample = SampleImages(config, held, "held out", &rng);
    if (!sample.ok()) return sample.status();
    accuracy["held_out"] = Accuracy(model, *sample);
  }
  if (!eval_ids.empty()) {
    StatusOr<PixelSample> sample = SampleImages(config, eval_ids, config.eval_split.c_str(), &rng);
    if (!sample.ok()) return sample.status();
    accuracy[config.eval_split] = Accuracy(model, *sample);
  }
  PLACEREC_RETURN_IF_ERROR(model.Save(config.out));

  nlohmann::json manifest;
  manifest["format_version"] = BoundaryModel::kFormatVersion;
  manifest["created"] = TodayUtc();
  manifest["file"] = BoundaryModel::kFileName;
  if (!config.command_line.empty()) manifest["command"] = config.command_line;
  manifest["data"] = {{"dataset", std::filesystem::path(config.dataset).filename().string()},
                      {"split", config.split},
                      {"holdout_first_images", config.holdout},
                      {"left_out_fold", config.leave_out_fold.ToString()},
                      {"images", static_cast<int>(train_ids.size())},
                      {"eval_split", config.eval_split}};
  manifest["pixels"] = {
      {"samples_per_image", config.samples_per_image},
      {"positive_distance", config.positive_distance},
      {"negative_distance", config.negative_distance},
      {"crack_pixels_per_image", train->crack_pixels / std::max(1, train->images)},
      {"working_width", config.organizer.superpixels.working_width},
      {"fh_k", config.organizer.superpixels.k},
      {"fh_min_size", config.organizer.superpixels.min_size},
      {"fh_sigma", config.organizer.superpixels.sigma}};
  manifest["boost"] = {{"type", "gentle"},
                       {"weak_count", config.boost.weak_count},
                       {"max_depth", config.boost.max_depth},
                       {"weight_trim_rate", config.boost.weight_trim_rate},
                       {"features", kBoundaryFeatures}};
  manifest["accuracy"] = accuracy;
  manifest["seconds"] = {{"sampling", sampling_seconds}, {"boosting", boosting_seconds}};
  manifest["seed"] = config.seed;
  PLACEREC_RETURN_IF_ERROR(WriteManifest(config.out + "/boundary.json", manifest));
  return manifest;
}

}  // namespace placerec
