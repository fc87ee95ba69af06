#include "tools/segment_command.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <optional>
#include <sstream>
#include <unordered_map>

#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/organization/organizer_flags.h"
#include "common/organization/scene_organizer.h"
#include "common/training/background_training.h"
#include "common/util/options.h"
#include "common/util/paths.h"
#include "common/util/progress.h"
#include "common/util/timer.h"
#include "tools/segment_pictures.h"

namespace placerec {

std::vector<ObjectScore> ScoreObjects(const cv::Mat& segments, const cv::Mat& objects,
                                      const cv::Mat& classes, const ClassTable& table,
                                      double min_object_fraction) {
  CHECK_EQ(segments.type(), CV_32S);
  CHECK_EQ(objects.type(), CV_32S);
  CHECK(segments.size() == objects.size());
  const bool has_classes = !classes.empty();
  if (has_classes) {
    CHECK_EQ(classes.type(), CV_32S);
    CHECK(classes.size() == objects.size());
  }
  std::unordered_map<int, int> segment_area;
  std::map<int, int> object_area;
  std::map<int, std::unordered_map<int, int>> overlap;    // object -> segment -> pixels
  std::map<int, std::map<int, int>> object_class_pixels;  // object -> class -> pixels
  for (int y = 0; y < segments.rows; ++y) {
    const int* s = segments.ptr<int>(y);
    const int* o = objects.ptr<int>(y);
    const int* c = has_classes ? classes.ptr<int>(y) : nullptr;
    for (int x = 0; x < segments.cols; ++x) {
      ++segment_area[s[x]];
      if (o[x] <= 0) continue;
      ++object_area[o[x]];
      ++overlap[o[x]][s[x]];
      if (c != nullptr && !table.IsUnlabelled(c[x])) ++object_class_pixels[o[x]][c[x]];
    }
  }
  const double min_pixels = min_object_fraction * static_cast<double>(segments.total());
  std::vector<ObjectScore> scores;
  for (const auto& [object, area] : object_area) {
    if (area < min_pixels) continue;
    ObjectScore score;
    score.object = object;
    score.pixels = area;
    for (const auto& [segment, inter] : overlap[object]) {
      const double iou =
          static_cast<double>(inter) / static_cast<double>(area + segment_area[segment] - inter);
      if (iou > score.iou) {
        score.iou = iou;
        score.coverage = static_cast<double>(inter) / area;
        score.purity = static_cast<double>(inter) / segment_area[segment];
      }
    }
    int best_class = -1;
    int best_pixels = 0;
    for (const auto& [id, pixels] : object_class_pixels[object]) {
      if (pixels > best_pixels) {
        best_class = id;
        best_pixels = pixels;
      }
    }
    score.class_name = best_class >= 0 ? table.Name(best_class) : "unknown";
    scores.push_back(score);
  }
  return scores;
}

void ObjectScoreSummary::Add(const std::vector<ObjectScore>& scores, const ClassTable& table) {
  std::map<std::string, bool> background_names;
  for (const auto& [id, name] : table.names) {
    background_names[name] = IsBackground(table.BackgroundClass(id));
  }
  auto add = [](const ObjectScore& s, Sum* sum) {
    sum->iou += s.iou;
    sum->coverage += s.coverage;
    sum->purity += s.purity;
    ++sum->objects;
  };
  for (const ObjectScore& s : scores) {
    add(s, &all_);
    add(s, &classes_[s.class_name]);
    if (s.class_name == "unknown") continue;
    add(s, &groups_[background_names[s.class_name] ? "background" : "structured"]);
  }
}

double ObjectScoreSummary::Mean() const {
  return all_.objects > 0 ? 100.0 * all_.iou / all_.objects : 0.0;
}

nlohmann::json ObjectScoreSummary::ToJson() const {
  auto entry = [](const Sum& s) {
    const double n = std::max(1, s.objects);
    return nlohmann::json{{"objects", s.objects},
                          {"mean_iou", 100.0 * s.iou / n},
                          {"mean_coverage", 100.0 * s.coverage / n},
                          {"mean_purity", 100.0 * s.purity / n}};
  };
  nlohmann::json out = entry(all_);
  for (const auto& [name, sum] : classes_) out["classes"][name] = entry(sum);
  for (const auto& [name, sum] : groups_) out["groups"][name] = entry(sum);
  return out;
}

namespace {

std::vector<double> ParseList(const std::string& text, bool* ok) {
  std::vector<double> values;
  std::stringstream stream(text);
  std::string item;
  *ok = true;
  while (std::getline(stream, item, ',')) {
    try {
      values.push_back(std::stod(item));
    } catch (...) {
      *ok = false;
    }
  }
  *ok = *ok && !values.empty();
  return values;
}

// Per-pixel comparison of output classes with ground-truth classes mapped to background
// classes: recall (accuracy) and precision per background class and for "structured".
struct PixelClassAccuracy {
  std::array<int64_t, kBackgroundClasses + 1> truth{};
  std::array<int64_t, kBackgroundClasses + 1> output{};
  std::array<int64_t, kBackgroundClasses + 1> both{};

