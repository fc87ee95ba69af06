#include "common/training/background_training.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <random>

#include <opencv2/core/persistence.hpp>

#include "common/organization/filter_bank.h"
#include "common/util/logging.h"
#include "common/util/paths.h"
#include "common/util/progress.h"
#include "common/util/timer.h"

namespace placerec {

std::string TodayUtc() {
  const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%d", std::gmtime(&now));
  return text;
}

Status WriteManifest(const std::string& path, const nlohmann::json& manifest) {
  std::ofstream out(path);
  out << manifest.dump(2) << "\n";
  out.close();
  if (!out) return Status::IoError("cannot write " + path);
  return Status::Ok();
}

std::vector<int> RegionLabels(const cv::Mat& regions, int n, const cv::Mat& gt_classes,
                              const ClassTable& table, double min_labelled_fraction,
                              std::vector<int>* majority_out) {
  CHECK_EQ(regions.type(), CV_32S);
  CHECK_EQ(gt_classes.type(), CV_32S);
  CHECK(regions.size() == gt_classes.size());
  std::vector<std::map<int, int>> counts(static_cast<size_t>(n));
  std::vector<int> area(static_cast<size_t>(n), 0);
  for (int y = 0; y < regions.rows; ++y) {
    const int* r = regions.ptr<int>(y);
    const int* g = gt_classes.ptr<int>(y);
    for (int x = 0; x < regions.cols; ++x) {
      if (r[x] < 0 || r[x] >= n) continue;
      ++area[r[x]];
      if (!table.IsUnlabelled(g[x])) ++counts[r[x]][g[x]];
    }
  }
  std::vector<int> labels(static_cast<size_t>(n), -1);
  if (majority_out != nullptr) majority_out->assign(static_cast<size_t>(n), -1);
  for (int i = 0; i < n; ++i) {
    int labelled = 0;
    int best = -1;
    int best_count = 0;
    for (const auto& [id, count] : counts[i]) {
      labelled += count;
      if (count > best_count) {
        best = id;
        best_count = count;
      }
    }
    if (area[i] == 0 || best < 0 || labelled < min_labelled_fraction * area[i]) continue;
    labels[i] = static_cast<int>(table.BackgroundClass(best));
    if (majority_out != nullptr) (*majority_out)[i] = best;
  }
  return labels;
}

void BackgroundAccuracy::Add(const cv::Mat& scores, const std::vector<float>& rivals,
                             const std::vector<int>& labels, const std::vector<int>& majority,
                             const std::vector<int>& areas, const ClassTable& table,
                             double threshold) {
  CHECK_EQ(scores.rows, static_cast<int>(labels.size()));
  CHECK_EQ(rivals.size(), labels.size());
  for (int r = 0; r < scores.rows; ++r) {
    const int label = labels[r];
    if (label < 0) continue;
    const float* s = scores.ptr<float>(r);
    const SegmentClass decided = BackgroundClassifier::Decide(s, threshold, rivals[r]);
    ++total;
    // Each binary classifier on its own: its boosted decision (> 0), whatever the threshold
    // of the five-way decision.
    for (int c = 0; c < kBackgroundClasses; ++c) {
      binary_correct[c] += (s[c] > 0.0f) == (label == c);
    }
    if (IsBackground(decided)) {
      ++called[static_cast<int>(decided)];
      called_pixels[static_cast<int>(decided)] += areas[r];
    }
    ++confusion[table.Name(majority[r])]
               [IsBackground(decided) ? static_cast<int>(decided) : kBackgroundClasses];
    if (label < kBackgroundClasses) {
      ++regions[label];
      correct[label] += static_cast<int>(decided) == label;
      pixels[label] += areas[r];
      if (static_cast<int>(decided) == label) correct_pixels[label] += areas[r];
    } else {
      ++structured_regions;
      structured_correct += decided == SegmentClass::kStructured;
    }
  }
}

nlohmann::json BackgroundAccuracy::ToJson() const {
  nlohmann::json out;
  out["regions"] = total;
  auto percent = [](int a, int b) { return b > 0 ? 100.0 * a / b : 0.0; };
  for (int c = 0; c < kBackgroundClasses; ++c) {
    nlohmann::json& j = out["classes"][SegmentClassName(BackgroundClassOf(c))];
    j["regions"] = regions[c];
    j["accuracy"] = percent(correct[c], regions[c]);  // recall of the five-way decision
    j["precision"] = percent(correct[c], called[c]);
    j["binary_accuracy"] = percent(binary_correct[c], total);
    j["pixel_accuracy"] = pixels[c] > 0 ? 100.0 * correct_pixels[c] / pixels[c] : 0.0;
    j["pixel_precision"] =
        called_pixels[c] > 0 ? 100.0 * correct_pixels[c] / called_pixels[c] : 0.0;
  }
  out["structured"]["regions"] = structured_regions;
  out["structured"]["accuracy"] = percent(structured_correct, structured_regions);
  for (const auto& [name, counts] : confusion) {
    nlohmann::json& row = out["decisions_by_true_class"][name];
    for (int c = 0; c <= kBackgroundClasses; ++c) {
      row[c < kBackgroundClasses ? SegmentClassName(BackgroundClassOf(c)) : "structured"] =
          counts[c];
    }
  }
  return out;
}

std::vector<int> RegionAreas(const cv::Mat& regions, int n) {
  std::vector<int> area(static_cast<size_t>(n), 0);
  for (int y = 0; y < regions.rows; ++y) {
    const int* r = regions.ptr<int>(y);
    for (int x = 0; x < regions.cols; ++x) {
      if (r[x] >= 0 && r[x] < n) ++area[r[x]];
    }
  }
  return area;
}

namespace {

// A dataset's name: its directory's (../shared/data/camvid -> camvid).
std::string DatasetName(const std::string& dir) {
  std::filesystem::path path(dir);
  if (!path.has_filename()) path = path.parent_path();  // a trailing slash
  return path.filename().string();
}

// The items joined by commas, each followed by `suffix`.
std::string JoinDatasets(const std::vector<std::string>& items, const std::string& suffix) {
  std::string text;
  for (const std::string& item : items) text += (text.empty() ? "" : ",") + item + suffix;
  return text;
}

// Sets *error to "<field> must not be empty" when `value` is.
bool CheckNotEmpty(const char* field, const std::string& value, std::string* error) {
  if (!value.empty()) return true;
  *error = std::string(field) + " must not be empty";
  return false;
}

// Ground-truth object ids as compact region ids 0..n-1 (pixels without an object: -1).
cv::Mat ObjectRegions(const cv::Mat& objects, int* n) {
  cv::Mat regions(objects.size(), CV_32S);
  std::map<int, int> ids;
  for (int y = 0; y < objects.rows; ++y) {
    const int* o = objects.ptr<int>(y);
    int* r = regions.ptr<int>(y);
    for (int x = 0; x < objects.cols; ++x) {
      if (o[x] <= 0) {
        r[x] = -1;
        continue;
      }
      const auto inserted = ids.emplace(o[x], static_cast<int>(ids.size()));
      r[x] = inserted.first->second;
    }
  }
  *n = static_cast<int>(ids.size());
  return regions;
}

int64_t FileSize(const std::string& path) {
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  return ec ? -1 : static_cast<int64_t>(size);
}

// The options TrainInto needs.
Status CheckTrainingOptions(const BackgroundTrainingConfig& config) {
  std::string error;
  if (!config.textons.Check(&error) || !config.boost.Check(&error) ||
      !config.organizer.Check(&error)) {
    return Status::InvalidArgument(error);
  }
  if (config.pixels_per_image < 1) {
    return Status::InvalidArgument("pixels_per_image must be at least 1");
  }
  return Status::Ok();
}

// The training images of `dataset`: the split without its first `holdout` images and the
// left-out fold.
StatusOr<std::vector<std::string>> TrainingIds(const BackgroundTrainingConfig& config,
                                               const std::string& dataset) {
  StatusOr<std::vector<std::string>> ids = ReadSplit(dataset, config.split);
  if (!ids.ok()) return ids.status();
  if (config.holdout < 0 || config.holdout >= static_cast<int>(ids->size())) {
    return Status::InvalidArgument(dataset + ": holdout must be in [0, " +
                                   std::to_string(ids->size()) + "), got " +
                                   std::to_string(config.holdout));
  }
  ids->erase(ids->begin(), ids->begin() + config.holdout);
  if (!config.leave_out_fold.empty()) {
    std::vector<std::string> kept;
    for (size_t i = 0; i < ids->size(); ++i) {
      if (FoldOf(i, ids->size(), config.leave_out_fold.count) != config.leave_out_fold.index) {
        kept.push_back((*ids)[i]);
      }
    }
    if (kept.empty()) {
      return Status::InvalidArgument(dataset + ": the left-out fold leaves no image");
    }
    *ids = std::move(kept);
  }
  return ids;
}

// One training dataset: its directory, class table, training images and which of its classes
// each structured classifier learns.
struct TrainingDataset {
  std::string dir;
  std::string name;  // the directory's name (stanford_background)
  ClassTable table;
  std::vector<std::string> ids;
  std::map<int, int> structured_index;  // dataset class id -> structured class index
};

// The structured classes' names: config.structured_classes in order, "all" standing for every
// labelled non-background class of the first dataset.
std::vector<std::string> StructuredNames(const BackgroundTrainingConfig& config,
                                         const ClassTable& first) {
  std::vector<std::string> names;
  auto add = [&names](const std::string& name) {
    if (std::find(names.begin(), names.end(), name) == names.end()) names.push_back(name);
  };
  for (const std::string& wanted : config.structured_classes) {
    if (wanted != "all") {
      add(wanted);
      continue;
    }
    for (const auto& [id, name] : first.names) {
      if (!first.IsUnlabelled(id) && !IsBackground(first.BackgroundClass(id))) add(name);
    }
  }
  return names;
}

}  // namespace

std::map<int, int> StructuredClassIndex(const std::vector<std::string>& names,
                                        const ClassTable& table) {
  std::map<int, int> index;
  const auto catch_all = std::find(names.begin(), names.end(), kCatchAllStructuredClass);
  bool has_catch_all_class = false;
  for (const auto& [id, name] : table.names)
    has_catch_all_class |= name == kCatchAllStructuredClass;
  for (const auto& [id, name] : table.names) {
    if (table.IsUnlabelled(id) || IsBackground(table.BackgroundClass(id))) continue;
    const auto it = std::find(names.begin(), names.end(), name);
    if (it != names.end()) {
      index[id] = static_cast<int>(it - names.begin());
    } else if (catch_all != names.end() && !has_catch_all_class) {
      index[id] = static_cast<int>(catch_all - names.begin());
    }
  }
  return index;
}

namespace {

// Reads every dataset's class table and training images and maps its classes to the structured
// classes; a structured class that no dataset has is an error.
StatusOr<std::vector<TrainingDataset>> ReadTrainingDatasets(const BackgroundTrainingConfig& config,
                                                            std::vector<std::string>* structured) {
  std::vector<TrainingDataset> datasets;
  for (const std::string& dir : config.datasets) {
    TrainingDataset dataset;
    dataset.dir = dir;
    dataset.name = DatasetName(dir);
    StatusOr<ClassTable> table = ReadClassTable(dir);
    if (!table.ok()) return table.status();
    if (table->empty()) {
      return Status::InvalidArgument(dir + " has no classes.txt: cannot label regions");
    }
    dataset.table = *table;
    StatusOr<std::vector<std::string>> ids = TrainingIds(config, dir);
    if (!ids.ok()) return ids.status();
    dataset.ids = *ids;
    datasets.push_back(std::move(dataset));
  }
  *structured = StructuredNames(config, datasets.front().table);
  std::vector<bool> found(structured->size(), false);
  for (TrainingDataset& dataset : datasets) {
    dataset.structured_index = StructuredClassIndex(*structured, dataset.table);
    for (const auto& [id, index] : dataset.structured_index) found[index] = true;
  }
  for (size_t j = 0; j < structured->size(); ++j) {
    if (!found[j]) {
      return Status::InvalidArgument("structured class '" + (*structured)[j] +
                                     "' is not a labelled, non-background class of " +
                                     JoinDatasets(config.datasets, "/classes.txt"));
    }
  }
  return datasets;
}

// Whether the evaluation split is given and present in `dataset`.
bool HasEvalSplit(const BackgroundTrainingConfig& config, const std::string& dataset) {
  return !config.eval_split.empty() && PathExists(dataset + "/" + config.eval_split + ".txt");
}

// The evaluation split is otherwise read only after the whole training: checks that every image
// it lists can be read.
Status CheckEvalSplit(const BackgroundTrainingConfig& config, const std::string& dataset) {
  if (!HasEvalSplit(config, dataset)) return Status::Ok();
  StatusOr<std::vector<std::string>> eval_ids = ReadSplit(dataset, config.eval_split);
  if (!eval_ids.ok()) return eval_ids.status();
  for (const std::string& id : *eval_ids) {
    const StatusOr<LabelledImage> image = ReadLabelledImage(dataset, id);
    if (!image.ok()) {
      return Status(image.status().code(), image.status().message() + " (listed in " + dataset +
                                               "/" + config.eval_split + ".txt, the --eval-split)");
    }
  }
  return Status::Ok();
}

// Filter-bank responses of `pixels_per_image` random pixels of every training image (the i-th
// image over all datasets, in order, seeded with seed + i), for the texton k-means.
StatusOr<cv::Mat> SamplePixels(const BackgroundTrainingConfig& config,
                               const std::vector<TrainingDataset>& datasets) {
  const int working_width = config.organizer.superpixels.working_width;
  std::vector<std::pair<const TrainingDataset*, const std::string*>> ids;
  for (const TrainingDataset& dataset : datasets) {
    for (const std::string& id : dataset.ids) ids.emplace_back(&dataset, &id);
  }
  cv::Mat pixel_samples;
  ProgressLine sampling_progress(ids.size(), kLogProgressEvery);
  for (size_t i = 0; i < ids.size(); ++i) {
    StatusOr<LabelledImage> image = ReadLabelledImage(ids[i].first->dir, *ids[i].second);
    if (!image.ok()) return image.status();
    const WorkingImage working = MakeWorkingImage(image->bgr, working_width);
    const cv::Mat features = ComputeFilterBank(working.lab);
    std::mt19937_64 rng(config.seed + i);
    std::uniform_int_distribution<int> row(0, features.rows - 1);
    std::uniform_int_distribution<int> col(0, features.cols - 1);
    cv::Mat samples(config.pixels_per_image, kTextonFeatureSize, CV_32F);
    for (int s = 0; s < config.pixels_per_image; ++s) {
      const float* f =
          features.ptr<float>(row(rng)) + static_cast<size_t>(col(rng)) * kTextonFeatureSize;
      std::copy(f, f + kTextonFeatureSize, samples.ptr<float>(s));
    }
    pixel_samples.push_back(samples);
    if (config.progress) sampling_progress.Report(i + 1, "filter bank %zu/%zu", i + 1, ids.size());
  }
  return pixel_samples;
}

// The labelled training regions: appearance rows, labels, structured class and weight of each.
struct RegionSample {
  cv::Mat samples;
  std::vector<int> labels;
  std::vector<int> structured;  // structured class index per sample, -1 none
  std::vector<float> weights;
  int superpixel_regions = 0;  // of the samples, how many are superpixels
};

// Appends the labelled regions of one image (`gt`: its classes at the working size).
void AppendRegions(const BackgroundTrainingConfig& config, const ClassTable& table,
                   const std::map<int, int>& structured_index, const cv::Mat& appearance,
                   const cv::Mat& regions, int n, const cv::Mat& gt, double fraction,
                   RegionSample* sample) {
  std::vector<int> majority;
  const std::vector<int> labels = RegionLabels(regions, n, gt, table, fraction, &majority);
  const std::vector<int> areas = RegionAreas(regions, n);
  for (int i = 0; i < n; ++i) {
    if (labels[i] < 0 || areas[i] < config.min_region_pixels) continue;
    sample->samples.push_back(appearance.row(i));
    sample->labels.push_back(labels[i]);
    const auto it = structured_index.find(majority[i]);
    sample->structured.push_back(it == structured_index.end() ? -1 : it->second);
    sample->weights.push_back(
        static_cast<float>(std::pow(static_cast<double>(areas[i]), config.area_weight_power)));
  }
}

// 2. Training regions of one dataset: superpixels (and ground-truth objects) with their
// majority class.
Status CollectRegions(const BackgroundTrainingConfig& config, const TrainingDataset& dataset,
                      const TextonAssigner& assigner, RegionSample* sample) {
  const int working_width = config.organizer.superpixels.working_width;
  const int stride = config.organizer.texton_stride;
  const std::vector<std::string>& ids = dataset.ids;
  const ClassTable& table = dataset.table;
  const std::map<int, int>& structured_index = dataset.structured_index;
  ProgressLine region_progress(ids.size(), kLogProgressEvery);
  for (size_t i = 0; i < ids.size(); ++i) {
    StatusOr<LabelledImage> image = ReadLabelledImage(dataset.dir, ids[i]);
    if (!image.ok()) return image.status();
    if (image->classes.empty()) continue;
    const WorkingImage working = MakeWorkingImage(image->bgr, working_width);
    const cv::Mat gt = LayerAtSize(image->classes, working.bgr.size());
    const cv::Mat features = ComputeFilterBank(working.lab);
    const TextonMap map = ComputeTextonMap(features, assigner, stride);
    const SceneSegmentation superpixels = ComputeSuperpixels(working, config.organizer.superpixels);
    const int before = sample->samples.rows;
    if (config.superpixel_regions) {
      AppendRegions(
          config, table, structured_index,
          RegionAppearance(superpixels.labels, superpixels.size(), map, features, assigner),
          superpixels.labels, superpixels.size(), gt, config.min_labelled_fraction, sample);
    }
    sample->superpixel_regions += sample->samples.rows - before;
    if (config.ground_truth_regions && !image->objects.empty()) {
      int n = 0;
      const cv::Mat objects = ObjectRegions(LayerAtSize(image->objects, working.bgr.size()), &n);
      AppendRegions(config, table, structured_index,
                    RegionAppearance(objects, n, map, features, assigner), objects, n, gt, 0.5,
                    sample);
    }
    if (config.progress) {
      region_progress.Report(i + 1, "%s regions %zu/%zu", dataset.name.c_str(), i + 1, ids.size());
    }
  }
  return Status::Ok();
}

// 3. Five binary Gentle AdaBoost classifiers (and one per structured class).
StatusOr<BackgroundClassifier> TrainClassifier(const BackgroundTrainingConfig& config,
                                               const RegionSample& regions,
                                               const std::vector<std::string>& structured_names,
                                               BackgroundTrainingSummary* boost_summary) {
  StatusOr<BackgroundClassifier> trained =
      BackgroundClassifier::Train(regions.samples, regions.labels, regions.weights, config.boost,
                                  boost_summary, structured_names, regions.structured);
  if (!trained.ok()) {
    return Status::InvalidArgument(
        "the training images (" + JoinDatasets(config.datasets, "/" + config.split + ".txt") +
        "): " + trained.status().message() +
        "; train on more images, or leave a structured class out (--structured-classes)");
  }
  return trained;
}

// The fixed check sample: the labelled ground-truth object regions of the evaluation split's
// first images.
struct CheckSample {
  cv::Mat features;
  std::vector<int> labels;
  std::vector<std::string> ids;
};

// 4. Accuracy on one dataset's evaluation split's ground-truth objects (seed Table 6.4
// protocol) and its superpixels, and the fixed check sample from its first images (when
// `check` is not null); null without an evaluation split.
StatusOr<nlohmann::json> Evaluate(const BackgroundTrainingConfig& config,
                                  const TrainingDataset& dataset, const TextonAssigner& assigner,
                                  const BackgroundClassifier& classifier, CheckSample* check) {
  nlohmann::json evaluation;
  if (!HasEvalSplit(config, dataset.dir)) return evaluation;
  const ClassTable& table = dataset.table;
  const int working_width = config.organizer.superpixels.working_width;
  const int stride = config.organizer.texton_stride;
  StatusOr<std::vector<std::string>> eval_ids = ReadSplit(dataset.dir, config.eval_split);
  if (!eval_ids.ok()) return eval_ids.status();
  BackgroundAccuracy objects_accuracy;
  BackgroundAccuracy superpixel_accuracy;
  // The decision segmentation makes: one-per-class when its options ask for it.
  auto rivals_of = [&](const cv::Mat& appearance) {
    return classifier.Rivals(appearance, config.organizer.one_per_class);
  };
  ProgressLine evaluation_progress(eval_ids->size(), kLogProgressEvery);
  for (size_t i = 0; i < eval_ids->size(); ++i) {
    StatusOr<LabelledImage> image = ReadLabelledImage(dataset.dir, (*eval_ids)[i]);
    if (!image.ok()) return image.status();
    if (image->classes.empty() || image->objects.empty()) continue;
    const WorkingImage working = MakeWorkingImage(image->bgr, working_width);
    const cv::Mat gt = LayerAtSize(image->classes, working.bgr.size());
    const cv::Mat features = ComputeFilterBank(working.lab);
    const TextonMap map = ComputeTextonMap(features, assigner, stride);
    int n = 0;
    const cv::Mat objects = ObjectRegions(LayerAtSize(image->objects, working.bgr.size()), &n);
    const cv::Mat appearance = RegionAppearance(objects, n, map, features, assigner);
    std::vector<int> majority;
    const std::vector<int> labels = RegionLabels(objects, n, gt, table, 0.5, &majority);
    objects_accuracy.Add(classifier.Scores(appearance), rivals_of(appearance), labels, majority,
                         RegionAreas(objects, n), table, config.organizer.background_threshold);
    const SceneSegmentation superpixels = ComputeSuperpixels(working, config.organizer.superpixels);
    std::vector<int> superpixel_majority;
    const std::vector<int> superpixel_labels =
        RegionLabels(superpixels.labels, superpixels.size(), gt, table,
                     config.min_labelled_fraction, &superpixel_majority);
    const cv::Mat superpixel_appearance =
        RegionAppearance(superpixels.labels, superpixels.size(), map, features, assigner);
    superpixel_accuracy.Add(
        classifier.Scores(superpixel_appearance), rivals_of(superpixel_appearance),
        superpixel_labels, superpixel_majority, RegionAreas(superpixels.labels, superpixels.size()),
        table, config.organizer.background_threshold);
    if (check != nullptr && static_cast<int>(i) < config.check_images) {
      check->ids.push_back((*eval_ids)[i]);
      for (int r = 0; r < n; ++r) {
        if (labels[r] < 0) continue;
        check->features.push_back(appearance.row(r));
        check->labels.push_back(labels[r]);
      }
    }
    if (config.progress) {
      evaluation_progress.Report(i + 1, "%s evaluation %zu/%zu", dataset.name.c_str(), i + 1,
                                 eval_ids->size());
    }
  }
  evaluation["split"] = config.eval_split;
  evaluation["ground_truth_objects"] = objects_accuracy.ToJson();
  evaluation["superpixels"] = superpixel_accuracy.ToJson();
  return evaluation;
}

// The check sample: regions, their labels and the decisions made now, written to
// check_sample.yml.gz; what the manifest says of it (null when the sample is empty).
StatusOr<nlohmann::json> WriteCheckSample(const BackgroundTrainingConfig& config,
                                          const BackgroundClassifier& classifier,
                                          const CheckSample& sample) {
  nlohmann::json check;
  if (sample.features.empty()) return check;
  const std::vector<SegmentClass> decided = classifier.Classify(
      sample.features, config.organizer.background_threshold, config.organizer.one_per_class);
  std::vector<int> decided_ids;
  int correct = 0;
  for (size_t r = 0; r < decided.size(); ++r) {
    decided_ids.push_back(static_cast<int>(decided[r]));
    correct += static_cast<int>(decided[r]) == sample.labels[r];
  }
  const double accuracy = static_cast<double>(correct) / static_cast<double>(decided.size());
  const std::string path = config.out + "/check_sample.yml.gz";
  try {
    cv::FileStorage fs(path, cv::FileStorage::WRITE);
    if (!fs.isOpened()) return Status::IoError("cannot write " + path);
    fs << "format_version" << 1;
    fs << "split" << config.eval_split;
    fs << "images" << sample.ids;
    fs << "features" << sample.features;
    fs << "labels" << sample.labels;
    fs << "decisions" << decided_ids;
    fs << "threshold" << config.organizer.background_threshold;
    fs << "one_per_class" << static_cast<int>(config.organizer.one_per_class);
    fs << "accuracy" << accuracy;
  } catch (const cv::Exception& e) {
    return Status::IoError("cannot write " + path + ": " + e.what());
  }
  check["file"] = "check_sample.yml.gz";
  check["dataset"] = DatasetName(config.datasets.front());
  check["split"] = config.eval_split;
  check["images"] = sample.ids;
  check["regions"] = static_cast<int>(decided.size());
  check["accuracy"] = 100.0 * accuracy;
  return check;
}

// The manifest's "classifiers": their files, boosting options, training regions and per-class
// counts.
nlohmann::json ClassifiersJson(const BackgroundTrainingConfig& config, const RegionSample& regions,
                               const std::vector<std::string>& structured_names,
                               const BackgroundTrainingSummary& boost_summary) {
  nlohmann::json classifiers;
  classifiers["files"] = {"background.yml"};
  classifiers["weak_count"] = config.boost.weak_count;
  classifiers["max_depth"] = config.boost.max_depth;
  classifiers["boost_type"] = "gentle";
  classifiers["weight_trim_rate"] = config.boost.weight_trim_rate;
  classifiers["max_negatives_per_positive"] = config.boost.max_negatives_per_positive;
  classifiers["regions"] = regions.samples.rows;
  classifiers["features"] = regions.samples.cols;
  classifiers["appearance_extras"] = config.appearance_extras;
  classifiers["superpixel_region_count"] = regions.superpixel_regions;
  classifiers["superpixel_regions"] = config.superpixel_regions;
  classifiers["ground_truth_regions"] = config.ground_truth_regions;
  classifiers["min_labelled_fraction"] = config.min_labelled_fraction;
  classifiers["min_region_pixels"] = config.min_region_pixels;
  classifiers["area_weight_power"] = config.area_weight_power;
  classifiers["structured_classes"] = structured_names;
  classifiers["decision"] = {{"threshold", config.organizer.background_threshold},
                             {"one_per_class", config.organizer.one_per_class}};
  for (int c = 0; c < kBackgroundClasses + static_cast<int>(structured_names.size()); ++c) {
    const std::string name = c < kBackgroundClasses ? SegmentClassName(BackgroundClassOf(c))
                                                    : structured_names[c - kBackgroundClasses];
    classifiers["files"].push_back("background_" + name + ".yml.gz");
    classifiers["per_class"][name] = {
        {"positives", boost_summary.positives[c]},
        {"negatives", boost_summary.negatives[c]},
        {"training_accuracy", 100.0 * boost_summary.training_accuracy[c]}};
  }
  return classifiers;
}

// How long each stage took, in seconds.
struct StageSeconds {
  double sampling = 0;
  double kmeans = 0;
  double regions = 0;
  double evaluation = 0;
};

// 5. The manifest; "total" seconds are `total_timer`'s now, and "file_bytes" lists config.out
// as it is now.
nlohmann::json BackgroundManifest(const BackgroundTrainingConfig& config,
                                  const std::vector<TrainingDataset>& datasets, int pixels,
                                  const RegionSample& regions,
                                  const std::vector<std::string>& structured_names,
                                  const BackgroundTrainingSummary& boost_summary,
                                  const nlohmann::json& evaluation, const nlohmann::json& check,
                                  const StageSeconds& seconds, const Timer& total_timer) {
  nlohmann::json manifest;
  manifest["format_version"] = 1;
  manifest["created"] = TodayUtc();
  if (!config.command_line.empty()) manifest["command"] = config.command_line;
  std::vector<std::string> names;
  int images = 0;
  nlohmann::json per_dataset;
  for (const TrainingDataset& dataset : datasets) {
    names.push_back(dataset.name);
    images += static_cast<int>(dataset.ids.size());
    per_dataset[dataset.name] = static_cast<int>(dataset.ids.size());
  }
  manifest["data"] = {{"dataset", JoinDatasets(names, "")},
                      {"split", config.split},
                      {"holdout_first_images", config.holdout},
                      {"left_out_fold", config.leave_out_fold.ToString()},
                      {"images", images}};
  if (datasets.size() > 1) manifest["data"]["images_per_dataset"] = per_dataset;
  manifest["textons"] = {{"file", "textons.yml"},
                         {"from_file", config.textons_file},
                         {"k", config.textons.k},
                         {"features", kTextonFeatureSize},
                         {"pixels_per_image", config.pixels_per_image},
                         {"pixels", pixels},
                         {"max_iterations", config.textons.max_iterations},
                         {"epsilon", config.textons.epsilon},
                         {"standardise", config.textons.standardise},
                         {"seed", config.textons.seed}};
  manifest["classifiers"] = ClassifiersJson(config, regions, structured_names, boost_summary);
  const SuperpixelOptions& sp = config.organizer.superpixels;
  manifest["regions"] = {{"working_width", sp.working_width},
                         {"fh_sigma", sp.sigma},
                         {"fh_k_640x480", sp.k},
                         {"fh_min_size_640x480", sp.min_size},
                         {"min_region_fraction", sp.min_region_fraction},
                         {"colour_merge_distance", sp.colour_merge_distance},
                         {"texton_stride", config.organizer.texton_stride}};
  // One dataset: its evaluation; several: the first's, and every dataset's by name.
  manifest["accuracy"] =
      datasets.size() > 1 ? evaluation.value(datasets.front().name, nlohmann::json()) : evaluation;
  if (datasets.size() > 1) manifest["accuracy_by_dataset"] = evaluation;
  manifest["check_sample"] = check;
  manifest["seconds"] = {{"filter_bank_sampling", seconds.sampling},
                         {"kmeans", seconds.kmeans},
                         {"regions", seconds.regions},
                         {"boosting", boost_summary.seconds},
                         {"evaluation", seconds.evaluation},
                         {"total", total_timer.ElapsedMs() / 1000.0}};
  nlohmann::json files;
  for (const auto& entry : std::filesystem::directory_iterator(config.out)) {
    const std::string name = entry.path().filename().string();
    if (name == "manifest.json" || name == "README.md") continue;
    files[name] = FileSize(entry.path().string());
  }
  manifest["file_bytes"] = files;
  return manifest;
}

// The whole training, writing into config.out (a fresh staging directory).
StatusOr<nlohmann::json> TrainInto(const BackgroundTrainingConfig& config) {
  PLACEREC_RETURN_IF_ERROR(CheckTrainingOptions(config));
  std::vector<std::string> structured_names;
  StatusOr<std::vector<TrainingDataset>> datasets = ReadTrainingDatasets(config, &structured_names);
  if (!datasets.ok()) return datasets.status();
  for (const TrainingDataset& dataset : *datasets) {
    PLACEREC_RETURN_IF_ERROR(CheckEvalSplit(config, dataset.dir));
  }
  Timer total_timer;
  StageSeconds seconds;

  // 1. Textons: k-means on pixels sampled from every training image, or the given dictionary.
  Timer timer;
  TextonModel textons;
  int pixels = 0;
  if (config.textons_file.empty()) {
    StatusOr<cv::Mat> pixel_samples = SamplePixels(config, *datasets);
    if (!pixel_samples.ok()) return pixel_samples.status();
    pixels = pixel_samples->rows;
    seconds.sampling = timer.ElapsedMs() / 1000.0;
    timer.Restart();
    if (config.progress) {
      std::fprintf(stderr, "k-means: %d pixels, k = %d\n", pixels, config.textons.k);
    }
    textons = TrainTextons(*pixel_samples, config.textons);
    seconds.kmeans = timer.ElapsedMs() / 1000.0;
  } else {
    StatusOr<TextonModel> loaded = LoadTextons(config.textons_file);
    if (!loaded.ok()) return loaded.status();
    if (loaded->size() != config.textons.k) {
      return Status::InvalidArgument(config.textons_file + " holds " +
                                     std::to_string(loaded->size()) + " textons, not --textons " +
                                     std::to_string(config.textons.k));
    }
    textons = *loaded;
  }
  PLACEREC_RETURN_IF_ERROR(SaveTextons(textons, config.out + "/textons.yml"));

  // 2. Training regions: superpixels (and ground-truth objects) with their majority class.
  timer.Restart();
  const TextonAssigner assigner(textons);
  RegionSample regions;
  for (const TrainingDataset& dataset : *datasets) {
    PLACEREC_RETURN_IF_ERROR(CollectRegions(config, dataset, assigner, &regions));
  }
  seconds.regions = timer.ElapsedMs() / 1000.0;
  if (config.progress) {
    std::fprintf(stderr, "boosting on %d regions (%d superpixels)\n", regions.samples.rows,
                 regions.superpixel_regions);
  }

  // 3. Five binary Gentle AdaBoost classifiers.
  if (!config.appearance_extras) {
    regions.samples = regions.samples.colRange(0, config.textons.k + 1).clone();
  }
  BackgroundTrainingSummary boost_summary;
  StatusOr<BackgroundClassifier> trained =
      TrainClassifier(config, regions, structured_names, &boost_summary);
  if (!trained.ok()) return trained.status();
  const BackgroundClassifier& classifier = *trained;
  PLACEREC_RETURN_IF_ERROR(classifier.Save(config.out));

  // 4. Accuracy on each dataset's evaluation split; the check sample from the first's.
  CheckSample check_sample;
  timer.Restart();
  nlohmann::json evaluation;
  for (const TrainingDataset& dataset : *datasets) {
    StatusOr<nlohmann::json> one =
        Evaluate(config, dataset, assigner, classifier,
                 &dataset == &datasets->front() ? &check_sample : nullptr);
    if (!one.ok()) return one.status();
    if (datasets->size() == 1) {
      evaluation = *one;
    } else {
      evaluation[dataset.name] = *one;
    }
  }
  seconds.evaluation = timer.ElapsedMs() / 1000.0;
  StatusOr<nlohmann::json> check = WriteCheckSample(config, classifier, check_sample);
  if (!check.ok()) return check.status();

  // 5. The manifest.
  nlohmann::json manifest =
      BackgroundManifest(config, *datasets, pixels, regions, structured_names, boost_summary,
                         evaluation, *check, seconds, total_timer);
  PLACEREC_RETURN_IF_ERROR(WriteManifest(config.out + "/manifest.json", manifest));
  return manifest;
}

}  // namespace

bool BackgroundTrainingConfig::Check(std::string* error) const {
  if (datasets.empty()) {
    *error = "datasets must not be empty";
    return false;
  }
  for (const std::string& dataset : datasets) {
    if (!CheckNotEmpty("datasets", dataset, error)) return false;
  }
  if (!CheckNotEmpty("split", split, error) || !CheckNotEmpty("out", out, error)) return false;
  if (pixels_per_image < 1) {
    *error = "pixels_per_image must be at least 1, got " + std::to_string(pixels_per_image);
    return false;
  }
  if (!(min_labelled_fraction >= 0.0 && min_labelled_fraction <= 1.0)) {
    *error =
        "min_labelled_fraction must be in [0, 1], got " + std::to_string(min_labelled_fraction);
    return false;
  }
  if (min_region_pixels < 1) {
    *error = "min_region_pixels must be at least 1, got " + std::to_string(min_region_pixels);
    return false;
  }
  if (holdout < 0) {
    *error = "holdout must be at least 0, got " + std::to_string(holdout);
    return false;
  }
  if (check_images < 0) {
    *error = "check_images must be at least 0, got " + std::to_string(check_images);
    return false;
  }
  if (!std::isfinite(area_weight_power)) {
    *error = "area_weight_power must be finite";
    return false;
  }
  for (const std::string& name : structured_classes) {
    if (name.empty()) {
      *error = "structured_classes must not hold an empty name";
      return false;
    }
  }
  return leave_out_fold.Check(error) && textons.Check(error) && boost.Check(error) &&
         organizer.Check(error);
}

StatusOr<nlohmann::json> TrainBackgroundModels(const BackgroundTrainingConfig& config) {
  namespace fs = std::filesystem;
  if (!MakeDirectories(config.out))
    return Status::IoError("cannot create or write in " + config.out);
  // Everything is written to a staging directory inside `out` and moved into place only when
  // the whole training has succeeded, so that a failed or interrupted run leaves the models
  // directory as it was (new textons beside old classifiers would load and be silently wrong).
  BackgroundTrainingConfig staged = config;
  staged.out = config.out + "/.training-" + std::to_string(getpid());
  std::error_code ec;
  fs::remove_all(staged.out, ec);
  if (!MakeDirectories(staged.out))
    return Status::IoError("cannot create or write in " + staged.out);
  StatusOr<nlohmann::json> manifest = TrainInto(staged);
  if (manifest.ok()) {
    // The manifest last: it describes the files beside it.
    std::vector<fs::path> files;
    for (const auto& entry : fs::directory_iterator(staged.out)) {
      if (entry.path().filename() != "manifest.json") files.push_back(entry.path());
    }
    files.push_back(fs::path(staged.out) / "manifest.json");
    for (const fs::path& file : files) {
      fs::rename(file, fs::path(config.out) / file.filename(), ec);
      if (ec) {
        manifest = Status::IoError("cannot move " + file.string() + " into " + config.out + ": " +
                                   ec.message());
        break;
      }
    }
  }
  fs::remove_all(staged.out, ec);
  if (manifest.ok()) {
    // Models trained on these classifiers' scores (grouping) or beside them (boundary) were not
    // replaced: a grouping model's semantic features read the old classes.
    for (const char* later : {"grouping.yml.gz", "boundary.yml.gz"}) {
      if (fs::exists(fs::path(config.out) / later, ec)) {
        LOG(WARNING) << config.out << "/" << later
                     << " was trained with the background classifiers just replaced: retrain it "
                        "(placerec-train boundary, then grouping, --out "
                     << config.out << "; models/README.md)";
      }
    }
  }
  return manifest;
}

}  // namespace placerec
