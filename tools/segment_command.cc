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

}  // namespace

int SegmentCommand(int argc, char** argv, const std::string& default_data_dir) {
  std::string dataset;
  std::string split = "test";
  std::string out;
  SceneOrganizerOptions options = SceneOrganizerOptions::ForSegmentation();
  int overlays = 12;
  int max_images = 0;
  double min_object_fraction = 0.005;
  std::string grid_k = "125,250,500,1000";
  std::string grid_min = "50,150,300";
  bool baseline = true;
  bool quiet = false;
  bool verbose = false;
  bool oracle_classes = false;
  bool oracle_grouping = false;
  FlagParser parser(
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
      "time and (with ground truth) scored objects and mean IoU, to find the worst.");
  parser.AddRequired("dataset", &dataset,
                     "dataset directory, or its name under PLACEREC_DATA / ../shared/data");
  parser.AddRequired("out", &out, "output directory (created if missing)");
  parser.Add("split", &split, "split list DIR/<split>.txt");
  parser.Add("overlays", &overlays, "overlay pictures to draw (evenly spread over the split)");
  parser.Add("max-images", &max_images, "segment only the first N images (0: all)");
  parser.Add("min-object-fraction", &min_object_fraction,
             "ground-truth objects smaller than this fraction of the image are not scored "
             "(seed §6.1.3: 0.5 %)");
  parser.Add("baseline", &baseline, "also score superpixels alone over the FH grid");
  parser.Add("grid-k", &grid_k, "superpixel baseline: FH k values at 320x240, comma-separated");
  parser.Add("grid-min", &grid_min,
             "superpixel baseline: FH minimum sizes at 320x240 (pixels), comma-separated");
  AddOrganizerFlags(&parser, &options);
  parser.Add("oracle-classes", &oracle_classes,
             "diagnosis only: superpixels take the background class of their ground-truth "
             "majority class instead of the classifiers' decision, then the --po-* grouping "
             "runs without the learned merging (shows what perfect background identification "
             "would give the seed's rule)");
  parser.Add("oracle-grouping", &oracle_grouping,
             "diagnosis only: the initial partition's regions are grouped by their majority "
             "ground-truth object (the best any grouping of that partition can score)");
  parser.AddSwitch("quiet", &quiet, "no progress line");
  parser.AddSwitch("verbose", &verbose, "one line per image: parts per round, segments, IoU");
  if (const std::optional<int> exit = parser.ParseOrExit(argc, argv, 2, "placerec-eval segment")) {
    return *exit;
  }
  std::string error;
  if (!options.Check(&error)) {
    std::fprintf(stderr, "placerec-eval segment: %s\n", error.c_str());
    return 2;
  }
  bool ok_k = false;
  bool ok_min = false;
  const std::vector<double> ks = ParseList(grid_k, &ok_k);
  const std::vector<double> mins = ParseList(grid_min, &ok_min);
  if (baseline && (!ok_k || !ok_min)) {
    std::fprintf(stderr, "placerec-eval segment: --grid-k and --grid-min take numbers a,b,c\n");
    return 2;
  }
  if (!PathExists(dataset)) {
    const std::string under = default_data_dir + "/" + dataset;
    if (PathExists(under)) dataset = under;
  }
  StatusOr<std::vector<std::string>> ids = ReadSplit(dataset, split);
  StatusOr<ClassTable> table = ReadClassTable(dataset);
  if (!ids.ok() || !table.ok()) {
    std::fprintf(stderr, "placerec-eval segment: %s\n",
                 (!ids.ok() ? ids.status() : table.status()).ToString().c_str());
    return 1;
  }
  if (max_images > 0 && static_cast<int>(ids->size()) > max_images) ids->resize(max_images);
  StatusOr<SceneOrganizer> organizer = SceneOrganizer::Create(options);
  if (!organizer.ok()) {
    std::fprintf(stderr, "placerec-eval segment: %s\n", organizer.status().ToString().c_str());
    return 1;
  }
  // Every listed image and ground-truth layer must read before anything is written, so that a
  // bad file stops the run with nothing half-written.
  for (size_t i = 0; i < ids->size(); ++i) {
    const StatusOr<LabelledImage> image = ReadLabelledImage(dataset, (*ids)[i]);
    if (!image.ok()) {
      std::fprintf(stderr,
                   "placerec-eval segment: %s\n  %s/%s.txt lists '%s': fix the file or remove the "
                   "id from the split. Nothing was written.\n",
                   image.status().ToString().c_str(), dataset.c_str(), split.c_str(),
                   (*ids)[i].c_str());
      return 1;
    }
  }
  for (const char* sub : {"segments", "classes", "overlays"}) {
    if (!MakeDirectories(out + "/" + sub)) {
      std::fprintf(stderr, "placerec-eval segment: cannot create %s/%s\n", out.c_str(), sub);
      return 1;
    }
  }
  cv::setNumThreads(1);

  std::vector<GridSetting> grid;
  if (baseline) {
    for (const double k : ks) {
      for (const double m : mins) grid.push_back({k, static_cast<int>(m), {}});
    }
  }
  ObjectScoreSummary po_score;
  BackgroundAccuracy background;
  // The same on the regions the object score counts (at least min_object_fraction of the image).
  BackgroundAccuracy salient_background;
  PixelClassAccuracy pixels;
  std::map<std::string, double> stage_ms;
  int scored_images = 0;
  int64_t segments_total = 0;
  // One row per image; objects and mean_iou stay empty without ground truth.
  std::string per_image = "id,segments,ms,objects,mean_iou\n";
  // `objects` < 0: not scored; `iou_sum` the scored objects' IoUs added up.
  auto add_row = [&per_image](const std::string& id, int segments, double ms, int objects,
                              double iou_sum) {
    char numbers[64];
    std::snprintf(numbers, sizeof(numbers), ",%d,%.1f,", segments, ms);
    per_image += id + numbers;
    if (objects >= 0) per_image += std::to_string(objects);
    per_image += ",";
    if (objects > 0) {
      std::snprintf(numbers, sizeof(numbers), "%.2f", 100.0 * iou_sum / objects);
      per_image += numbers;
    }
    per_image += "\n";
  };
  std::vector<size_t> overlay_at;
  for (int i = 0; i < overlays && !ids->empty(); ++i) {
    overlay_at.push_back(static_cast<size_t>(i) * ids->size() / static_cast<size_t>(overlays));
  }
  Timer total_timer;
  ProgressLine progress(ids->size(), kLogProgressEvery);
  for (size_t i = 0; i < ids->size(); ++i) {
    const std::string& id = (*ids)[i];
    StatusOr<LabelledImage> image = ReadLabelledImage(dataset, id);
    if (!image.ok()) {
      progress.Clear();
      std::fprintf(stderr, "placerec-eval segment: %s\n", image.status().ToString().c_str());
      return 1;
    }
    Timer timer;
    const WorkingImage working = MakeWorkingImage(image->bgr, options.superpixels.working_width);
    SceneOrganizerSummary summary;
    SceneSegmentation segmentation;
    if (oracle_classes && !image->classes.empty()) {
      segmentation = OrganizeOnTrueClasses(*organizer, working, image->classes, *table,
                                           options.organization, &summary.organization);
    } else if (oracle_grouping && !image->objects.empty()) {
      segmentation = GroupByTrueObjects(organizer->ClassifiedSuperpixels(working),
                                        LayerAtSize(image->objects, working.bgr.size()));
    } else {
      segmentation = organizer->Segment(working, &summary);
    }
    const double image_ms = timer.ElapsedMs();
    stage_ms["total"] += image_ms;
    for (const auto& [stage, ms] : summary.timings) stage_ms[stage] += ms;
    segments_total += segmentation.size();
    if (segmentation.size() > 65535) {
      progress.Clear();
      std::fprintf(stderr, "placerec-eval segment: %s has more than 65535 segments\n", id.c_str());
      return 1;
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
    if (!cv::imwrite(out + "/segments/" + id + ".png", ids16) ||
        !cv::imwrite(out + "/classes/" + id + ".png", classes8)) {
      progress.Clear();
      std::fprintf(stderr, "placerec-eval segment: cannot write %s's pictures\n", id.c_str());
      return 1;
    }
    const cv::Mat objects =
        image->objects.empty() ? cv::Mat() : LayerAtSize(image->objects, segments.size());
    const cv::Mat gt_classes =
        image->classes.empty() ? cv::Mat() : LayerAtSize(image->classes, segments.size());
    if (std::find(overlay_at.begin(), overlay_at.end(), i) != overlay_at.end()) {
      cv::imwrite(out + "/overlays/" + id + ".png",
                  DrawSegmentOverlay(image->bgr, segments, segmentation.classes, objects));
    }
    if (objects.empty()) {
      add_row(id, segmentation.size(), image_ms, -1, 0.0);
    } else {
      ++scored_images;
      const std::vector<ObjectScore> scores =
          ScoreObjects(segments, objects, gt_classes, *table, min_object_fraction);
      po_score.Add(scores, *table);
      double sum = 0;
      for (const ObjectScore& s : scores) sum += s.iou;
      add_row(id, segmentation.size(), image_ms, static_cast<int>(scores.size()), sum);
      if (verbose) {
        progress.Clear();
        std::string rounds;
        for (const int p : summary.organization.parts) rounds += " " + std::to_string(p);
        std::fprintf(stderr,
                     "%s: %d superpixels (%d background), structured parts per round:%s,"
                     " %d segments, mean IoU %.1f over %zu objects\n",
                     id.c_str(), summary.superpixels, summary.background_superpixels,
                     rounds.c_str(), segmentation.size(),
                     scores.empty() ? 0.0 : 100.0 * sum / scores.size(), scores.size());
      }
      for (GridSetting& setting : grid) {
        SuperpixelOptions baseline_options = options.superpixels;
        // Settings are given at 320x240; SuperpixelOptions are at 640x480, scaled by area.
        baseline_options.k = setting.k * 4.0;
        baseline_options.min_size = setting.min_size * 4;
        const SceneSegmentation superpixels = ComputeSuperpixels(working, baseline_options);
        setting.score.Add(ScoreObjects(ToOriginal(superpixels.labels, image->bgr.size()), objects,
                                       gt_classes, *table, min_object_fraction),
                          *table);
      }
      if (!gt_classes.empty() && !table->empty()) {
        TallyTrueRegions(*organizer, working, *image, *table, options, min_object_fraction,
                         &background, &salient_background);
        pixels.Add(segments, segmentation.classes, gt_classes, *table);
      }
    }
    if (!quiet) progress.Report(i + 1, "segmented %zu/%zu", i + 1, ids->size());
  }

  nlohmann::json report;
  report["dataset"] = dataset;
  report["split"] = split;
  report["images"] = static_cast<int>(ids->size());
  report["scored_images"] = scored_images;
  report["mean_segments_per_image"] =
      ids->empty() ? 0.0 : static_cast<double>(segments_total) / static_cast<double>(ids->size());
  report["min_object_fraction"] = min_object_fraction;
  report["options"] = OptionsJson(options, organizer->model().classifier.structured_names());
  report["options"]["oracle_classes"] = oracle_classes;
  report["options"]["oracle_grouping"] = oracle_grouping;
  for (const auto& [stage, ms] : stage_ms) {
    report["mean_ms"][stage] = ids->empty() ? 0.0 : ms / static_cast<double>(ids->size());
  }
  if (scored_images > 0) {
    report["perceptual_organization"] = po_score.ToJson();
    if (!grid.empty()) {
      const GridSetting* best = &grid[0];
      nlohmann::json settings = nlohmann::json::array();
      for (const GridSetting& setting : grid) {
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
    if (background.total > 0) {
      report["background"]["ground_truth_regions"] = background.ToJson();
      report["background"]["salient_ground_truth_regions"] = salient_background.ToJson();
      report["background"]["salient_ground_truth_regions"]["min_region_fraction"] =
          min_object_fraction;
      report["background"]["output_pixels"] = pixels.ToJson();
    }
  } else {
    report["note"] = "no ground truth (objects/) in the dataset: nothing scored";
  }
  report["seconds"] = total_timer.ElapsedMs() / 1000.0;
  std::ofstream file(out + "/segmentation.json");
  file << report.dump(2) << "\n";
  std::ofstream rows(out + "/per_image.csv");
  rows << per_image;
  if (!file || !rows) {
    std::fprintf(stderr,
                 "placerec-eval segment: cannot write %s/segmentation.json or per_image.csv\n",
                 out.c_str());
    return 1;
  }
  if (scored_images > 0) {
    char learned[64];
    std::snprintf(learned, sizeof(learned), "learned merging (threshold %g)",
                  options.merge.threshold);
    const std::string method =
        oracle_grouping         ? "superpixels grouped by the ground truth (oracle)"
        : oracle_classes        ? "seed's Perceptual Organization on ground-truth classes (oracle)"
        : options.learned_merge ? std::string(learned)
                                : "seed's Perceptual Organization";
    const Status chart = WriteSegmentSummaryChart(report, method, out + "/summary.png");
    if (!chart.ok()) {
      std::fprintf(stderr, "placerec-eval segment: %s\n", chart.ToString().c_str());
      return 1;
    }
  }
  std::printf("%s: %zu images, %.1f segments per image, %.1f ms per image\n", split.c_str(),
              ids->size(), report["mean_segments_per_image"].get<double>(),
              report["mean_ms"].value("total", 0.0));
  if (scored_images > 0) {
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
              out.c_str(), scored_images > 0 ? ", summary.png" : "");
  return 0;
}

}  // namespace placerec