  static int Index(SegmentClass c) {
    return IsBackground(c) ? static_cast<int>(c) : kBackgroundClasses;
  }

  void Add(const cv::Mat& segments, const std::vector<SegmentClass>& classes,
           const cv::Mat& gt_classes, const ClassTable& table) {
    for (int y = 0; y < segments.rows; ++y) {
      const int* s = segments.ptr<int>(y);
      const int* g = gt_classes.ptr<int>(y);
      for (int x = 0; x < segments.cols; ++x) {
        if (table.IsUnlabelled(g[x])) continue;
        const int t = Index(table.BackgroundClass(g[x]));
        const int o = Index(classes[s[x]]);
        ++truth[t];
        ++output[o];
        both[t] += t == o;
      }
    }
  }

  nlohmann::json ToJson() const {
    nlohmann::json out;
    int64_t correct = 0;
    int64_t total = 0;
    for (int i = 0; i <= kBackgroundClasses; ++i) {
      const std::string name =
          i < kBackgroundClasses ? SegmentClassName(BackgroundClassOf(i)) : "structured";
      out["classes"][name] = {{"pixels", truth[i]},
                              {"accuracy", truth[i] > 0 ? 100.0 * both[i] / truth[i] : 0.0},
                              {"precision", output[i] > 0 ? 100.0 * both[i] / output[i] : 0.0}};
      correct += both[i];
      total += truth[i];
    }
    out["overall"] = total > 0 ? 100.0 * correct / total : 0.0;
    return out;
  }
};

struct GridSetting {
  double k;  // FH k at 320x240
  int min_size;
  ObjectScoreSummary score;
};

cv::Mat ToOriginal(const cv::Mat& labels, cv::Size size) {
  if (labels.size() == size) return labels;
  cv::Mat out;
  cv::resize(labels, out, size, 0, 0, cv::INTER_NEAREST);
  return out;
}

// --oracle-classes: the classified superpixels take the background class of their ground-truth
// majority class (`true_classes`, dataset ids at any size), then the seed's Perceptual
// Organization groups them.
SceneSegmentation OrganizeOnTrueClasses(const SceneOrganizer& organizer,
                                        const WorkingImage& working, const cv::Mat& true_classes,
                                        const ClassTable& table,
                                        const OrganizationOptions& organization,
                                        OrganizationSummary* summary) {
  SceneSegmentation parts = organizer.ClassifiedSuperpixels(working);
  const cv::Mat gt = LayerAtSize(true_classes, working.bgr.size());
  const std::vector<int> labels = RegionLabels(parts.labels, parts.size(), gt, table, 0.0);
  for (int r = 0; r < parts.size(); ++r) {
    parts.classes[r] = labels[r] >= 0 && labels[r] < kBackgroundClasses
                           ? static_cast<SegmentClass>(labels[r])
                           : SegmentClass::kStructured;
  }
  SceneSegmentation segmentation =
      OrganizeScene(parts.labels, parts.classes, working.lab, organization, summary);
  segmentation.scale = working.scale;
  return segmentation;
}

// --oracle-grouping: the regions of `parts` grouped by their majority ground-truth object
// (`objects` CV_32S at the size of parts.labels, 0 = none); regions mostly outside every object
// stay apart. Every group is "structured"; the scale stays that of `parts`.
SceneSegmentation GroupByTrueObjects(SceneSegmentation parts, const cv::Mat& objects) {
  std::vector<std::map<int, int>> votes(static_cast<size_t>(parts.size()));
  for (int y = 0; y < objects.rows; ++y) {
    const int* g = objects.ptr<int>(y);
    const int* l = parts.labels.ptr<int>(y);
    for (int x = 0; x < objects.cols; ++x) ++votes[l[x]][g[x]];
  }
  std::map<int, int> group_of_object;
  std::vector<int> group(votes.size());
  for (size_t r = 0; r < votes.size(); ++r) {
    int best = 0;
    int best_votes = -1;
    for (const auto& [object, count] : votes[r]) {
      if (object > 0 && count > best_votes) {
        best = object;
        best_votes = count;
      }
    }
    const int next_group = static_cast<int>(group_of_object.size());
    group[r] = best > 0 ? group_of_object.emplace(best, next_group).first->second : -1;
  }
  int next = static_cast<int>(group_of_object.size());
  for (int& g : group) {
    if (g < 0) g = next++;
  }
  for (int y = 0; y < objects.rows; ++y) {
    int* l = parts.labels.ptr<int>(y);
    for (int x = 0; x < objects.cols; ++x) l[x] = group[l[x]];
  }
  parts.classes.assign(static_cast<size_t>(next), SegmentClass::kStructured);
  return parts;
}

// Seed Table 6.4 protocol: every ground-truth object region of `image` (which has objects and
// classes) is described and classified as a whole, and tallied into `all`, and into `salient`
// when it covers at least `min_object_fraction` of the image.
void TallyTrueRegions(const SceneOrganizer& organizer, const WorkingImage& working,
                      const LabelledImage& image, const ClassTable& table,
                      const SceneOrganizerOptions& options, double min_object_fraction,
                      BackgroundAccuracy* all, BackgroundAccuracy* salient) {
  const cv::Size working_size = working.bgr.size();
  const cv::Mat working_objects = LayerAtSize(image.objects, working_size);
  cv::Mat regions(working_size, CV_32S);
  std::map<int, int> compact;
  for (int y = 0; y < regions.rows; ++y) {
    const int* o = working_objects.ptr<int>(y);
    int* r = regions.ptr<int>(y);
    for (int x = 0; x < regions.cols; ++x) {
      r[x] = o[x] <= 0 ? -1 : compact.emplace(o[x], static_cast<int>(compact.size())).first->second;
    }
  }
  const int n = static_cast<int>(compact.size());
  const cv::Mat appearance = organizer.Appearance(organizer.Features(working), regions, n);
  std::vector<int> majority;
  const std::vector<int> labels =
      RegionLabels(regions, n, LayerAtSize(image.classes, working_size), table, 0.5, &majority);
  const BackgroundClassifier& classifier = organizer.model().classifier;
  const cv::Mat region_scores = classifier.Scores(appearance);
  const std::vector<float> rivals = classifier.Rivals(appearance, options.one_per_class);
  const std::vector<int> areas = RegionAreas(regions, n);
  all->Add(region_scores, rivals, labels, majority, areas, table, options.background_threshold);
  std::vector<int> salient_labels = labels;
  for (int r = 0; r < n; ++r) {
    if (areas[r] < min_object_fraction * static_cast<double>(regions.total())) {
      salient_labels[r] = -1;
    }
  }
  salient->Add(region_scores, rivals, salient_labels, majority, areas, table,
               options.background_threshold);
}

// The segmentation options of a run, for segmentation.json.
nlohmann::json OptionsJson(const SceneOrganizerOptions& options,
                           const std::vector<std::string>& structured_classes) {
  const SuperpixelOptions& sp = options.superpixels;
  const OrganizationOptions& po = options.organization;
  nlohmann::json opts;
  opts["models_dir"] = options.models_dir.empty() ? DefaultModelsDir() : options.models_dir;
  opts["working_width"] = sp.working_width;
  opts["fh"] = {{"sigma", sp.sigma},
                {"k_640x480", sp.k},
                {"min_size_640x480", sp.min_size},
                {"min_region_fraction", sp.min_region_fraction},
                {"colour_merge_distance", sp.colour_merge_distance}};
  opts["texton_stride"] = options.texton_stride;
  opts["background_threshold"] = options.background_threshold;
  opts["background_smoothing"] = options.background_smoothing;
  opts["one_per_class"] = options.one_per_class;
  opts["structured_classes"] = structured_classes;
  opts["learned_merge"] = {{"enabled", options.learned_merge},
                           {"threshold", options.merge.threshold}};
  opts["organization"] = {{"theta", {po.theta_complexity, po.theta_cohesion}},
                          {"alpha", po.alpha},
                          {"beta", po.beta},
                          {"complexity_step", po.complexity_step},
                          {"complexity_window", po.complexity_window},
                          {"symmetry_tolerance", po.symmetry_tolerance},
                          {"alignment_extension", po.alignment_extension},
                          {"alignment_tolerance", po.alignment_tolerance},
                          {"enclosed_fraction", po.enclosed_fraction},
                          {"max_subset", po.max_subset},
                          {"max_rounds", po.max_rounds},
                          {"round_colour_merge_distance", po.round_colour_merge_distance},
                          {"background_merge_colour_distance", po.background_merge_colour_distance},
                          {"merge_background", po.merge_background}};
  return opts;
}

// The superpixel baseline's FH grid (settings at 320x240) from --grid-k and --grid-min; false
// when either list is not numbers a,b,c.
bool ParseGrid(const SegmentCommandOptions& options, std::vector<double>* ks,
               std::vector<double>* mins) {
  bool ok_k = false;
  bool ok_min = false;
  *ks = ParseList(options.grid_k, &ok_k);
  *mins = ParseList(options.grid_min, &ok_min);
  return ok_k && ok_min;
}

constexpr char kSegmentUsage[] =
    "placerec-eval segment --dataset DIR --split test --out OUT [options]\n\n"
    "Segments every image of DIR/<split>.txt (superpixels, background classes, the learned\n"
    "region merging, then Perceptual Organization as configured; seed Ch. 3) and\n"
    "writes OUT/segments/<id>.png (16-bit segment ids 1..n, every pixel in one segment),\n"
    "OUT/classes/<id>.png (8-bit: 0 sky, 1 tree, 2 road, 3 grass, 4 water, 7 structured) and\n"
    "OUT/overlays/<id>.png; with ground truth in DIR (classes/, objects/, classes.txt) it also\n"
    "writes OUT/segmentation.json: object-level accuracy (seed eq. 6.2) for Perceptual\n"
    "Organization and for superpixels alone over a grid of FH settings, and background\n"
    "classification accuracy (seed Table 6.4) on all ground-truth regions and on those the\n"
    "object score counts, and OUT/summary.png, a bar chart of the object IoU overall and per\n"
    "class beside the superpixel baseline. OUT/per_image.csv lists every image's segments,\n"
    "time and (with ground truth) scored objects and mean IoU, to find the worst.";

// Binds every flag of the command to its field of *options (whose values are the defaults).
void AddSegmentCommandFlags(FlagParser* parser, SegmentCommandOptions* options) {
  parser->AddRequired("dataset", &options->dataset,
                      "dataset directory, or its name under PLACEREC_DATA / ../shared/data");
  parser->AddRequired("out", &options->out, "output directory (created if missing)");
  parser->Add("split", &options->split, "split list DIR/<split>.txt");
  parser->Add("overlays", &options->overlays,
              "overlay pictures to draw (evenly spread over the split)");
  parser->Add("max-images", &options->max_images, "segment only the first N images (0: all)");
  parser->Add("min-object-fraction", &options->min_object_fraction,
              "ground-truth objects smaller than this fraction of the image are not scored "
              "(seed §6.1.3: 0.5 %)");
  parser->Add("baseline", &options->baseline, "also score superpixels alone over the FH grid");
  parser->Add("grid-k", &options->grid_k,
              "superpixel baseline: FH k values at 320x240, comma-separated");
  parser->Add("grid-min", &options->grid_min,
              "superpixel baseline: FH minimum sizes at 320x240 (pixels), comma-separated");
  AddOrganizerFlags(parser, &options->organizer);
  parser->Add("oracle-classes", &options->oracle_classes,
              "diagnosis only: superpixels take the background class of their ground-truth "
              "majority class instead of the classifiers' decision, then the --po-* grouping "
              "runs without the learned merging (shows what perfect background identification "
              "would give the seed's rule)");
  parser->Add("oracle-grouping", &options->oracle_grouping,
              "diagnosis only: the initial partition's regions are grouped by their majority "
              "ground-truth object (the best any grouping of that partition can score)");
  parser->AddSwitch("quiet", &options->quiet, "no progress line");
  parser->AddSwitch("verbose", &options->verbose,
                    "one line per image: parts per round, segments, IoU");
}

// One run of the command, in stages: ReadInputs, SegmentImages (which writes each image's
// pictures as it goes), Score (the report) and WriteOutputs. A stage that fails sets *error to
// the message (without the "placerec-eval segment: " prefix) and returns false; the run then
// stops with exit code 1.
class SegmentRun {
 public:
  // `options` pass Check; options.dataset not found as given is looked for under
  // `default_data_dir`.
  SegmentRun(const SegmentCommandOptions& options, const std::string& default_data_dir);

