// placerec-train: learns the models that ship in models/.
//   placerec-train background --dataset DIR --out models/
// learns the textons and the five background classifiers (seed §3.4) from DIR's train split and
// writes them with manifest.json (data, split, options, accuracy, date).
//   placerec-train grouping --dataset DIR --out models/
// learns the region-merge classifier (region_merging.h) from DIR's object ground truth with the
// textons and classifiers already in --out, and writes grouping.yml.gz and grouping.json.
//   placerec-train boundary --dataset DIR --out models/
// learns the boundary classifier (boundary.h) the grouping model's boundary features read.
//   placerec-train objects --dataset DIR --out models/objects
// learns the object classifiers of seed Ch. 4 (feature selection, one classifier per class) from
// DIR's ground-truth object segments (common/training/object_training.h).
#include <cstdio>
#include <cstring>
#include <fstream>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include <opencv2/core/utility.hpp>

#include "common/organization/organizer_flags.h"
#include "common/training/background_training.h"
#include "common/training/boundary_training.h"
#include "common/training/grouping_training.h"
#include "common/training/object_training.h"
#include "common/util/csv.h"
#include "common/util/logging.h"
#include "common/util/options.h"
#include "common/util/paths.h"

namespace placerec {
namespace {

constexpr char kUsage[] =
    "placerec-train COMMAND [options]\n\n"
    "Commands:\n"
    "  background   textons and background classifiers (seed §3.4) from a labelled dataset\n"
    "  boundary     the learned object-boundary classifier the grouping reads\n"
    "  grouping     the learned region-merge classifier, from a dataset's object ground truth\n"
    "  grouping-ensemble\n"
    "               one grouping model that averages the scores of trained ones\n"
    "  objects      object classifiers (seed Ch. 4: feature selection, one per class) from a\n"
    "               dataset's ground-truth object segments\n\n"
    "'placerec-train COMMAND --help' lists the options of a command.";

// The flags of a training command that are text (or a switch) on the command line and reach
// the config only once parsed, by FinishConfig. Their defaults are the config's (MakeTextFlags).
struct TextFlags {
  std::string datasets;            // --dataset DIR,...,DIR (background)
  std::string leave_out_fold;      // --leave-out-fold I/K (background, boundary)
  std::string structured_classes;  // --structured-classes a,b,... / all / none (background)
  std::string cross_fit;           // --cross-fit DIR,...,DIR (grouping)
  bool quiet = false;              // --quiet: no progress lines
};

// `items` joined with commas; `none` when there are none.
std::string JoinList(const std::vector<std::string>& items, const std::string& none) {
  if (items.empty()) return none;
  std::string text;
  for (const std::string& item : items) text += (text.empty() ? "" : ",") + item;
  return text;
}

// The non-empty items of a comma-separated list.
std::vector<std::string> SplitList(const std::string& text) {
  std::vector<std::string> items;
  for (const std::string& item : SplitString(text, ',')) {
    if (!item.empty()) items.push_back(item);
  }
  return items;
}

// The text flags' defaults: the values of a default `config`.
template <typename Config>
TextFlags MakeTextFlags(const Config& config) {
  TextFlags flags;
  if constexpr (std::is_same_v<Config, GroupingTrainingConfig>) {
    flags.cross_fit = JoinList(config.cross_fit, "");
  } else {
    flags.leave_out_fold = config.leave_out_fold.ToString();
  }
  if constexpr (std::is_same_v<Config, BackgroundTrainingConfig>) {
    flags.datasets = JoinList(config.datasets, "");
    flags.structured_classes = JoinList(config.structured_classes, "none");
  }
  flags.quiet = !config.progress;
  return flags;
}

// Moves the parsed text flags and the invocation into *config, then checks it. On an error
// prints it for `command` and returns the exit code (2: bad flags).
template <typename Config>
std::optional<int> FinishConfig(const char* command, const TextFlags& flags, int argc, char** argv,
                                Config* config) {
  if constexpr (std::is_same_v<Config, GroupingTrainingConfig>) {
    config->cross_fit = SplitList(flags.cross_fit);
  } else {
    StatusOr<Fold> fold = ParseFold(flags.leave_out_fold);
    if (!fold.ok()) {
      std::fprintf(stderr, "%s: --leave-out-fold: %s\n", command, fold.status().ToString().c_str());
      return 2;
    }
    config->leave_out_fold = *fold;
  }
  if constexpr (std::is_same_v<Config, BackgroundTrainingConfig>) {
    config->datasets = SplitList(flags.datasets);
    config->structured_classes.clear();
    if (flags.structured_classes != "none") {
      config->structured_classes = SplitList(flags.structured_classes);
    }
    config->textons.seed = config->seed;
    config->boost.seed = config->seed;
  }
  config->progress = !flags.quiet;
  config->command_line = CommandLine(argc, argv);
  std::string error;
  if (!config->Check(&error)) {
    std::fprintf(stderr, "%s: %s\n", command, error.c_str());
    return 2;
  }
  return std::nullopt;
}

// Prints a training run's manifest, or its error, and returns the exit code.
int ReportTraining(const char* command, const StatusOr<nlohmann::json>& manifest) {
  if (!manifest.ok()) {
    std::fprintf(stderr, "%s: %s\n", command, manifest.status().ToString().c_str());
    return 1;
  }
  std::printf("%s\n", manifest->dump(2).c_str());
  return 0;
}

int BackgroundCommand(int argc, char** argv) {
  BackgroundTrainingConfig config;
  TextFlags flags = MakeTextFlags(config);
  FlagParser parser(
      "placerec-train background --dataset DIR --out DIR [options]\n\n"
      "Learns k-means textons on filter-bank responses of pixels sampled from DIR's training\n"
      "images, then five binary Gentle AdaBoost classifiers (sky, tree, road, grass, water) on\n"
      "the texton histograms of their superpixels and ground-truth regions (and one per\n"
      "structured class, for the one-per-class decision), and writes\n"
      "textons.yml, background*.yml*, check_sample.yml.gz and manifest.json into --out.\n"
      "--dataset A,B,C trains on the union of their training images and scores each test\n"
      "split on its own.");
  parser.AddRequired("dataset", &flags.datasets,
                     "labelled dataset (layout of shared/data/README.md), e.g. "
                     "../shared/data/stanford_background, or several, comma-separated");
  parser.AddRequired("out", &config.out, "models directory to write (created if missing)");
  parser.Add("split", &config.split, "split to train on");
  parser.Add("eval-split", &config.eval_split, "split whose accuracy goes into the manifest");
  parser.Add("pixels-per-image", &config.pixels_per_image, "pixels sampled per image for k-means");
  parser.Add("textons", &config.textons.k, "number of textons (seed §4.1.1: 150)");
  parser.Add("textons-file", &config.textons_file,
             "read the textons from this file (e.g. models/textons.yml) instead of learning them");
  parser.Add("standardise", &config.textons.standardise,
             "standardise filter responses before k-means");
  parser.Add("kmeans-iterations", &config.textons.max_iterations, "k-means iterations");
  parser.Add("weak-count", &config.boost.weak_count, "boosted trees per classifier");
  parser.Add("max-depth", &config.boost.max_depth, "depth of each boosted tree");
  parser.Add("negatives-per-positive", &config.boost.max_negatives_per_positive,
             "negatives drawn per positive region (0: all)");
  parser.Add("appearance-extras", &config.appearance_extras,
             "region features: texton histogram and height plus the mean and standard deviation "
             "of the 20 filter-bank features (false: the seed's 151 numbers only)");
  parser.Add("superpixel-regions", &config.superpixel_regions, "train on superpixels");
  parser.Add("ground-truth-regions", &config.ground_truth_regions,
             "also train on ground-truth object regions");
  parser.Add("min-region-pixels", &config.min_region_pixels,
             "training regions have at least this many working pixels");
  parser.Add("area-weight-power", &config.area_weight_power,
             "initial boosting weight of a region: its area to this power (0: all alike)");
  parser.Add("check-images", &config.check_images,
             "images of --eval-split whose regions form the stored check sample");
  parser.Add("seed", &config.seed, "random seed (pixel sampling, negatives)");
  parser.Add("holdout", &config.holdout,
             "leave the first N images of --split out of training (validation)");
  parser.Add("leave-out-fold", &flags.leave_out_fold,
             "I/K: also leave out fold I of the images after the holdout, cut into K contiguous "
             "folds (models for placerec-train grouping --cross-fit)");
  parser.Add("structured-classes", &flags.structured_classes,
             "comma-separated dataset classes that get a classifier of their own for the "
             "one-per-class decision ('all': every labelled non-background class; 'none')");
  AddBackgroundDecisionFlags(&parser, &config.organizer);  // of the reported accuracy
  parser.AddSwitch("quiet", &flags.quiet, "no progress lines");
  if (const std::optional<int> exit =
          parser.ParseOrExit(argc, argv, 2, "placerec-train background")) {
    return *exit;
  }
  if (const std::optional<int> exit =
          FinishConfig("placerec-train background", flags, argc, argv, &config)) {
    return *exit;
  }
  cv::setNumThreads(1);  // deterministic k-means, and a fair share of a shared machine
  return ReportTraining("placerec-train background", TrainBackgroundModels(config));
}

int BoundaryCommand(int argc, char** argv) {
  BoundaryTrainingConfig config;
  TextFlags flags = MakeTextFlags(config);
  FlagParser parser(
      "placerec-train boundary --dataset DIR --out DIR [options]\n\n"
      "Learns the object-boundary classifier (common/organization/boundary.h): the pixels on\n"
      "the superpixel boundaries of DIR's training images, labelled by whether a ground-truth\n"
      "object boundary runs there, described by filter-bank differences across them in four\n"
      "directions at three distances, and a Gentle AdaBoost classifier on them. Writes\n"
      "boundary.yml.gz and boundary.json (data, options, accuracy) into --out. Grouping models\n"
      "trained with --features 48 read it.");
  parser.AddRequired("dataset", &config.dataset,
                     "labelled dataset with objects/ (layout of shared/data/README.md)");
  parser.AddRequired("out", &config.out, "models directory to write (created if missing)");
  parser.Add("split", &config.split, "split to train on");
  parser.Add("eval-split", &config.eval_split,
             "split whose accuracy goes into the manifest ('' to skip)");
  parser.Add("holdout", &config.holdout,
             "leave the first N images of --split out of training (their accuracy is reported)");
  parser.Add("leave-out-fold", &flags.leave_out_fold,
             "I/K: also leave out fold I of the images after the holdout (a boundary model for "
             "the fold's directory of placerec-train grouping --cross-fit)");
  parser.Add("samples-per-image", &config.samples_per_image,
             "pixels drawn per image on object boundaries, and as many off them");
  parser.Add("positive-distance", &config.positive_distance,
             "a pixel this close (working pixels) to an object boundary is on it");
  parser.Add("negative-distance", &config.negative_distance,
             "a pixel at least this far from every object boundary is off them");
  parser.Add("weak-count", &config.boost.weak_count, "boosted trees");
  parser.Add("max-depth", &config.boost.max_depth, "depth of each tree");
  parser.Add("seed", &config.seed, "random seed (pixel sampling)");
  parser.AddSwitch("quiet", &flags.quiet, "no progress lines");
  if (const std::optional<int> exit =
          parser.ParseOrExit(argc, argv, 2, "placerec-train boundary")) {
    return *exit;
  }
  if (const std::optional<int> exit =
          FinishConfig("placerec-train boundary", flags, argc, argv, &config)) {
    return *exit;
  }
  cv::setNumThreads(1);
  return ReportTraining("placerec-train boundary", TrainBoundaryModel(config));
}

int GroupingCommand(int argc, char** argv) {
  GroupingTrainingConfig config;
  TextFlags flags = MakeTextFlags(config);
  FlagParser parser(
      "placerec-train grouping --dataset DIR --out DIR [options]\n\n"
      "Learns the region-merge classifier: pairs of adjacent regions (the superpixels of DIR's\n"
      "training images, and the larger regions their ground-truth objects form) labelled\n"
      "'same object' or not, described by colour, texture, boundary contrast, shape and\n"
      "background scores, and a Gentle AdaBoost classifier on them. Reads textons.yml and the\n"
      "background classifiers from --out (train those first) and writes grouping.yml.gz and\n"
      "grouping.json there.");
  parser.AddRequired("dataset", &config.dataset,
                     "labelled dataset with objects/ (layout of shared/data/README.md)");
  parser.AddRequired("out", &config.out, "models directory (holds the background models)");
  parser.Add("split", &config.split, "split to train on");
  parser.Add("holdout", &config.holdout,
             "leave the first N images of the split out (to tune the threshold on them)");
  parser.Add("cross-fit", &flags.cross_fit,
             "DIR_0,...,DIR_K-1: describe fold k of the images after the holdout with the "
             "background models in DIR_k, trained with --holdout N --leave-out-fold k/K (so the "
             "pairs' background scores are those of unseen images; --out then only receives "
             "the model; a DIR_k with boundary.yml.gz, trained with the same --holdout and "
             "--leave-out-fold, also gives fold k's boundary scores)");
  parser.Add("levels", &config.levels, "ground-truth merge levels recorded after the superpixels");
  parser.Add("level-fraction", &config.level_fraction,
             "share of the same-object pairs each level merges");
  parser.Add("min-purity", &config.min_purity,
             "regions whose majority object covers less than this are not trained on");
  parser.Add("on-policy", &config.on_policy,
             "second pass: train again with the pairs the first model's own merging meets");
  parser.Add("policy-threshold", &config.policy_threshold,
             "second pass: the first model merges while its best score exceeds this");
  parser.Add("max-pairs", &config.max_pairs, "train each model on at most N random pairs (0: all)");
  parser.Add("features", &config.features,
             "pair features the model reads: the 33 relational ones, 42 with the structured "
             "classes' scores (needs background classifiers trained with structured classes), "
             "48 with the learned boundary scores (needs boundary.yml.gz in --out: "
             "placerec-train boundary), 88 with the pair's place in appearance space");
  // The regions' background classes while pairs are described (the shipped model: threshold
  // 0, one-per-class; models/README.md).
  AddBackgroundDecisionFlags(&parser, &config.organizer);
  parser.Add("weak-count", &config.boost.weak_count, "boosted trees");
  parser.Add("max-depth", &config.boost.max_depth, "depth of each tree");
  parser.Add("seed", &config.seed, "random seed (order of the ground-truth merges)");
  parser.AddSwitch("quiet", &flags.quiet, "no progress lines");
  if (const std::optional<int> exit =
          parser.ParseOrExit(argc, argv, 2, "placerec-train grouping")) {
    return *exit;
  }
  if (const std::optional<int> exit =
          FinishConfig("placerec-train grouping", flags, argc, argv, &config)) {
    return *exit;
  }
  cv::setNumThreads(1);
  return ReportTraining("placerec-train grouping", TrainGroupingModel(config));
}

int GroupingEnsembleCommand(int argc, char** argv) {
  std::string members;
  std::string out;
  FlagParser parser(
      "placerec-train grouping-ensemble --members DIR,DIR[,...] --out DIR\n\n"
      "Combines the grouping models (grouping.yml.gz) of several models directories into one\n"
      "whose score is the mean of theirs, and writes it with grouping.json (the members'\n"
      "manifests) into --out.");
  parser.AddRequired("members", &members, "comma-separated models directories to combine");
  parser.AddRequired("out", &out, "models directory to write (created if missing)");
  if (const std::optional<int> exit =
          parser.ParseOrExit(argc, argv, 2, "placerec-train grouping-ensemble")) {
    return *exit;
  }
  std::vector<RegionMergeModel> models;
  nlohmann::json manifest;
  manifest["format_version"] = RegionMergeModel::kFormatVersion;
  manifest["file"] = RegionMergeModel::kFileName;
  manifest["command"] = CommandLine(argc, argv);
  for (const std::string& dir : SplitString(members, ',')) {
    if (dir.empty()) continue;
    StatusOr<RegionMergeModel> model = RegionMergeModel::Load(dir);
    if (!model.ok()) {
      std::fprintf(stderr, "placerec-train grouping-ensemble: %s\n",
                   model.status().ToString().c_str());
      return 1;
    }
    models.push_back(std::move(*model));
    nlohmann::json member = {{"directory", dir}};
    std::ifstream in(dir + "/grouping.json");
    if (in) member["manifest"] = nlohmann::json::parse(in, nullptr, false);
    manifest["members"].push_back(member);
  }
  if (models.size() < 2) {
    std::fprintf(stderr, "placerec-train grouping-ensemble: --members needs at least two\n");
    return 2;
  }
  if (!MakeDirectories(out)) {
    std::fprintf(stderr, "placerec-train grouping-ensemble: cannot create or write in %s\n",
                 out.c_str());
    return 1;
  }
  const RegionMergeModel ensemble = RegionMergeModel::Ensemble(models);
  if (const Status status = ensemble.Save(out); !status.ok()) {
    std::fprintf(stderr, "placerec-train grouping-ensemble: %s\n", status.ToString().c_str());
    return 1;
  }
  if (const Status status = WriteManifest(out + "/grouping.json", manifest); !status.ok()) {
    std::fprintf(stderr, "placerec-train grouping-ensemble: %s\n", status.ToString().c_str());
    return 1;
  }
  std::printf("%d classifiers from %zu models written to %s/%s\n", ensemble.members(),
              models.size(), out.c_str(), RegionMergeModel::kFileName);
  return 0;
}

int ObjectsCommand(int argc, char** argv) {
  ObjectTrainingConfig config;
  std::string exclude;
  bool quiet = false;
  FlagParser parser(
      "placerec-train objects --dataset DIR --out DIR [options]\n\n"
      "Describes every ground-truth object segment of DIR's training split (seed §4.1: texton\n"
      "appearance, parts layout, Poisson shape; objects/ and classes/ layers and classes.txt\n"
      "required), selects each class's features (seed §4.2: information gain eq. 4.8, then an\n"
      "AdaBoost wrapper) and trains one Gentle AdaBoost classifier per class on them; the\n"
      "multiclass decision is one-per-class (placerec-eval classify). Writes all/ (the model),\n"
      "the ablation's appearance/, appearance_parts/, appearance_shape/ and full/ (seed Tables\n"
      "6.5-6.6), textons.yml and manifest.json into --out.");
  parser.AddRequired("dataset", &config.dataset,
                     "labelled dataset (layout of shared/data/README.md), e.g. "
                     "../shared/data/msrc_v2");
  parser.AddRequired("out", &config.out, "directory to write (created), e.g. models/objects");
  parser.Add("split", &config.split, "split to train on");
  parser.Add("textons", &config.textons,
             "textons.yml to describe with (default: the shipped models/textons.yml)");
  parser.Add("exclude-classes", &exclude,
             "comma-separated dataset classes to leave out (msrc_v2: horse,mountain gives the "
             "seed's MSRC-21)");
  parser.Add("min-class-segments", &config.min_class_segments,
             "classes with fewer training segments get no classifier");
  parser.Add("min-object-pixels", &config.segments.min_object_pixels,
             "smaller ground-truth objects are not used (image pixels)");
  parser.Add("max-segments-per-class", &config.segments.max_segments_per_class,
             "train on at most N random segments per class (0: all)");
  parser.Add("weak-count", &config.classifier.weak_count, "boosted trees per class classifier");
  parser.Add("max-depth", &config.classifier.max_depth, "depth of each boosted tree");
  parser.Add("bins", &config.classifier.selection.bins,
             "quantile bins per feature for the information gain (eq. 4.8)");
  parser.Add("parts-candidates", &config.classifier.selection.parts_layout_candidates,
             "parts-layout candidates of highest gain (seed §4.2: 50)");
  parser.Add("wrapper-weak-count", &config.classifier.selection.wrapper_weak_count,
             "boosted trees of the wrapper's cross-validated classifier");
  parser.Add("folds", &config.classifier.selection.folds, "the wrapper's cross-validation folds");
  parser.Add("wrapper-negatives-per-positive",
             &config.classifier.selection.max_negatives_per_positive,
             "negatives the wrapper sees per positive (0: all)");
  parser.Add("spouses", &config.classifier.selection.add_spouses,
             "stage 3 of seed §4.2: try the children's parents");
  parser.Add("ablation", &config.ablation,
             "also train the feature-group and full-set variants (seed Tables 6.5, 6.6)");
  parser.Add("threads", &config.classifier.threads, "classes trained at a time");
  parser.Add("seed", &config.classifier.selection.seed, "random seed (folds, negatives)");
  parser.AddSwitch("quiet", &quiet, "no progress lines");
  if (const std::optional<int> exit = parser.ParseOrExit(argc, argv, 2, "placerec-train objects")) {
    return *exit;
  }
  config.exclude_classes = SplitList(exclude);
  config.segments.seed = config.classifier.selection.seed;
  config.progress = !quiet;
  config.command_line = CommandLine(argc, argv);
  std::string error;
  if (!config.Check(&error)) {
    std::fprintf(stderr, "placerec-train objects: %s\n", error.c_str());
    return 2;
  }
  cv::setNumThreads(1);
  return ReportTraining("placerec-train objects", TrainObjectModels(config));
}

}  // namespace
}  // namespace placerec

int main(int argc, char** argv) {
  placerec::InitLogging(argv[0]);
  if (argc < 2 || std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0) {
    std::printf("%s\n", placerec::kUsage);
    return argc < 2 ? 2 : 0;
  }
  if (std::strcmp(argv[1], "background") == 0) return placerec::BackgroundCommand(argc, argv);
  if (std::strcmp(argv[1], "boundary") == 0) return placerec::BoundaryCommand(argc, argv);
  if (std::strcmp(argv[1], "grouping") == 0) return placerec::GroupingCommand(argc, argv);
  if (std::strcmp(argv[1], "objects") == 0) return placerec::ObjectsCommand(argc, argv);
  if (std::strcmp(argv[1], "grouping-ensemble") == 0) {
    return placerec::GroupingEnsembleCommand(argc, argv);
  }
  std::fprintf(stderr, "placerec-train: unknown command '%s'\n%s\n", argv[1], placerec::kUsage);
  return 2;
}
