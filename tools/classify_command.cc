#include "tools/classify_command.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/classification/object_classifier.h"
#include "common/eval/plots.h"
#include "common/organization/scene_organizer.h"
#include "common/organization/textons.h"
#include "common/training/background_training.h"
#include "common/training/object_training.h"
#include "common/util/options.h"
#include "common/util/paths.h"

namespace placerec {
namespace {

// Seed Tables 6.5-6.7 (MSRC-21, ground-truth segments), for the report.
nlohmann::json SeedFigures() {
  return {{"table_6_5_binary",
           {{"appearance", {{"car", 63.1}, {"building", 61.0}, {"face", 60.0}}},
            {"appearance_parts", {{"car", 68.4}, {"building", 66.2}, {"face", 73.1}}},
            {"appearance_shape", {{"car", 80.9}, {"building", 73.8}, {"face", 71.4}}},
            {"all", {{"car", 85.7}, {"building", 76.2}, {"face", 82.8}}}}},
          {"table_6_6_binary",
           {{"full", {{"car", 23.8}, {"building", 65.5}, {"face", 73.7}}},
            {"all", {{"car", 85.7}, {"building", 76.2}, {"face", 82.8}}}}},
          {"table_6_7_one_per_class", {{"car", 85.7}, {"building", 91.9}, {"body", 86.4}}}};
}

struct Options {
  std::string dataset;
  std::string split = "test";
  std::string segments = "truth";
  std::string models;  // empty: DefaultModelsDir()/objects
  std::string out;
  bool quiet = false;
};

// The binary classifiers' accuracy on the segments of their class (seed Tables 6.5, 6.6: "the
// classification accuracy of the corresponding binary classifiers"): the percent of the class's
// segments whose score is positive, and the percent of all segments told right (yes/no).
nlohmann::json BinaryAccuracy(const cv::Mat& scores, const std::vector<int>& truth,
                              const std::vector<std::string>& names) {
  nlohmann::json j;
  for (int c = 0; c < scores.cols; ++c) {
    int positives = 0;
    int found = 0;
    int right = 0;
    for (int r = 0; r < scores.rows; ++r) {
      const bool said = scores.at<float>(r, c) > 0.0f;
      const bool is = truth[r] == c;
      positives += is;
      found += is && said;
      right += said == is;
    }
    if (positives == 0) continue;
    j[names[c]] = {{"recall", 100.0 * found / positives},
                   {"accuracy", 100.0 * right / std::max(scores.rows, 1)}};
  }
  return j;
}

int Fail(const Status& status) {
  std::fprintf(stderr, "placerec-eval classify: %s\n", status.ToString().c_str());
  return 1;
}

// A contact sheet of up to 48 misclassified segments (the first of each (truth, decision) pair
// first, so that every kind of mistake shows): the segment's box in its image with some context,
// the box drawn, "truth -> decided" below.
Status WriteMisclassifiedSheet(const std::string& path, const std::string& dataset,
                               const DescribedSegments& segments, const std::vector<int>& truth,
                               const std::vector<int>& decided,
                               const std::vector<std::string>& names) {
  constexpr int kTiles = 48;
  constexpr int kColumns = 8;
  constexpr int kTile = 160;
  constexpr int kCaption = 20;
  std::vector<size_t> chosen;
  std::set<std::pair<int, int>> kinds;
  for (int pass = 0; pass < 2; ++pass) {
    for (size_t i = 0; i < truth.size() && static_cast<int>(chosen.size()) < kTiles; ++i) {
      if (truth[i] < 0 || decided[i] == truth[i]) continue;
      const bool first_of_kind = kinds.insert({truth[i], decided[i]}).second;
      if ((pass == 0) == first_of_kind &&
          std::find(chosen.begin(), chosen.end(), i) == chosen.end()) {
        chosen.push_back(i);
      }
    }
  }
  const int rows = std::max(1, (static_cast<int>(chosen.size()) + kColumns - 1) / kColumns);
  cv::Mat sheet(rows * (kTile + kCaption), kColumns * kTile, CV_8UC3, cv::Scalar::all(255));
  for (size_t t = 0; t < chosen.size(); ++t) {
    const size_t i = chosen[t];
    StatusOr<LabelledImage> image = ReadLabelledImage(dataset, segments.images[i]);
    if (!image.ok()) return image.status();
    const cv::Rect box = segments.boxes[i];
    const int pad = std::max(box.width, box.height) / 4;
    const cv::Rect view =
        cv::Rect(box.x - pad, box.y - pad, box.width + 2 * pad, box.height + 2 * pad) &
        cv::Rect(0, 0, image->bgr.cols, image->bgr.rows);
    cv::Mat crop = image->bgr(view).clone();
    cv::rectangle(crop, box - view.tl(), cv::Scalar(0, 0, 255), 2);
    const double scale = static_cast<double>(kTile) / std::max(crop.cols, crop.rows);
    cv::resize(crop, crop, cv::Size(), scale, scale, cv::INTER_AREA);
    const int x = static_cast<int>(t % kColumns) * kTile;
    const int y = static_cast<int>(t / kColumns) * (kTile + kCaption);
    crop.copyTo(sheet(cv::Rect(x, y, crop.cols, crop.rows)));
    const std::string caption =
        names[static_cast<size_t>(truth[i])] + " -> " + names[static_cast<size_t>(decided[i])];
    cv::putText(sheet, caption, cv::Point(x + 3, y + kTile + 14), cv::FONT_HERSHEY_SIMPLEX, 0.4,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  }
  if (!cv::imwrite(path, sheet)) return Status::IoError("cannot write " + path);
  return Status::Ok();
}

}  // namespace

int ClassifyCommand(int argc, char** argv, const std::string& default_data_dir) {
  Options options;
  FlagParser parser(
      "placerec-eval classify --dataset DIR --out OUT [options]\n\n"
      "Describes every ground-truth object segment of DIR's split (seed §4.1), classifies it\n"
      "with the object classifiers of --models (placerec-train objects) one-per-class (the\n"
      "class whose binary classifier is most confident, seed §6.2.1) and writes\n"
      "OUT/classification.json (per-class and mean accuracy, confusion, the binary classifiers'\n"
      "accuracy, the feature-group and selection ablation of seed Tables 6.5-6.6 when the\n"
      "models hold it, and the seed's figures), OUT/confusion.png and OUT/misclassified.png (a "
      "sheet of misclassified segments, truth -> decision).");
  parser.AddRequired(
      "dataset", &options.dataset,
      "labelled dataset directory, or its name under PLACEREC_DATA / ../shared/data");
  parser.AddRequired("out", &options.out, "output directory (created if missing)");
  parser.Add("split", &options.split, "split to classify");
  parser.Add("segments", &options.segments,
             "segments to classify: 'truth' (ground-truth objects) or 'organization' (the "
             "Perceptual Organization segments recognition classifies, each given the majority "
             "ground-truth class of its pixels)");
  parser.Add("models", &options.models,
             "object models directory (default: the shipped models/objects)");
  parser.AddSwitch("quiet", &options.quiet, "no progress lines");
  if (const std::optional<int> exit = parser.ParseOrExit(argc, argv, 2, "placerec-eval classify")) {
    return *exit;
  }
  if (options.segments != "truth" && options.segments != "organization") {
    std::fprintf(stderr,
                 "placerec-eval classify: --segments %s is not known (truth: the ground-truth "
                 "objects; organization: the segments recognition classifies)\n",
                 options.segments.c_str());
    return 2;
  }
  if (options.split.empty()) {
    std::fprintf(stderr, "placerec-eval classify: --split must not be empty\n");
    return 2;
  }
  std::string dataset = options.dataset;
  if (!PathExists(dataset) && PathExists(default_data_dir + "/" + dataset)) {
    dataset = default_data_dir + "/" + dataset;
  }
  if (!PathExists(dataset)) return Fail(Status::NotFound("no dataset " + options.dataset));
  const std::string models =
      options.models.empty() ? DefaultModelsDir() + "/objects" : options.models;
  cv::setNumThreads(1);

  // The models: manifest (exclusions, segment options), textons and the variants present.
  nlohmann::json manifest;
  {
    std::ifstream in(models + "/manifest.json");
    if (!in) return Fail(Status::NotFound("cannot read " + models + "/manifest.json"));
    manifest = nlohmann::json::parse(in, nullptr, false);
    if (manifest.is_discarded()) {
      return Fail(Status::InvalidArgument(models + "/manifest.json is not JSON"));
    }
  }
  StatusOr<TextonModel> textons = LoadTextons(models + "/textons.yml");
  if (!textons.ok()) return Fail(textons.status());
  std::vector<std::pair<std::string, ObjectClassifier>> variants;
  for (const ObjectModelVariant& variant : ObjectModelVariants()) {
    if (!PathExists(models + "/" + variant.name + "/objects.yml")) continue;
    StatusOr<ObjectClassifier> classifier = ObjectClassifier::Load(models + "/" + variant.name);
    if (!classifier.ok()) return Fail(classifier.status());
    if (classifier->feature_size() != ObjectDescriptionSize(textons->size())) {
      return Fail(Status::InvalidArgument(
          models + "/" + variant.name + ": classifiers read a description of " +
          std::to_string(classifier->feature_size()) + " numbers, the textons give " +
          std::to_string(ObjectDescriptionSize(textons->size()))));
    }
    variants.emplace_back(variant.name, std::move(*classifier));
  }
  if (variants.empty() || variants.front().first != "all") {
    return Fail(Status::NotFound(models + "/all/objects.yml: no object model (placerec-train "
                                          "objects writes it)"));
  }

  StatusOr<ClassTable> table = ReadClassTable(dataset);
  if (!table.ok()) return Fail(table.status());
  TruthSegmentOptions segment_options;
  segment_options.min_object_pixels =
      manifest["options"].value("min_object_pixels", segment_options.min_object_pixels);
  const std::vector<std::string> exclude =
      manifest.value("excluded_classes", std::vector<std::string>{});
  const TextonAssigner assigner(*textons);
  // Organization: the Perceptual Organization segments of recognition's preset (what
  // recognition classifies), each with the majority ground-truth class of its pixels.
  std::unique_ptr<SceneOrganizer> organizer;
  std::function<cv::Mat(const LabelledImage&)> objects_of;
  if (options.segments == "organization") {
    StatusOr<SceneOrganizer> made = SceneOrganizer::Create(SceneOrganizerOptions::ForRecognition());
    if (!made.ok()) return Fail(made.status());
    organizer = std::make_unique<SceneOrganizer>(std::move(*made));
    objects_of = [&organizer](const LabelledImage& image) {
      const WorkingImage working =
          MakeWorkingImage(image.bgr, organizer->options().superpixels.working_width);
      cv::Mat ids = organizer->Segment(working).labels + 1;
      return ids;
    };
  }
  StatusOr<DescribedSegments> segments =
      DescribeSegmentsOf(dataset, options.split, *table, assigner, exclude, segment_options,
                         !options.quiet, objects_of);
  if (!segments.ok()) return Fail(segments.status());

  // Truth as class indices of the model; segments of classes without a classifier are counted
  // apart (they cannot be classified right).
  const std::vector<std::string>& names = variants.front().second.names();
  for (const auto& [name, classifier] : variants) {
    if (classifier.names() != names) {
      return Fail(Status::InvalidArgument(models + "/" + name + ": other classes than all/"));
    }
  }
  std::vector<int> truth(segments->class_ids.size(), -1);
  nlohmann::json unclassifiable = nlohmann::json::object();
  for (size_t i = 0; i < truth.size(); ++i) {
    const std::string name = table->Name(segments->class_ids[i]);
    for (size_t c = 0; c < names.size(); ++c) {
      if (names[c] == name) truth[i] = static_cast<int>(c);
    }
    if (truth[i] < 0) unclassifiable[name] = unclassifiable.value(name, 0) + 1;
  }
  // Structured classes (not sky, tree, road, grass, water): seed Table 6.7 decides among their
  // 16 classifiers only.
  std::vector<bool> structured(names.size(), true);
  for (const auto& [id, name] : table->names) {
    for (size_t c = 0; c < names.size(); ++c) {
      if (names[c] == name && table->BackgroundClass(id) != SegmentClass::kStructured) {
        structured[c] = false;
      }
    }
  }

  nlohmann::json report;
  report["dataset"] = dataset;
  report["split"] = options.split;
  report["segments"] = options.segments;
  report["models"] = models;
  report["command"] = CommandLine(argc, argv);
  report["test_segments"] = segments->size();
  report["segments_of_classes_without_classifier"] = unclassifiable;
  report["excluded_classes"] = exclude;
  report["seed"] = SeedFigures();
  std::vector<std::vector<int>> main_confusion;
  std::vector<int> main_decided;  // the model's one-per-class decision per segment
  for (const auto& [name, classifier] : variants) {
    const cv::Mat scores = classifier.Scores(segments->features);
    const std::vector<int> decided = ObjectClassifier::Decide(scores);
    const std::vector<int> decided_structured = ObjectClassifier::Decide(scores, structured);
    ClassificationAccuracy all(names);
    ClassificationAccuracy among_structured(names);
    for (size_t i = 0; i < truth.size(); ++i) {
      if (truth[i] < 0) continue;
      all.Add(truth[i], decided[i]);
      if (structured[truth[i]]) among_structured.Add(truth[i], decided_structured[i]);
    }
    nlohmann::json v = all.ToJson();
    nlohmann::json s = among_structured.ToJson();
    v["structured_one_per_class"] = {{"per_class_accuracy", s["per_class_accuracy"]},
                                     {"mean_accuracy", s["mean_accuracy"]},
                                     {"confusion", s["confusion"]}};
    v["binary"] = BinaryAccuracy(scores, truth, names);
    int features = 0;
    for (int c = 0; c < classifier.classes(); ++c) {
      features += static_cast<int>(classifier.columns(c).size());
    }
    v["mean_features_per_class"] = static_cast<double>(features) / classifier.classes();
    if (name == "all") {
      for (const auto& [key, value] : v.items()) report[key] = value;
      main_confusion = all.confusion();
      main_decided = decided;
    } else {
      v.erase("confusion");
      v["structured_one_per_class"].erase("confusion");
    }
    report["ablation"][name] = v;
    report["ablation"][name].erase("confusion");
  }
  report["ablation"]["all"].erase("structured_one_per_class");
  report["ablation"]["all"]["structured_one_per_class"] = {
      {"mean_accuracy", report["structured_one_per_class"]["mean_accuracy"]},
      {"per_class_accuracy", report["structured_one_per_class"]["per_class_accuracy"]}};

  if (!MakeDirectories(options.out)) {
    return Fail(Status::IoError("cannot create or write in " + options.out));
  }
  if (const Status s = WriteManifest(options.out + "/classification.json", report); !s.ok()) {
    return Fail(s);
  }
  if (const Status s = WriteConfusionMatrixPng(
          options.out + "/confusion.png",
          "one-per-class, " + options.split + " " + options.segments + " segments", names,
          main_confusion);
      !s.ok()) {
    return Fail(s);
  }
  if (const Status s = WriteMisclassifiedSheet(options.out + "/misclassified.png", dataset,
                                               *segments, truth, main_decided, names);
      !s.ok()) {
    return Fail(s);
  }
  std::printf("%s %s: %d %s segments, %zu classes\n", dataset.c_str(), options.split.c_str(),
              segments->size(), options.segments.c_str(), names.size());
  std::printf("%-18s %8s %8s", "variant", "mean", "struct.");
  for (const char* c : {"car", "building", "body", "face"}) std::printf(" %9s", c);
  std::printf("   (one-per-class among all | binary recall)\n");
  for (const auto& [name, classifier] : variants) {
    const nlohmann::json& v = report["ablation"][name];
    std::printf("%-18s %8.1f %8.1f", name.c_str(), v["mean_accuracy"].get<double>(),
                v["structured_one_per_class"]["mean_accuracy"].get<double>());
    for (const char* c : {"car", "building", "body", "face"}) {
      if (v["per_class_accuracy"].contains(c) && v["binary"].contains(c)) {
        std::printf(" %4.1f|%4.1f", v["per_class_accuracy"][c].get<double>(),
                    v["binary"][c]["recall"].get<double>());
      } else {
        std::printf(" %9s", "-");
      }
    }
    std::printf("\n");
  }
  std::printf("wrote %s/classification.json, confusion.png, misclassified.png\n",
              options.out.c_str());
  return 0;
}

}  // namespace placerec