  // Reads the split, the class table and the models, and every listed image and ground-truth
  // layer, so that a bad file stops the run before anything is written.
  bool ReadInputs(std::string* error);
  // Creates the output directories, segments every image, writes its pictures and scores it.
  bool SegmentImages(std::string* error);
  // The contents of segmentation.json.
  nlohmann::json Score() const;
  // Writes segmentation.json, per_image.csv and (with ground truth) summary.png, then prints
  // the summary lines to standard output.
  bool WriteOutputs(const nlohmann::json& report, std::string* error) const;

 private:
  // The image's segmentation by the organiser, or by an oracle when one is asked for.
  SceneSegmentation Organize(const WorkingImage& working, const LabelledImage& image,
                             SceneOrganizerSummary* summary) const;
  bool SegmentImage(size_t i, ProgressLine* progress, std::string* error);
  // Scores one image that has object ground truth (`objects`, `gt_classes` at its size).
  void ScoreImage(const std::string& id, const LabelledImage& image, const WorkingImage& working,
                  const cv::Mat& segments, const SceneSegmentation& segmentation,
                  const cv::Mat& objects, const cv::Mat& gt_classes,
                  const SceneOrganizerSummary& summary, double image_ms, ProgressLine* progress);
  // Adds a per_image.csv row: `objects` < 0: not scored; `iou_sum` the scored objects' IoUs
  // added up.
  void AddRow(const std::string& id, int segments, double ms, int objects, double iou_sum);
  void PrintSummary(const nlohmann::json& report) const;

