#include "common/training/grouping_training.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <numeric>
#include <random>

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

// Ground-truth object votes of a region and their majority.
struct Votes {
  std::map<int, int> counts;  // object id (0: none) -> pixels
  int total = 0;

  // The majority object when it is a real object covering at least `min_purity`; else -1.
  int Majority(double min_purity) const {
    int best = -1;
    int best_count = 0;
    for (const auto& [object, count] : counts) {
      if (count > best_count) {
        best = object;
        best_count = count;
      }
    }
    if (best <= 0 || best_count < min_purity * total) return -1;
    return best;
  }
  void Add(const Votes& other) {
    for (const auto& [object, count] : other.counts) counts[object] += count;
    total += other.total;
  }
};

struct PairSample {
  cv::Mat features;
  std::vector<int> labels;
};

// Appends the pair (a, b) labelled "same object" or not by its regions' majority objects; a
// pair with an impure or unlabelled region is left out.
void RecordPair(const MergeState& state, const std::vector<Votes>& votes, int a, int b,
                double min_purity, PairSample* sample) {
  const int ma = votes[a].Majority(min_purity);
  const int mb = votes[b].Majority(min_purity);
  if (ma < 0 || mb < 0) return;
  float row[kMergeFeatures];
  state.PairFeatures(a, b, row);
  sample->features.push_back(cv::Mat(1, kMergeFeatures, CV_32F, row));
  sample->labels.push_back(ma == mb ? 1 : 0);
}

// Records the pairs of `state` with a changed region (all when `changed` is empty).
void Record(const MergeState& state, const std::vector<Votes>& votes,
            const std::vector<char>& changed, double min_purity, PairSample* sample) {
  for (const auto& [a, b] : state.Pairs()) {
    if (changed.empty() || changed[a] || changed[b]) {
      RecordPair(state, votes, a, b, min_purity, sample);
    }
  }
}

// What the passes need of one training image.
struct TrainingImage {
  int fold = 0;  // which organizer describes it
  SceneSegmentation parts;
  cv::Mat lab;
  cv::Mat appearance;
  cv::Mat boundary;  // learned boundary scores on the cracks of parts (empty when not read)
  std::vector<Votes> votes;
};

// At most `max_rows` rows of `sample`, drawn at random.
PairSample Subsample(const PairSample& sample, int max_rows, std::mt19937_64* rng) {
  if (max_rows <= 0 || sample.features.rows <= max_rows) return sample;
  std::vector<int> rows(static_cast<size_t>(sample.features.rows));
  std::iota(rows.begin(), rows.end(), 0);
  std::shuffle(rows.begin(), rows.end(), *rng);
  rows.resize(static_cast<size_t>(max_rows));
  std::sort(rows.begin(), rows.end());
  PairSample out;
  out.features.create(max_rows, kMergeFeatures, CV_32F);
  for (int r = 0; r < max_rows; ++r) {
    sample.features.row(rows[r]).copyTo(out.features.row(r));
    out.labels.push_back(sample.labels[rows[r]]);
  }
  return out;
}

struct TrainedModel {
  RegionMergeModel model;
  int pairs = 0;
  int positives = 0;
  double same_object_recall = 0;
  double different_object_recall = 0;
  double seconds = 0;
};

