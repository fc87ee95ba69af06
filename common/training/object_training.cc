#include "common/training/object_training.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <map>
#include <random>
#include <set>

#include <unistd.h>

#include <opencv2/imgproc.hpp>

#include "common/image/image.h"
#include "common/organization/filter_bank.h"
#include "common/organization/scene_organizer.h"
#include "common/training/background_training.h"
#include "common/util/paths.h"
#include "common/util/progress.h"
#include "common/util/timer.h"

namespace placerec {

namespace {

// One ground-truth object of an image: its id and majority class.
struct Segment {
  int object = 0;
  int class_id = 0;
};

// The objects of one labelled image that pass `options` (and whose class is not excluded).
std::vector<Segment> FindSegments(const LabelledImage& image, const ClassTable& table,
                                  const std::set<int>& excluded,
                                  const TruthSegmentOptions& options) {
  const cv::Mat objects = LayerAtSize(image.objects, image.bgr.size());
  const cv::Mat classes = LayerAtSize(image.classes, image.bgr.size());
  std::map<int, std::map<int, int>> counts;  // object -> class -> pixels
  std::map<int, int> areas;
  for (int y = 0; y < objects.rows; ++y) {
    const int* o = objects.ptr<int>(y);
    const int* c = classes.ptr<int>(y);
    for (int x = 0; x < objects.cols; ++x) {
      if (o[x] <= 0) continue;
      ++areas[o[x]];
      if (table.names.count(c[x]) && !table.IsUnlabelled(c[x])) ++counts[o[x]][c[x]];
    }
  }
  std::vector<Segment> segments;
  for (const auto& [object, area] : areas) {
    if (area < options.min_object_pixels) continue;
    const auto it = counts.find(object);
    if (it == counts.end()) continue;
    int best = -1;
    int best_count = 0;
    int labelled = 0;
    for (const auto& [class_id, count] : it->second) {
      labelled += count;
      if (count > best_count) {
        best = class_id;
        best_count = count;
      }
    }
    if (best < 0 || labelled < options.min_labelled_fraction * area || excluded.count(best)) {
      continue;
    }
    segments.push_back({object, best});
  }
  return segments;
}

// Removes a directory tree when it goes out of scope (the staging directory, on every return).
struct RemoveOnExit {
  std::string path;
  ~RemoveOnExit() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
};

std::set<int> ExcludedIds(const ClassTable& table, const std::vector<std::string>& exclude) {
  std::set<int> ids;
  for (const auto& [id, name] : table.names) {
    if (std::find(exclude.begin(), exclude.end(), name) != exclude.end()) ids.insert(id);
  }
  return ids;
}

}  // namespace

bool TruthSegmentOptions::Check(std::string* error) const {
  if (min_object_pixels < 1) {
    *error = "min_object_pixels must be at least 1, got " + std::to_string(min_object_pixels);
    return false;
  }
  if (!(min_labelled_fraction >= 0.0 && min_labelled_fraction <= 1.0)) {
    *error = "min_labelled_fraction must be in [0, 1]";
    return false;
  }
  if (max_segments_per_class < 0) {
    *error = "max_segments_per_class must be at least 0";
    return false;
  }
  return description.Check(error);
}

StatusOr<DescribedSegments> DescribeTruthSegments(const std::string& dataset,
                                                  const std::string& split, const ClassTable& table,
                                                  const TextonAssigner& textons,
                                                  const std::vector<std::string>& exclude,
                                                  const TruthSegmentOptions& options,
                                                  bool progress) {
  return DescribeSegmentsOf(dataset, split, table, textons, exclude, options, progress, {});
}

StatusOr<DescribedSegments> DescribeSegmentsOf(
    const std::string& dataset, const std::string& split, const ClassTable& table,
    const TextonAssigner& textons, const std::vector<std::string>& exclude,
    const TruthSegmentOptions& options, bool progress,
    const std::function<cv::Mat(const LabelledImage&)>& objects_of) {
  std::string error;
  if (!options.Check(&error)) return Status::InvalidArgument(error);
  if (table.empty()) return Status::InvalidArgument(dataset + " has no classes.txt");
  for (const std::string& name : exclude) {
    bool known = false;
    for (const auto& entry : table.names) known = known || entry.second == name;
    if (!known) return Status::InvalidArgument("no class '" + name + "' in " + dataset);
  }
  StatusOr<std::vector<std::string>> ids = ReadSplit(dataset, split);
  if (!ids.ok()) return ids.status();
  if (ids->empty()) return Status::InvalidArgument(dataset + "/" + split + ".txt lists no images");
  const std::set<int> excluded = ExcludedIds(table, exclude);

  // 1. The segments of every image (layers only), then the per-class subsample.
  std::vector<std::vector<Segment>> per_image(ids->size());
  std::vector<cv::Mat> found_objects(objects_of ? ids->size() : 0);  // objects_of's layers
  std::map<int, std::vector<std::pair<size_t, size_t>>> by_class;    // class -> (image, segment)
  ProgressLine listing(ids->size(), kLogProgressEvery);
  for (size_t i = 0; i < ids->size(); ++i) {
    StatusOr<LabelledImage> image = ReadLabelledImage(dataset, (*ids)[i]);
    if (!image.ok()) return image.status();
    if ((!objects_of && image->objects.empty()) || image->classes.empty()) {
      return Status::InvalidArgument(dataset + ": image " + (*ids)[i] +
                                     " lacks objects/ or classes/ ground truth");
    }
    if (objects_of) {
      found_objects[i] = objects_of(*image);
      image->objects = found_objects[i];
    }
    per_image[i] = FindSegments(*image, table, excluded, options);
    for (size_t s = 0; s < per_image[i].size(); ++s) {
      by_class[per_image[i][s].class_id].push_back({i, s});
    }
    if (progress) listing.Report(i + 1, "listing segments: image %zu/%zu", i + 1, ids->size());
  }
  std::vector<std::vector<bool>> keep(ids->size());
  for (size_t i = 0; i < ids->size(); ++i) keep[i].assign(per_image[i].size(), true);
  if (options.max_segments_per_class > 0) {
    std::mt19937_64 random(options.seed);
    for (auto& [class_id, members] : by_class) {
      if (static_cast<int>(members.size()) <= options.max_segments_per_class) continue;
      std::shuffle(members.begin(), members.end(), random);
      for (size_t m = options.max_segments_per_class; m < members.size(); ++m) {
        keep[members[m].first][members[m].second] = false;
      }
    }
  }

  // 2. Descriptions, one filter bank per image.
  DescribedSegments out;
  const int size = ObjectDescriptionSize(textons.size());
  std::vector<float> rows;
  ProgressLine describing(ids->size(), kLogProgressEvery);
  for (size_t i = 0; i < ids->size(); ++i) {
    const bool any = std::find(keep[i].begin(), keep[i].end(), true) != keep[i].end();
    if (any) {
      StatusOr<LabelledImage> image = ReadLabelledImage(dataset, (*ids)[i]);
      if (!image.ok()) return image.status();
      const cv::Mat objects =
          LayerAtSize(objects_of ? found_objects[i] : image->objects, image->bgr.size());
      const cv::Mat bank = ComputeFilterBank(ToLab(image->bgr));
      for (size_t s = 0; s < per_image[i].size(); ++s) {
        if (!keep[i][s]) continue;
        const Segment& segment = per_image[i][s];
        const cv::Mat mask = objects == segment.object;
        StatusOr<ObjectDescription> description =
            DescribeObjectInFeatures(bank, mask, textons, options.description);
        if (!description.ok()) {
          return Status::InvalidArgument((*ids)[i] + " object " + std::to_string(segment.object) +
                                         ": " + description.status().message());
        }
        const std::vector<float> values = description->Concatenated();
        CHECK_EQ(static_cast<int>(values.size()), size);
        rows.insert(rows.end(), values.begin(), values.end());
        out.class_ids.push_back(segment.class_id);
        out.images.push_back((*ids)[i]);
        out.objects.push_back(segment.object);
        out.boxes.push_back(cv::boundingRect(mask));
      }
      ++out.images_read;
    }
    if (progress) {
      describing.Report(i + 1, "describing segments: image %zu/%zu, %zu segments", i + 1,
                        ids->size(), out.class_ids.size());
    }
  }
  out.features = cv::Mat(static_cast<int>(out.class_ids.size()), size, CV_32F);
  if (!rows.empty()) std::copy(rows.begin(), rows.end(), out.features.ptr<float>());
  return out;
}

const std::vector<ObjectModelVariant>& ObjectModelVariants() {
  static const std::vector<ObjectModelVariant> variants = {
      {"all", {"appearance", "parts_layout", "shape"}, true},
      {"appearance", {"appearance"}, true},
      {"appearance_parts", {"appearance", "parts_layout"}, true},
      {"appearance_shape", {"appearance", "shape"}, true},
      {"full", {"appearance", "parts_layout", "shape"}, false},
  };
  return variants;
}

std::vector<FeatureGroup> VariantGroups(const ObjectModelVariant& variant, int k,
                                        int parts_layout_candidates) {
  std::vector<FeatureGroup> groups;
  for (const FeatureGroup& group : DescriptionGroups(k, parts_layout_candidates)) {
    if (std::find(variant.groups.begin(), variant.groups.end(), group.name) !=
        variant.groups.end()) {
      groups.push_back(group);
    }
  }
  return groups;
}

bool ObjectTrainingConfig::Check(std::string* error) const {
  if (dataset.empty() || split.empty() || out.empty()) {
    *error = "dataset, split and out must not be empty";
    return false;
  }
  if (min_class_segments < classifier.selection.folds) {
    *error = "min_class_segments must be at least the selection's folds (" +
             std::to_string(classifier.selection.folds) + ")";
    return false;
  }
  return segments.Check(error) && classifier.Check(error);
}

StatusOr<nlohmann::json> TrainObjectModels(const ObjectTrainingConfig& config) {
  std::string error;
  if (!config.Check(&error)) return Status::InvalidArgument(error);
  Timer total;
  if (!PathExists(config.dataset))
    return Status::NotFound("no dataset directory " + config.dataset);
  StatusOr<ClassTable> table = ReadClassTable(config.dataset);
  if (!table.ok()) return table.status();
  if (table->empty()) {
    return Status::InvalidArgument(config.dataset + " has no classes.txt: cannot label objects");
  }
  const std::string textons_file =
      config.textons.empty() ? DefaultModelsDir() + "/textons.yml" : config.textons;
  StatusOr<TextonModel> textons = LoadTextons(textons_file);
  if (!textons.ok()) return textons.status();
  const TextonAssigner assigner(*textons);
  // Everything is written to a staging directory inside --out and moved into place only when
  // the whole training succeeded, so that a failed run leaves the previous models as they were.
  namespace fs = std::filesystem;
  const std::string staging = config.out + "/.training-" + std::to_string(getpid());
  std::error_code ec;
  fs::remove_all(staging, ec);
  if (!MakeDirectories(staging)) return Status::IoError("cannot create or write in " + staging);
  const RemoveOnExit cleanup{staging};

  Timer timer;
  StatusOr<DescribedSegments> segments =
      DescribeTruthSegments(config.dataset, config.split, *table, assigner, config.exclude_classes,
                            config.segments, config.progress);
  if (!segments.ok()) return segments.status();
  const double describe_seconds = timer.ElapsedMs() / 1000.0;

  // Classes with enough segments, in class id order.
  std::map<int, int> counts;
  for (const int id : segments->class_ids) ++counts[id];
  std::vector<std::string> names;
  std::map<int, int> index_of;
  nlohmann::json skipped = nlohmann::json::object();
  nlohmann::json trained_counts = nlohmann::json::object();
  for (const auto& [id, count] : counts) {
    if (count < config.min_class_segments) {
      skipped[table->Name(id)] = count;
      continue;
    }
    index_of[id] = static_cast<int>(names.size());
    names.push_back(table->Name(id));
    trained_counts[table->Name(id)] = count;
  }
  if (names.size() < 2) {
    return Status::InvalidArgument("fewer than two classes have " +
                                   std::to_string(config.min_class_segments) +
                                   " training segments in " + config.dataset);
  }
  std::vector<int> labels(segments->class_ids.size(), -1);
  for (size_t i = 0; i < labels.size(); ++i) {
    const auto it = index_of.find(segments->class_ids[i]);
    if (it != index_of.end()) labels[i] = it->second;
  }

  nlohmann::json manifest;
  manifest["format_version"] = ObjectClassifier::kFormatVersion;
  manifest["created"] = TodayUtc();
  manifest["command"] = config.command_line;
  manifest["dataset"] = config.dataset;
  manifest["split"] = config.split;
  manifest["textons"] = textons_file;
  manifest["textons_k"] = textons->size();
  manifest["description_size"] = segments->features.cols;
  manifest["images"] = segments->images_read;
  manifest["classes"] = trained_counts;
  manifest["classes_without_classifier"] = skipped;
  manifest["excluded_classes"] = config.exclude_classes;
  const ObjectClassifierOptions& o = config.classifier;
  manifest["options"] = {{"weak_count", o.weak_count},
                         {"max_depth", o.max_depth},
                         {"min_object_pixels", config.segments.min_object_pixels},
                         {"max_segments_per_class", config.segments.max_segments_per_class},
                         {"bins", o.selection.bins},
                         {"parts_layout_candidates", o.selection.parts_layout_candidates},
                         {"wrapper_weak_count", o.selection.wrapper_weak_count},
                         {"wrapper_max_depth", o.selection.wrapper_max_depth},
                         {"folds", o.selection.folds},
                         {"redundancy", o.selection.redundancy},
                         {"add_spouses", o.selection.add_spouses},
                         {"max_negatives_per_positive", o.selection.max_negatives_per_positive},
                         {"seed", o.selection.seed}};
  manifest["seconds"]["describe"] = describe_seconds;

  fs::copy_file(textons_file, staging + "/textons.yml", ec);
  if (ec) return Status::IoError("cannot copy " + textons_file + ": " + ec.message());
  for (const ObjectModelVariant& variant : ObjectModelVariants()) {
    if (!config.ablation && variant.name != "all") continue;
    ObjectClassifierOptions options = config.classifier;
    options.select_features = variant.select;
    const std::vector<FeatureGroup> groups =
        VariantGroups(variant, textons->size(), options.selection.parts_layout_candidates);
    timer.Restart();
    std::vector<ObjectClassSummary> summary;
    StatusOr<ObjectClassifier> classifier = ObjectClassifier::Train(
        segments->features, labels, names, groups, options, &summary,
        [&](int done, const ObjectClassSummary& s) {
          if (!config.progress) return;
          std::string picked;
          for (size_t g = 0; g < s.per_group.size(); ++g) {
            picked += (g ? "+" : "") + std::to_string(s.per_group[g]);
          }
          std::fprintf(stderr, "%s: %d/%zu %s (%d positives): %s features, %.1f s\n",
                       variant.name.c_str(), done, names.size(), s.name.c_str(), s.positives,
                       picked.c_str(), s.seconds);
        });
    if (!classifier.ok()) return classifier.status();
    const std::string dir = staging + "/" + variant.name;
    PLACEREC_RETURN_IF_ERROR(classifier->Save(dir));
    nlohmann::json v;
    v["groups"] = variant.groups;
    v["select"] = variant.select;
    v["seconds"] = timer.ElapsedMs() / 1000.0;
    for (const ObjectClassSummary& s : summary) {
      nlohmann::json c;
      c["positives"] = s.positives;
      c["features_per_group"] = s.per_group;
      if (variant.select) {
        c["candidates"] = s.selection.candidates.size();
        c["after_wrapper"] = s.selection.after_wrapper.size();
        c["cv_error_candidates"] = s.selection.candidates_error;
        c["cv_error_selected"] = s.selection.selected_error;
        c["wrapper_fits"] = s.selection.fits;
      }
      v["classes"][s.name] = c;
    }
    manifest["variants"][variant.name] = v;
  }
  manifest["seconds"]["total"] = total.ElapsedMs() / 1000.0;
  PLACEREC_RETURN_IF_ERROR(WriteManifest(staging + "/manifest.json", manifest));
  // Into place, the manifest last (it describes the files beside it).
  std::vector<fs::path> entries;
  for (const auto& entry : fs::directory_iterator(staging)) {
    if (entry.path().filename() != "manifest.json") entries.push_back(entry.path());
  }
  entries.push_back(fs::path(staging) / "manifest.json");
  for (const fs::path& entry : entries) {
    const fs::path target = fs::path(config.out) / entry.filename();
    fs::remove_all(target, ec);
    fs::rename(entry, target, ec);
    if (ec) {
      return Status::IoError("cannot move " + entry.string() + " into " + config.out + ": " +
                             ec.message());
    }
  }
  // The variants of an earlier run that this one did not train (without --ablation): left
  // beside the new manifest they were loaded as if they belonged to it.
  for (const ObjectModelVariant& variant : ObjectModelVariants()) {
    if (manifest["variants"].contains(variant.name)) continue;
    fs::remove_all(fs::path(config.out) / variant.name, ec);
  }
  return manifest;
}

ClassificationAccuracy::ClassificationAccuracy(std::vector<std::string> names)
    : names_(std::move(names)), confusion_(names_.size(), std::vector<int>(names_.size() + 1, 0)) {}

void ClassificationAccuracy::Add(int truth, int decided) {
  CHECK(truth >= 0 && truth < static_cast<int>(names_.size())) << truth;
  const int column = decided >= 0 && decided < static_cast<int>(names_.size())
                         ? decided
                         : static_cast<int>(names_.size());
  ++confusion_[truth][column];
}

int ClassificationAccuracy::Segments(int c) const {
  int n = 0;
  for (const int v : confusion_[c]) n += v;
  return n;
}

double ClassificationAccuracy::Accuracy(int c) const {
  const int n = Segments(c);
  return n == 0 ? std::numeric_limits<double>::quiet_NaN() : 100.0 * confusion_[c][c] / n;
}

double ClassificationAccuracy::MeanAccuracy(const std::vector<bool>& only) const {
  double sum = 0.0;
  int classes = 0;
  for (size_t c = 0; c < names_.size(); ++c) {
    if (!only.empty() && !only[c]) continue;
    if (Segments(static_cast<int>(c)) == 0) continue;
    sum += Accuracy(static_cast<int>(c));
    ++classes;
  }
  return classes == 0 ? std::numeric_limits<double>::quiet_NaN() : sum / classes;
}

nlohmann::json ClassificationAccuracy::ToJson() const {
  nlohmann::json j;
  int total = 0;
  int correct = 0;
  for (size_t c = 0; c < names_.size(); ++c) {
    const int n = Segments(static_cast<int>(c));
    total += n;
    correct += confusion_[c][c];
    j["segments"][names_[c]] = n;
    if (n > 0) j["per_class_accuracy"][names_[c]] = Accuracy(static_cast<int>(c));
    nlohmann::json row = nlohmann::json::object();
    for (size_t d = 0; d <= names_.size(); ++d) {
      if (confusion_[c][d] > 0) row[d < names_.size() ? names_[d] : "none"] = confusion_[c][d];
    }
    j["confusion"][names_[c]] = row;
  }
  j["mean_accuracy"] = MeanAccuracy();
  j["overall_accuracy"] = total == 0 ? 0.0 : 100.0 * correct / total;
  j["total_segments"] = total;
  return j;
}

}  // namespace placerec