  const SegmentCommandOptions options_;
  std::string dataset_;  // the directory read
  std::vector<std::string> ids_;
  ClassTable table_;
  std::optional<SceneOrganizer> organizer_;
  std::vector<GridSetting> grid_;
  std::vector<size_t> overlay_at_;
  ObjectScoreSummary po_score_;
  BackgroundAccuracy background_;
  // The same on the regions the object score counts (at least min_object_fraction of the image).
  BackgroundAccuracy salient_background_;
  PixelClassAccuracy pixels_;
  std::map<std::string, double> stage_ms_;
  int scored_images_ = 0;
  int64_t segments_total_ = 0;
  // One row per image; objects and mean_iou stay empty without ground truth.
  std::string per_image_ = "id,segments,ms,objects,mean_iou\n";
  Timer total_timer_;
};

SegmentRun::SegmentRun(const SegmentCommandOptions& options, const std::string& default_data_dir)
    : options_(options), dataset_(options.dataset) {
  if (!PathExists(dataset_)) {
    const std::string under = default_data_dir + "/" + dataset_;
    if (PathExists(under)) dataset_ = under;
  }
}

bool SegmentRun::ReadInputs(std::string* error) {
  StatusOr<std::vector<std::string>> ids = ReadSplit(dataset_, options_.split);
  StatusOr<ClassTable> table = ReadClassTable(dataset_);
  if (!ids.ok() || !table.ok()) {
    *error = (!ids.ok() ? ids.status() : table.status()).ToString();
    return false;
  }
  ids_ = std::move(*ids);
  table_ = std::move(*table);
  if (options_.max_images > 0 && static_cast<int>(ids_.size()) > options_.max_images) {
    ids_.resize(options_.max_images);
  }
  StatusOr<SceneOrganizer> organizer = SceneOrganizer::Create(options_.organizer);
  if (!organizer.ok()) {
    *error = organizer.status().ToString();
    return false;
  }
  organizer_.emplace(std::move(*organizer));
  for (const std::string& id : ids_) {
    const StatusOr<LabelledImage> image = ReadLabelledImage(dataset_, id);
    if (!image.ok()) {
      *error = image.status().ToString() + "\n  " + dataset_ + "/" + options_.split +
               ".txt lists '" + id +
               "': fix the file or remove the id from the split. Nothing was written.";
      return false;
    }
  }
  return true;
}

bool SegmentRun::SegmentImages(std::string* error) {
  for (const char* sub : {"segments", "classes", "overlays"}) {
    if (!MakeDirectories(options_.out + "/" + sub)) {
      *error = "cannot create or write in " + options_.out + "/" + sub;
      return false;
    }
  }
  cv::setNumThreads(1);
  if (options_.baseline) {
    std::vector<double> ks;
    std::vector<double> mins;
    ParseGrid(options_, &ks, &mins);
    for (const double k : ks) {
      for (const double m : mins) grid_.push_back({k, static_cast<int>(m), {}});
    }
  }
  for (int i = 0; i < options_.overlays && !ids_.empty(); ++i) {
    overlay_at_.push_back(static_cast<size_t>(i) * ids_.size() /
                          static_cast<size_t>(options_.overlays));
  }
  total_timer_.Restart();
  ProgressLine progress(ids_.size(), kLogProgressEvery);
  for (size_t i = 0; i < ids_.size(); ++i) {
    if (!SegmentImage(i, &progress, error)) {
      progress.Clear();
      return false;
    }
    if (!options_.quiet) progress.Report(i + 1, "segmented %zu/%zu", i + 1, ids_.size());
  }
  return true;
}

SceneSegmentation SegmentRun::Organize(const WorkingImage& working, const LabelledImage& image,
                                       SceneOrganizerSummary* summary) const {
  if (options_.oracle_classes && !image.classes.empty()) {
    return OrganizeOnTrueClasses(*organizer_, working, image.classes, table_,
                                 options_.organizer.organization, &summary->organization);
  }
  if (options_.oracle_grouping && !image.objects.empty()) {
    return GroupByTrueObjects(organizer_->ClassifiedSuperpixels(working),
                              LayerAtSize(image.objects, working.bgr.size()));
  }
  return organizer_->Segment(working, summary);
}

bool SegmentRun::SegmentImage(size_t i, ProgressLine* progress, std::string* error) {
  const std::string& id = ids_[i];
  StatusOr<LabelledImage> image = ReadLabelledImage(dataset_, id);
  if (!image.ok()) {
    *error = image.status().ToString();
    return false;
  }
  Timer timer;
  const WorkingImage working =
      MakeWorkingImage(image->bgr, options_.organizer.superpixels.working_width);
  SceneOrganizerSummary summary;
  const SceneSegmentation segmentation = Organize(working, *image, &summary);
  const double image_ms = timer.ElapsedMs();
  stage_ms_["total"] += image_ms;
  for (const auto& [stage, ms] : summary.timings) stage_ms_[stage] += ms;
  segments_total_ += segmentation.size();
  if (segmentation.size() > 65535) {
    *error = id + " has more than 65535 segments";
    return false;
  }
  const cv::Mat segments = ToOriginal(segmentation.labels, image->bgr.size());
  cv::Mat ids16(segments.size(), CV_16U);
  cv::Mat classes8(segments.size(), CV_8U);
  for (int y = 0; y < segments.rows; ++y) {
    const int* s = segments.ptr<int>(y);
    uint16_t* o16 = ids16.ptr<uint16_t>(y);
    uint8_t* o8 = classes8.ptr<uint8_t>(y);
    for (int x = 0; x < segments.cols; ++x) {
      o16[x] = static_cast<uint16_t>(s[x] + 1);
      o8[x] = static_cast<uint8_t>(segmentation.classes[s[x]]);
    }
  }
  if (!cv::imwrite(options_.out + "/segments/" + id + ".png", ids16) ||
      !cv::imwrite(options_.out + "/classes/" + id + ".png", classes8)) {
    *error = "cannot write " + id + "'s pictures";
    return false;
  }
  const cv::Mat objects =
      image->objects.empty() ? cv::Mat() : LayerAtSize(image->objects, segments.size());
  const cv::Mat gt_classes =
      image->classes.empty() ? cv::Mat() : LayerAtSize(image->classes, segments.size());
  if (std::find(overlay_at_.begin(), overlay_at_.end(), i) != overlay_at_.end()) {
    cv::imwrite(options_.out + "/overlays/" + id + ".png",
                DrawSegmentOverlay(image->bgr, segments, segmentation.classes, objects));
  }
  if (objects.empty()) {
    AddRow(id, segmentation.size(), image_ms, -1, 0.0);
  } else {
    ScoreImage(id, *image, working, segments, segmentation, objects, gt_classes, summary, image_ms,
               progress);
  }
  return true;
}

void SegmentRun::ScoreImage(const std::string& id, const LabelledImage& image,
                            const WorkingImage& working, const cv::Mat& segments,
                            const SceneSegmentation& segmentation, const cv::Mat& objects,
                            const cv::Mat& gt_classes, const SceneOrganizerSummary& summary,
                            double image_ms, ProgressLine* progress) {
  ++scored_images_;
  const std::vector<ObjectScore> scores =
      ScoreObjects(segments, objects, gt_classes, table_, options_.min_object_fraction);
  po_score_.Add(scores, table_);
  double sum = 0;
  for (const ObjectScore& s : scores) sum += s.iou;
  AddRow(id, segmentation.size(), image_ms, static_cast<int>(scores.size()), sum);
  if (options_.verbose) {
    progress->Clear();
    std::string rounds;
    for (const int p : summary.organization.parts) rounds += " " + std::to_string(p);
    std::fprintf(stderr,
                 "%s: %d superpixels (%d background), structured parts per round:%s,"
                 " %d segments, mean IoU %.1f over %zu objects\n",
                 id.c_str(), summary.superpixels, summary.background_superpixels, rounds.c_str(),
                 segmentation.size(), scores.empty() ? 0.0 : 100.0 * sum / scores.size(),
                 scores.size());
  }
  for (GridSetting& setting : grid_) {
    SuperpixelOptions baseline_options = options_.organizer.superpixels;
    // Settings are given at 320x240; SuperpixelOptions are at 640x480, scaled by area.
    baseline_options.k = setting.k * 4.0;
    baseline_options.min_size = setting.min_size * 4;
    const SceneSegmentation superpixels = ComputeSuperpixels(working, baseline_options);
    setting.score.Add(ScoreObjects(ToOriginal(superpixels.labels, image.bgr.size()), objects,
                                   gt_classes, table_, options_.min_object_fraction),
                      table_);
  }
  if (!gt_classes.empty() && !table_.empty()) {
    TallyTrueRegions(*organizer_, working, image, table_, options_.organizer,
                     options_.min_object_fraction, &background_, &salient_background_);
    pixels_.Add(segments, segmentation.classes, gt_classes, table_);
  }
}

void SegmentRun::AddRow(const std::string& id, int segments, double ms, int objects,
                        double iou_sum) {
  char numbers[64];
  std::snprintf(numbers, sizeof(numbers), ",%d,%.1f,", segments, ms);
  per_image_ += id + numbers;
  if (objects >= 0) per_image_ += std::to_string(objects);
  per_image_ += ",";
  if (objects > 0) {
    std::snprintf(numbers, sizeof(numbers), "%.2f", 100.0 * iou_sum / objects);
    per_image_ += numbers;
  }
  per_image_ += "\n";
}

nlohmann::json SegmentRun::Score() const {
  const double images = static_cast<double>(ids_.size());
  nlohmann::json report;
  report["dataset"] = dataset_;
  report["split"] = options_.split;
  report["images"] = static_cast<int>(ids_.size());
  report["scored_images"] = scored_images_;
  report["mean_segments_per_image"] =
      ids_.empty() ? 0.0 : static_cast<double>(segments_total_) / images;
  report["min_object_fraction"] = options_.min_object_fraction;
  report["options"] =
      OptionsJson(options_.organizer, organizer_->model().classifier.structured_names());
  report["options"]["oracle_classes"] = options_.oracle_classes;
  report["options"]["oracle_grouping"] = options_.oracle_grouping;
  for (const auto& [stage, ms] : stage_ms_) {
    report["mean_ms"][stage] = ids_.empty() ? 0.0 : ms / images;
  }
  if (scored_images_ == 0) {
    report["note"] = "no ground truth (objects/) in the dataset: nothing scored";
    return report;
  }
  report["perceptual_organization"] = po_score_.ToJson();
  if (!grid_.empty()) {
    const GridSetting* best = &grid_[0];
    nlohmann::json settings = nlohmann::json::array();
    for (const GridSetting& setting : grid_) {
      settings.push_back({{"k_320x240", setting.k},
                          {"min_size_320x240", setting.min_size},
                          {"mean_iou", setting.score.Mean()}});
      if (setting.score.Mean() > best->score.Mean()) best = &setting;
    }
    report["superpixels"]["grid"] = settings;
    report["superpixels"]["best"] = best->score.ToJson();
    report["superpixels"]["best"]["k_320x240"] = best->k;
    report["superpixels"]["best"]["min_size_320x240"] = best->min_size;
  }
  if (background_.total > 0) {
    report["background"]["ground_truth_regions"] = background_.ToJson();
    report["background"]["salient_ground_truth_regions"] = salient_background_.ToJson();
    report["background"]["salient_ground_truth_regions"]["min_region_fraction"] =
        options_.min_object_fraction;
    report["background"]["output_pixels"] = pixels_.ToJson();
  }
  return report;
}

bool SegmentRun::WriteOutputs(const nlohmann::json& scores, std::string* error) const {
  nlohmann::json report = scores;
  report["seconds"] = total_timer_.ElapsedMs() / 1000.0;
  const std::string& out = options_.out;
  std::ofstream file(out + "/segmentation.json");
  file << report.dump(2) << "\n";
  std::ofstream rows(out + "/per_image.csv");
  rows << per_image_;
  if (!file || !rows) {
    *error = "cannot write " + out + "/segmentation.json or per_image.csv";
    return false;
  }
  if (scored_images_ > 0) {
    std::string method = "seed's Perceptual Organization";
    if (options_.oracle_grouping) {
      method = "superpixels grouped by the ground truth (oracle)";
    } else if (options_.oracle_classes) {
      method = "seed's Perceptual Organization on ground-truth classes (oracle)";
    } else if (options_.organizer.learned_merge) {
      char learned[64];
      std::snprintf(learned, sizeof(learned), "learned merging (threshold %g)",
                    options_.organizer.merge.threshold);
      method = learned;
    }
    const Status chart = WriteSegmentSummaryChart(report, method, out + "/summary.png");
    if (!chart.ok()) {
      *error = chart.ToString();
      return false;
    }
  }
  PrintSummary(report);
  return true;
}

void SegmentRun::PrintSummary(const nlohmann::json& report) const {
  std::printf("%s: %zu images, %.1f segments per image, %.1f ms per image\n",
              options_.split.c_str(), ids_.size(), report["mean_segments_per_image"].get<double>(),
              report["mean_ms"].value("total", 0.0));
  if (scored_images_ > 0) {
    auto line = [](const char* name, const nlohmann::json& j) {
      const nlohmann::json& classes = j["classes"];
      auto of = [&classes](const char* c) {
        char text[32] = "none";  // the dataset has no object of the class
        if (classes.contains(c)) {
          std::snprintf(text, sizeof(text), "%.1f", classes[c]["mean_iou"].get<double>());
        }
        return std::string(text);
      };
      std::printf("  %-24s mean %.1f %% over %d objects (building %s, foreground %s)\n", name,
                  j["mean_iou"].get<double>(), j["objects"].get<int>(), of("building").c_str(),
                  of("foreground").c_str());
    };
    line("perceptual organization", report["perceptual_organization"]);
    if (report.contains("superpixels"))
      line("superpixels (best FH)", report["superpixels"]["best"]);
    if (report.contains("background")) {
      auto recall = [](const char* name, const nlohmann::json& j) {
        std::printf("  %-24s", name);
        for (const char* c : {"sky", "tree", "road", "grass", "water"}) {
          std::printf(" %s %.1f", c, j["classes"][c]["accuracy"].get<double>());
        }
        std::printf(" (%d regions)\n", j["regions"].get<int>());
      };
      recall("background recall", report["background"]["ground_truth_regions"]);
      recall("  on salient regions", report["background"]["salient_ground_truth_regions"]);
    }
  }
  std::printf("  wrote %s/segments, classes, overlays, segmentation.json, per_image.csv%s\n",
              options_.out.c_str(), scored_images_ > 0 ? ", summary.png" : "");
}

}  // namespace

bool SegmentCommandOptions::Check(std::string* error) const {
  if (!organizer.Check(error)) return false;
  std::vector<double> ks;
  std::vector<double> mins;
  if (baseline && !ParseGrid(*this, &ks, &mins)) {
    *error = "--grid-k and --grid-min take numbers a,b,c";
    return false;
  }
  if (dataset.empty() || out.empty() || split.empty()) {
    *error = "--dataset, --out and --split must not be empty";
    return false;
  }
  if (overlays < 0) {
    *error = "--overlays must be at least 0, got " + std::to_string(overlays);
    return false;
  }
  if (max_images < 0) {
    *error = "--max-images must be at least 0 (0: all), got " + std::to_string(max_images);
    return false;
  }
  if (!(min_object_fraction >= 0.0 && min_object_fraction < 1.0)) {
    *error = "--min-object-fraction must be in [0, 1), got " + std::to_string(min_object_fraction);
    return false;
  }
  return true;
}

int SegmentCommand(int argc, char** argv, const std::string& default_data_dir) {
  SegmentCommandOptions options;
  FlagParser parser(kSegmentUsage);
  AddSegmentCommandFlags(&parser, &options);
  if (const std::optional<int> exit = parser.ParseOrExit(argc, argv, 2, "placerec-eval segment")) {
    return *exit;
  }
  std::string error;
  if (!options.Check(&error)) {
    std::fprintf(stderr, "placerec-eval segment: %s\n", error.c_str());
    return 2;
  }
  SegmentRun run(options, default_data_dir);
  if (!run.ReadInputs(&error) || !run.SegmentImages(&error) ||
      !run.WriteOutputs(run.Score(), &error)) {
    std::fprintf(stderr, "placerec-eval segment: %s\n", error.c_str());
    return 1;
  }
  return 0;
}

}  // namespace placerec