// Trains on (a random subset of) `sample`; positives weigh negatives / positives so the two
// classes weigh alike.
StatusOr<TrainedModel> TrainOn(const PairSample& all, const GroupingTrainingConfig& config,
                               std::mt19937_64* rng) {
  const PairSample sample = Subsample(all, config.max_pairs, rng);
  int positives = 0;
  for (const int l : sample.labels) positives += l;
  const int negatives = static_cast<int>(sample.labels.size()) - positives;
  if (positives == 0 || negatives == 0) {
    return Status::InvalidArgument("training needs both same-object and different-object pairs");
  }
  std::vector<float> weights(sample.labels.size(), 1.0f);
  for (size_t r = 0; r < weights.size(); ++r) {
    if (sample.labels[r]) weights[r] = static_cast<float>(negatives) / positives;
  }
  if (config.progress) {
    std::fprintf(stderr, "boosting on %d pairs (%d same object, %d different)\n",
                 sample.features.rows, positives, negatives);
  }
  Timer timer;
  TrainedModel trained;
  trained.model = RegionMergeModel::Train(sample.features.colRange(0, config.features).clone(),
                                          sample.labels, weights, config.boost);
  trained.seconds = timer.ElapsedMs() / 1000.0;
  trained.pairs = sample.features.rows;
  trained.positives = positives;
  const cv::Mat scores = trained.model.Scores(sample.features);
  int true_positives = 0;
  int true_negatives = 0;
  for (int r = 0; r < scores.rows; ++r) {
    const bool merge = scores.at<float>(r) > 0;
    true_positives += merge && sample.labels[r];
    true_negatives += !merge && !sample.labels[r];
  }
  trained.same_object_recall = 100.0 * true_positives / positives;
  trained.different_object_recall = 100.0 * true_negatives / negatives;
  return trained;
}

// Checks that `dir`'s background models left out fold `fold` of the images the grouping model
// trains on (its manifest.json, written by placerec-train background).
// Checks that the training manifest at `path` (background or boundary) left out fold `fold` of
// the images the grouping model trains on.
Status CheckCrossFitManifest(const std::string& path, const Fold& fold,
                             const GroupingTrainingConfig& config) {
  const std::string dir = std::filesystem::path(path).parent_path().string();
  const std::string command =
      std::filesystem::path(path).filename() == "boundary.json" ? "boundary" : "background";
  std::ifstream in(path);
  if (!in)
    return Status::NotFound("cannot read " + path + " (a " + command + " training manifest)");
  const nlohmann::json manifest = nlohmann::json::parse(in, nullptr, false);
  if (manifest.is_discarded() || !manifest.contains("data")) {
    return Status::InvalidArgument(path + " is not a " + command + " training manifest");
  }
  const nlohmann::json& data = manifest["data"];
  const std::string dataset = std::filesystem::path(config.dataset).filename().string();
  if (data.value("dataset", "") != dataset || data.value("split", "") != config.split ||
      data.value("holdout_first_images", -1) != config.holdout ||
      data.value("left_out_fold", "") != fold.ToString()) {
    return Status::InvalidArgument(
        "--cross-fit: " + dir + " holds other " + command +
        " models (its manifest's data: " + data.dump() + "); train them with placerec-train " +
        command + " --dataset " + config.dataset + " --split " + config.split + " --holdout " +
        std::to_string(config.holdout) + " --leave-out-fold " + fold.ToString() + " --out " + dir);
  }
  return Status::Ok();
}

// The options and parameter ranges TrainGroupingModel needs (organizer_options: the organizer's
// with learned merging off).
Status CheckTrainingConfig(const GroupingTrainingConfig& config,
                           const SceneOrganizerOptions& organizer_options) {
  std::string error;
  if (!config.boost.Check(&error) || !organizer_options.Check(&error)) {
    return Status::InvalidArgument(error);
  }
  if (config.levels < 0 || !(config.level_fraction > 0 && config.level_fraction <= 1) ||
      !(config.min_purity > 0 && config.min_purity <= 1) || config.holdout < 0 ||
      config.max_pairs < 0 || !std::isfinite(config.policy_threshold) || config.features < 1 ||
      config.features > kMergeFeatures) {
    return Status::InvalidArgument(
        "levels >= 0, level_fraction and min_purity in (0, 1], holdout and max_pairs >= 0, a "
        "finite policy threshold, features in 1.." +
        std::to_string(kMergeFeatures));
  }
  if (config.cross_fit.size() == 1) {
    return Status::InvalidArgument("--cross-fit needs at least two models directories");
  }
  return Status::Ok();
}

// What describes the training images of each fold: its organizer and, when the grouping features
// read them, its boundary classifier.
struct FoldModels {
  SceneOrganizerOptions organizer_options;
  std::vector<std::string> model_dirs;  // one per fold (cross-fitting), or just `out`
  std::vector<SceneOrganizer> organizers;
  bool reads_boundary = false;
  std::vector<BoundaryModel> boundary_models;
  std::vector<std::string> boundary_sources;  // the directory each boundary model came from

  // The merge state of `t`'s superpixels, as its fold's organizer sees them.
  MergeState NewState(const TrainingImage& t) const {
    const BackgroundModel& model = organizers[static_cast<size_t>(t.fold)].model();
    return MergeState(t.parts.labels, t.parts.size(), t.lab, t.appearance,
                      organizer_options.texton_stride, model.textons.inv_std, model.classifier,
                      organizer_options.background_threshold, organizer_options.one_per_class,
                      t.boundary);
  }
};

// One organizer per fold (cross-fitting), or `out`'s for every image; each cross-fit directory's
// manifest must have left its fold out.
Status MakeOrganizers(const GroupingTrainingConfig& config, FoldModels* m) {
  m->model_dirs =
      config.cross_fit.empty() ? std::vector<std::string>{config.out} : config.cross_fit;
  for (size_t k = 0; k < config.cross_fit.size(); ++k) {
    PLACEREC_RETURN_IF_ERROR(CheckCrossFitManifest(
        m->model_dirs[k] + "/manifest.json",
        Fold{static_cast<int>(k), static_cast<int>(m->model_dirs.size())}, config));
  }
  for (size_t k = 0; k < m->model_dirs.size(); ++k) {
    m->organizer_options.models_dir = m->model_dirs[k];
    StatusOr<SceneOrganizer> organizer = SceneOrganizer::Create(m->organizer_options);
    if (!organizer.ok()) return organizer.status();
    if (!m->organizers.empty() && organizer->model().classifier.structured_names() !=
                                      m->organizers[0].model().classifier.structured_names()) {
      return Status::InvalidArgument("--cross-fit: " + m->model_dirs[k] +
                                     " has other structured classes than " + m->model_dirs[0]);
    }
    m->organizers.push_back(std::move(*organizer));
  }
  return Status::Ok();
}

// The boundary classifier of each fold: from the fold's cross-fit directory when it has one
// (trained without the fold), otherwise from --out.
Status LoadBoundaryModels(const GroupingTrainingConfig& config, FoldModels* m) {
  StatusOr<BoundaryModel> shared = BoundaryModel::Load(config.out);
  if (!shared.ok() && shared.status().code() != StatusCode::kNotFound) return shared.status();
  for (size_t k = 0; k < m->organizers.size(); ++k) {
    const Fold fold{static_cast<int>(k), static_cast<int>(config.cross_fit.size())};
    StatusOr<BoundaryModel> own = config.cross_fit.empty()
                                      ? StatusOr<BoundaryModel>(Status::NotFound(""))
                                      : BoundaryModel::Load(m->model_dirs[k]);
    if (own.ok()) {
      PLACEREC_RETURN_IF_ERROR(
          CheckCrossFitManifest(m->model_dirs[k] + "/boundary.json", fold, config));
      m->boundary_models[k] = std::move(*own);
      m->boundary_sources[k] = m->model_dirs[k];
    } else if (own.status().code() != StatusCode::kNotFound) {
      return own.status();
    } else if (shared.ok()) {
      m->boundary_models[k] = *shared;
      m->boundary_sources[k] = config.out;
    } else {
      return Status::NotFound("--features " + std::to_string(config.features) +
                              " reads learned boundary scores but " + config.out + " has no " +
                              BoundaryModel::kFileName +
                              ": train it first with placerec-train boundary --dataset " +
                              config.dataset + " --out " + config.out);
    }
  }
  return Status::Ok();
}

// Image `ids[i]`'s superpixels (classified by its fold's organizer), appearance, boundary scores
// and ground-truth object votes.
StatusOr<TrainingImage> PrepareImage(const GroupingTrainingConfig& config, const FoldModels& m,
                                     const std::vector<std::string>& ids, size_t i, size_t total) {
  StatusOr<LabelledImage> image = ReadLabelledImage(config.dataset, ids[i]);
  if (!image.ok()) return image.status();
  if (image->objects.empty()) {
    return Status::InvalidArgument(config.dataset + ": image " + ids[i] +
                                   " has no objects/ layer to learn grouping from");
  }
  const WorkingImage working =
      MakeWorkingImage(image->bgr, m.organizer_options.superpixels.working_width);
  TrainingImage t;
  t.fold =
      FoldOf(i - static_cast<size_t>(config.holdout), total, static_cast<int>(m.organizers.size()));
  cv::Mat bank;
  t.parts = m.organizers[static_cast<size_t>(t.fold)].ClassifiedSuperpixels(working, &bank, nullptr,
                                                                            &t.appearance);
  t.lab = working.lab;
  if (m.reads_boundary) {
    t.boundary =
        m.boundary_models[static_cast<size_t>(t.fold)].ScoreMap(bank, CrackPixels(t.parts.labels));
  }
  const cv::Mat objects = LayerAtSize(image->objects, working.bgr.size());
  t.votes.resize(static_cast<size_t>(t.parts.size()));
  for (int y = 0; y < objects.rows; ++y) {
    const int* o = objects.ptr<int>(y);
    const int* l = t.parts.labels.ptr<int>(y);
    for (int x = 0; x < objects.cols; ++x) {
      ++t.votes[l[x]].counts[o[x]];
      ++t.votes[l[x]].total;
    }
  }
  return t;
}

// Records the pairs of `t`'s superpixels, then of each ground-truth merge level: a random
// `level_fraction` of the same-object neighbours merged.
void RecordGroundTruthLevels(const GroupingTrainingConfig& config, const FoldModels& m,
                             const TrainingImage& t, std::mt19937_64* rng, PairSample* sample) {
  std::vector<Votes> votes = t.votes;
  MergeState state = m.NewState(t);
  Record(state, votes, {}, config.min_purity, sample);
  for (int level = 0; level < config.levels; ++level) {
    std::vector<std::pair<int, int>> candidates;
    for (const auto& [a, b] : state.Pairs()) {
      const int ma = votes[a].Majority(config.min_purity);
      if (ma >= 0 && ma == votes[b].Majority(config.min_purity)) candidates.emplace_back(a, b);
    }
    if (candidates.empty()) break;
    std::shuffle(candidates.begin(), candidates.end(), *rng);
    const size_t merge_count = std::max<size_t>(
        1, static_cast<size_t>(config.level_fraction * static_cast<double>(candidates.size())));
    std::vector<char> changed(static_cast<size_t>(state.capacity()), 0);
    for (size_t c = 0; c < merge_count; ++c) {
      const int a = state.Find(candidates[c].first);
      const int b = state.Find(candidates[c].second);
      if (a == b || state.NeighboursOf(a).count(b) == 0) continue;
      state.Merge(a, b);
      votes[a].Add(votes[b]);
      changed[a] = 1;
    }
    Record(state, votes, changed, config.min_purity, sample);
  }
}

// Pass 1: superpixels and ground-truth merge levels of every training image.
Status CollectGroundTruthPairs(const GroupingTrainingConfig& config, const FoldModels& m,
                               const std::vector<std::string>& ids, std::mt19937_64* rng,
                               std::vector<TrainingImage>* images, PairSample* sample) {
  const size_t total = ids.size() - static_cast<size_t>(config.holdout);
  ProgressLine pass1_progress(total, kLogProgressEvery);
  for (size_t i = static_cast<size_t>(config.holdout); i < ids.size(); ++i) {
    StatusOr<TrainingImage> t = PrepareImage(config, m, ids, i, total);
    if (!t.ok()) return t.status();
    RecordGroundTruthLevels(config, m, *t, rng, sample);
    images->push_back(std::move(*t));
    if (config.progress) {
      pass1_progress.Report(images->size(), "pass 1: pairs from %zu/%zu images: %d", images->size(),
                            total, sample->features.rows);
    }
  }
  return Status::Ok();
}

// Pass 2: `model`'s own greedy merging, every pair it meets after a merge.
void CollectOnPolicyPairs(const GroupingTrainingConfig& config, const FoldModels& m,
                          const RegionMergeModel& model, const std::vector<TrainingImage>& images,
                          int pass1_pairs, PairSample* sample) {
  RegionMergeOptions policy;
  policy.threshold = config.policy_threshold;
  size_t done = 0;
  ProgressLine pass2_progress(images.size(), kLogProgressEvery);
  for (const TrainingImage& t : images) {
    std::vector<Votes> votes = t.votes;
    MergeState state = m.NewState(t);
    MergeRegions(model, policy, &state, [&](int a, int b) {
      votes[a].Add(votes[b]);
      for (const auto& [n, edge] : state.NeighboursOf(a)) {
        RecordPair(state, votes, a, n, config.min_purity, sample);
      }
    });
    ++done;
    if (config.progress) {
      pass2_progress.Report(done, "pass 2: pairs from %zu/%zu images: %d", done, images.size(),
                            sample->features.rows - pass1_pairs);
    }
  }
}

// What grouping.json holds.
nlohmann::json GroupingManifest(const GroupingTrainingConfig& config, const FoldModels& m,
                                int images, double pairs_seconds, const nlohmann::json& passes) {
  const BackgroundModel& background = m.organizers[0].model();
  nlohmann::json manifest;
  manifest["format_version"] = RegionMergeModel::kFormatVersion;
  manifest["created"] = TodayUtc();
  manifest["file"] = RegionMergeModel::kFileName;
  if (!config.command_line.empty()) manifest["command"] = config.command_line;
  manifest["data"] = {{"dataset", std::filesystem::path(config.dataset).filename().string()},
                      {"split", config.split},
                      {"holdout_first_images", config.holdout},
                      {"cross_fit_folds", static_cast<int>(config.cross_fit.size())},
                      {"cross_fit_models", config.cross_fit},
                      {"images", images}};
  manifest["pairs"] = {{"levels", config.levels},         {"level_fraction", config.level_fraction},
                       {"min_purity", config.min_purity}, {"max_pairs", config.max_pairs},
                       {"on_policy", config.on_policy},   {"pass1_seconds", pairs_seconds}};
  manifest["passes"] = passes;
  manifest["boost"] = {{"type", "gentle"},
                       {"weak_count", config.boost.weak_count},
                       {"max_depth", config.boost.max_depth},
                       {"weight_trim_rate", config.boost.weight_trim_rate},
                       {"features", config.features}};
  manifest["background_decision"] = {
      {"threshold", m.organizer_options.background_threshold},
      {"one_per_class", m.organizer_options.one_per_class},
      {"structured_classes", background.classifier.structured_names()}};
  manifest["seed"] = config.seed;
  if (m.reads_boundary) {
    // The boundary model that describes the pairs of each fold, with its manifest.
    for (const std::string& dir : m.boundary_sources) {
      std::ifstream in(dir + "/boundary.json");
      manifest["boundary_models"].push_back(
          {{"directory", dir},
           {"manifest", in ? nlohmann::json::parse(in, nullptr, false) : nlohmann::json()}});
    }
  }
  return manifest;
}

}  // namespace

bool GroupingTrainingConfig::Check(std::string* error) const {
  if (!CheckNotEmpty("dataset", dataset, error) || !CheckNotEmpty("split", split, error) ||
      !CheckNotEmpty("out", out, error)) {
    return false;
  }
  if (holdout < 0) {
    *error = "holdout must be at least 0, got " + std::to_string(holdout);
    return false;
  }
  if (levels < 0) {
    *error = "levels must be at least 0, got " + std::to_string(levels);
    return false;
  }
  if (!(level_fraction > 0.0 && level_fraction <= 1.0)) {
    *error = "level_fraction must be in (0, 1], got " + std::to_string(level_fraction);
    return false;
  }
  if (!(min_purity > 0.0 && min_purity <= 1.0)) {
    *error = "min_purity must be in (0, 1], got " + std::to_string(min_purity);
    return false;
  }
  if (!std::isfinite(policy_threshold)) {
    *error = "policy_threshold must be finite";
    return false;
  }
  if (max_pairs < 0) {
    *error = "max_pairs must be at least 0 (0: all), got " + std::to_string(max_pairs);
    return false;
  }
  if (features < 1 || features > kMergeFeatures) {
    *error = "features must be in 1.." + std::to_string(kMergeFeatures) + ", got " +
             std::to_string(features);
    return false;
  }
  if (cross_fit.size() == 1) {
    *error = "cross_fit needs at least two models directories";
    return false;
  }
  for (const std::string& dir : cross_fit) {
    if (!CheckNotEmpty("a cross_fit directory", dir, error)) return false;
  }
  SceneOrganizerOptions organizer_options = organizer;
  organizer_options.learned_merge = false;
  return boost.Check(error) && organizer_options.Check(error);
}

StatusOr<nlohmann::json> TrainGroupingModel(const GroupingTrainingConfig& config) {
  FoldModels m;
  m.organizer_options = config.organizer;
  m.organizer_options.learned_merge = false;
  PLACEREC_RETURN_IF_ERROR(CheckTrainingConfig(config, m.organizer_options));
  StatusOr<std::vector<std::string>> ids = ReadSplit(config.dataset, config.split);
  if (!ids.ok()) return ids.status();
  if (static_cast<int>(ids->size()) <= config.holdout) {
    return Status::InvalidArgument("the holdout leaves no training image");
  }
  PLACEREC_RETURN_IF_ERROR(MakeOrganizers(config, &m));
  m.reads_boundary = config.features > kMergeBoundaryOffset;
  m.boundary_models.resize(m.organizers.size());
  m.boundary_sources.resize(m.organizers.size());
  if (m.reads_boundary) PLACEREC_RETURN_IF_ERROR(LoadBoundaryModels(config, &m));

  // Pass 1: superpixels and ground-truth merge levels.
  Timer timer;
  PairSample sample;
  std::mt19937_64 rng(config.seed);
  std::vector<TrainingImage> images;
  PLACEREC_RETURN_IF_ERROR(CollectGroundTruthPairs(config, m, *ids, &rng, &images, &sample));
  const double pairs_seconds = timer.ElapsedMs() / 1000.0;
  const int pass1_pairs = sample.features.rows;
  StatusOr<TrainedModel> trained = TrainOn(sample, config, &rng);
  if (!trained.ok()) return trained.status();
  nlohmann::json passes;
  passes.push_back({{"pairs", pass1_pairs},
                    {"trained_on", trained->pairs},
                    {"same_object_recall", trained->same_object_recall},
                    {"different_object_recall", trained->different_object_recall},
                    {"boosting_seconds", trained->seconds}});

  // Pass 2: the first model's own greedy merging, every pair it meets after a merge.
  if (config.on_policy) {
    timer.Restart();
    CollectOnPolicyPairs(config, m, trained->model, images, pass1_pairs, &sample);
    const double policy_seconds = timer.ElapsedMs() / 1000.0;
    trained = TrainOn(sample, config, &rng);
    if (!trained.ok()) return trained.status();
    passes.push_back({{"pairs", sample.features.rows - pass1_pairs},
                      {"policy_threshold", config.policy_threshold},
                      {"pairs_seconds", policy_seconds},
                      {"trained_on", trained->pairs},
                      {"same_object_recall", trained->same_object_recall},
                      {"different_object_recall", trained->different_object_recall},
                      {"boosting_seconds", trained->seconds}});
  }
  PLACEREC_RETURN_IF_ERROR(trained->model.Save(config.out));

  nlohmann::json manifest =
      GroupingManifest(config, m, static_cast<int>(images.size()), pairs_seconds, passes);
  PLACEREC_RETURN_IF_ERROR(WriteManifest(config.out + "/grouping.json", manifest));
  return manifest;
}

}  // namespace placerec
