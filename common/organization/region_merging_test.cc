#include "common/organization/region_merging.h"

#include <cmath>
#include <filesystem>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "common/organization/filter_bank.h"
#include "common/organization/scene_organizer.h"
#include "common/organization/textons.h"
#include "common/segmentation/region_graph.h"

namespace placerec {
namespace {

// The shipped textons and background classifiers (models/, part of the repository); null, with
// a failure saying why, when they do not load: the tests that need them fail then.
std::shared_ptr<const BackgroundModel> ShippedModel() {
  StatusOr<std::shared_ptr<const BackgroundModel>> model = LoadBackgroundModel(PLACEREC_MODELS_DIR);
  if (!model.ok()) {
    ADD_FAILURE() << "the shipped models in " << PLACEREC_MODELS_DIR
                  << " do not load: " << model.status().ToString();
    return nullptr;
  }
  return *model;
}

// A 64 x 48 CIE Lab image of four noisy colour blocks and its labels: the blocks, each cut
// into a left and a right half (8 regions).
struct Scene {
  cv::Mat lab;     // CV_32FC3
  cv::Mat labels;  // CV_32S
  int regions = 8;
};

Scene MakeScene() {
  Scene scene;
  const int w = 64;
  const int h = 48;
  cv::Mat bgr(h, w, CV_8UC3);
  const cv::Vec3b colours[4] = {{200, 120, 40}, {40, 160, 60}, {90, 90, 200}, {150, 150, 150}};
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 6.0f);
  scene.labels.create(h, w, CV_32S);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const int block = (y < h / 2 ? 0 : 2) + (x < w / 2 ? 0 : 1);
      cv::Vec3b c = colours[block];
      for (int k = 0; k < 3; ++k) c[k] = cv::saturate_cast<uchar>(c[k] + noise(rng));
      bgr.at<cv::Vec3b>(y, x) = c;
      const int half = (x % (w / 2)) < w / 4 ? 0 : 1;
      scene.labels.at<int>(y, x) = block * 2 + half;
    }
  }
  cv::Mat bgr_float;
  bgr.convertTo(bgr_float, CV_32F, 1.0 / 255.0);
  cv::cvtColor(bgr_float, scene.lab, cv::COLOR_BGR2Lab);
  return scene;
}

cv::Mat AppearanceOf(const BackgroundModel& model, const cv::Mat& lab, const cv::Mat& labels,
                     int regions, int stride) {
  const TextonAssigner assigner(model.textons);
  const cv::Mat features = ComputeFilterBank(lab);
  return RegionAppearance(labels, regions, ComputeTextonMap(features, assigner, stride), features,
                          assigner);
}

MergeState StateOf(const BackgroundModel& model, const cv::Mat& lab, const cv::Mat& labels,
                   int regions, const cv::Mat& boundary = cv::Mat()) {
  constexpr int kStride = 2;
  return MergeState(labels, regions, lab, AppearanceOf(model, lab, labels, regions, kStride),
                    kStride, model.textons.inv_std, model.classifier, 0.0,
                    /*one_per_class=*/true, boundary);
}

// A made-up learned boundary score for every pixel, varying in x and y and of both signs.
cv::Mat BoundaryField(cv::Size size) {
  cv::Mat field(size, CV_32F);
  for (int y = 0; y < size.height; ++y) {
    for (int x = 0; x < size.width; ++x) {
      field.at<float>(y, x) = static_cast<float>(std::sin(0.3 * x) + 0.5 * std::cos(0.2 * y));
    }
  }
  return field;
}

TEST(MergeStateTest, PairFeaturesAreSymmetric) {
  const std::shared_ptr<const BackgroundModel> model = ShippedModel();
  ASSERT_NE(model, nullptr);
  const Scene scene = MakeScene();
  const MergeState state = StateOf(*model, scene.lab, scene.labels, scene.regions);
  const std::vector<std::pair<int, int>> pairs = state.Pairs();
  ASSERT_FALSE(pairs.empty());
  for (const auto& [a, b] : pairs) {
    float ab[kMergeFeatures];
    float ba[kMergeFeatures];
    state.PairFeatures(a, b, ab);
    state.PairFeatures(b, a, ba);
    for (int f = 0; f < kMergeFeatures; ++f) {
      EXPECT_FLOAT_EQ(ab[f], ba[f]) << "pair " << a << "," << b << " feature " << f;
    }
  }
}

// The incremental bookkeeping of Merge equals a state built from scratch on the merged labels:
// every pair's features (colour, textons, boundary contrast and lengths, shape, classifier
// scores) agree.
TEST(MergeStateTest, MergedStateEqualsStateBuiltFromMergedLabels) {
  const std::shared_ptr<const BackgroundModel> model = ShippedModel();
  ASSERT_NE(model, nullptr);
  const Scene scene = MakeScene();
  const cv::Mat boundary = BoundaryField(scene.labels.size());
  MergeState state = StateOf(*model, scene.lab, scene.labels, scene.regions, boundary);
  // Join the halves of the top-left block, then that block with the top-right block's left
  // half, then the bottom blocks' inner halves.
  state.Merge(0, 1);
  state.Merge(0, 2);
  state.Merge(5, 6);
  const SceneSegmentation merged = state.Result();
  ASSERT_EQ(merged.size(), 5);
  const MergeState fresh = StateOf(*model, scene.lab, merged.labels, merged.size(), boundary);
  // Map the incremental state's live ids to the compact ids of Result().
  std::vector<int> compact_of(static_cast<size_t>(state.capacity()), -1);
  for (int y = 0; y < scene.labels.rows; ++y) {
    for (int x = 0; x < scene.labels.cols; ++x) {
      compact_of[state.Find(scene.labels.at<int>(y, x))] = merged.labels.at<int>(y, x);
    }
  }
  const std::vector<std::pair<int, int>> pairs = state.Pairs();
  ASSERT_EQ(pairs.size(), fresh.Pairs().size());
  for (const auto& [a, b] : pairs) {
    float incremental[kMergeFeatures];
    float scratch[kMergeFeatures];
    state.PairFeatures(a, b, incremental);
    fresh.PairFeatures(compact_of[a], compact_of[b], scratch);
    for (int f = 0; f < kMergeFeatures; ++f) {
      // The cracks inside a region are those merges removed: a fresh state has none.
      if (f == kMergeInternalBoundary || f == kMergeInternalBoundary + 1) continue;
      EXPECT_NEAR(incremental[f], scratch[f], 1e-3 * (1.0 + std::abs(scratch[f])))
          << "pair " << a << "," << b << " feature " << f;
    }
  }
  for (int r = 0; r < state.capacity(); ++r) {
    if (state.alive(r)) {
      EXPECT_EQ(state.ClassOf(r), fresh.ClassOf(compact_of[r]));
    }
  }
}

// The boundary features are the mean learned score of the common boundary's cracks (each the
// mean of its two pixels) and the share of cracks scoring above 0; zeros without scores.
TEST(MergeStateTest, BoundaryFeaturesReadTheCrackScores) {
  const std::shared_ptr<const BackgroundModel> model = ShippedModel();
  ASSERT_NE(model, nullptr);
  const Scene scene = MakeScene();
  // Regions 0 and 1 (the top-left block's halves) meet along the vertical crack between
  // columns 15 and 16, rows 0..23.
  cv::Mat boundary(scene.labels.size(), CV_32F, cv::Scalar(-1.0f));
  for (int y = 0; y < 12; ++y) {
    boundary.at<float>(y, 15) = 2.0f;
    boundary.at<float>(y, 16) = 4.0f;
  }
  float f[kMergeFeatures];
  StateOf(*model, scene.lab, scene.labels, scene.regions, boundary).PairFeatures(0, 1, f);
  // 12 cracks score (2 + 4) / 2 = 3, the other 12 score -1.
  EXPECT_FLOAT_EQ(f[kMergeBoundaryOffset], 1.0f);
  EXPECT_FLOAT_EQ(f[kMergeBoundaryOffset + 1], 0.5f);         // above 0
  EXPECT_FLOAT_EQ(f[kMergeBoundaryOffset + 2], 0.5f);         // above kStrongBoundary (1)
  EXPECT_FLOAT_EQ(f[kMergeBoundaryOffset + 3], 0.0f);         // below kWeakBoundary (-1)
  EXPECT_EQ(f[kMergeInternalBoundary], kNoInternalBoundary);  // superpixels hold no cracks
  EXPECT_EQ(f[kMergeInternalBoundary + 1], kNoInternalBoundary);
  // Once 0 and 1 are merged, their common boundary is inside the union: against region 2 (the
  // top-right block's left half, no merge yet) it is the larger internal mean.
  MergeState state = StateOf(*model, scene.lab, scene.labels, scene.regions, boundary);
  state.Merge(0, 1);
  state.PairFeatures(0, 2, f);
  EXPECT_FLOAT_EQ(f[kMergeInternalBoundary], kNoInternalBoundary);
  EXPECT_FLOAT_EQ(f[kMergeInternalBoundary + 1], 1.0f);
  StateOf(*model, scene.lab, scene.labels, scene.regions).PairFeatures(0, 1, f);
  for (int k = 0; k < kMergeBoundaryFeatures; ++k) EXPECT_EQ(f[kMergeBoundaryOffset + k], 0.0f);
}

TEST(MergeStateTest, ResultCoversEveryPixelAndFollowsMerges) {
  const std::shared_ptr<const BackgroundModel> model = ShippedModel();
  ASSERT_NE(model, nullptr);
  const Scene scene = MakeScene();
  MergeState state = StateOf(*model, scene.lab, scene.labels, scene.regions);
  state.Merge(3, 2);
  EXPECT_FALSE(state.alive(2));
  EXPECT_EQ(state.Find(2), 3);
  const SceneSegmentation result = state.Result();
  EXPECT_EQ(result.size(), 7);
  EXPECT_EQ(static_cast<int>(result.classes.size()), 7);
  double min_id = 0;
  double max_id = 0;
  cv::minMaxLoc(result.labels, &min_id, &max_id);
  EXPECT_EQ(min_id, 0);
  EXPECT_EQ(max_id, 6);
  EXPECT_EQ(result.labels.at<int>(0, 40), result.labels.at<int>(0, 55));  // regions 2 and 3
  EXPECT_NE(result.labels.at<int>(0, 20), result.labels.at<int>(0, 40));  // 1 stays apart
}

// A model trained on one feature (pairs merge when their colour difference is small, below
// `limit`).
RegionMergeModel ColourRuleModel(float limit = 15.0f) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> value(0.0f, 40.0f);
  cv::Mat features(400, kMergeFeatures, CV_32F);
  std::vector<int> labels;
  for (int r = 0; r < features.rows; ++r) {
    for (int f = 0; f < kMergeFeatures; ++f) features.at<float>(r, f) = value(rng);
    labels.push_back(features.at<float>(r, 0) < limit ? 1 : 0);
  }
  RegionMergeModel::TrainingOptions options;
  options.weak_count = 20;
  options.max_depth = 1;
  return RegionMergeModel::Train(features, labels, {}, options);
}

// The flattened trees give exactly ml::Boost::predict's sums: on a model with deep trees over
// many features (splits on every side of every threshold), and on the shipped model.
// Single and batched sums equal OpenCV's prediction, on a model of depth-4 trees (unbalanced, so
// padded) and on a shipped grouping member.
TEST(BoostedForestTest, SumsEqualOpenCvPredict) {
  std::mt19937 rng(11);
  std::normal_distribution<float> value(0.0f, 1.0f);
  cv::Mat features(600, 12, CV_32F);
  cv::Mat responses(features.rows, 1, CV_32S);
  for (int r = 0; r < features.rows; ++r) {
    for (int f = 0; f < features.cols; ++f) features.at<float>(r, f) = value(rng);
    const float* x = features.ptr<float>(r);
    responses.at<int>(r) = (x[0] * x[1] > 0.2f || x[5] < -1.0f) ? 1 : 0;
  }
  const cv::Mat weights(features.rows, 1, CV_32F, cv::Scalar(1.0f));
  std::vector<cv::Ptr<cv::ml::Boost>> boosts = {
      TrainGentleBoost(features, responses, weights, 40, 4, 0.95)};
  const StatusOr<RegionMergeModel> shipped = RegionMergeModel::Load(DefaultModelsDir());
  ASSERT_TRUE(shipped.ok()) << "the shipped grouping model does not load: "
                            << shipped.status().ToString();
  cv::FileStorage fs(DefaultModelsDir() + "/" + RegionMergeModel::kFileName, cv::FileStorage::READ);
  cv::Ptr<cv::ml::Boost> member = cv::ml::Boost::create();
  member->read(fs["member_0"]);
  ASSERT_TRUE(member->isTrained());
  boosts.push_back(member);
  for (const cv::Ptr<cv::ml::Boost>& boost : boosts) {
    const BoostedForest forest(*boost);
    ASSERT_EQ(forest.var_count(), boost->getVarCount());
    // Each variable's split thresholds: probes exactly on them decide which way ties go.
    std::vector<std::vector<float>> thresholds(static_cast<size_t>(forest.var_count()));
    for (const cv::ml::DTrees::Split& split : boost->getSplits()) {
      thresholds[static_cast<size_t>(split.varIdx)].push_back(split.c);
    }
    cv::Mat probe(300, forest.var_count(), CV_32F);
    for (int r = 0; r < probe.rows; ++r) {
      for (int f = 0; f < probe.cols; ++f) {
        const std::vector<float>& on = thresholds[static_cast<size_t>(f)];
        // Training rows, rows on thresholds, and scaled random rows.
        if (r < 100 && boost->getVarCount() == features.cols) {
          probe.at<float>(r, f) = features.at<float>(r, f);
        } else if (r < 200 && !on.empty()) {
          probe.at<float>(r, f) = on[static_cast<size_t>(r) % on.size()];
        } else {
          probe.at<float>(r, f) = 3.0f * value(rng);
        }
      }
    }
    const cv::Mat expected = BoostedSums(*boost, probe);
    // In batches too (not a multiple of the batch size), each sum the single sample's.
    std::vector<double> batch(static_cast<size_t>(probe.rows));
    forest.Sums(probe.ptr<float>(0), probe.step1(), probe.rows, batch.data());
    int positive = 0;
    for (int r = 0; r < probe.rows; ++r) {
      EXPECT_EQ(static_cast<float>(forest.Sum(probe.ptr<float>(r))), expected.at<float>(r)) << r;
      EXPECT_EQ(batch[static_cast<size_t>(r)], forest.Sum(probe.ptr<float>(r))) << r;
      positive += expected.at<float>(r) > 0;
    }
    EXPECT_GT(positive, 0);
    EXPECT_LT(positive, probe.rows);
  }
}

TEST(RegionMergeModelTest, SaveLoadRoundTripGivesTheSameScores) {
  const RegionMergeModel model = ColourRuleModel();
  const std::string dir = ::testing::TempDir() + "/grouping_roundtrip";
  std::filesystem::create_directories(dir);
  ASSERT_TRUE(model.Save(dir).ok());
  const StatusOr<RegionMergeModel> loaded = RegionMergeModel::Load(dir);
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  cv::Mat probe(2, kMergeFeatures, CV_32F, cv::Scalar(20.0f));
  probe.at<float>(0, 0) = 2.0f;  // similar colours
  probe.at<float>(1, 0) = 35.0f;
  const cv::Mat before = model.Scores(probe);
  const cv::Mat after = loaded->Scores(probe);
  EXPECT_GT(before.at<float>(0), 0.0f);
  EXPECT_LT(before.at<float>(1), 0.0f);
  EXPECT_FLOAT_EQ(before.at<float>(0), after.at<float>(0));
  EXPECT_FLOAT_EQ(before.at<float>(1), after.at<float>(1));
}

TEST(RegionMergeModelTest, EnsembleScoresAreTheMeanOfItsMembersAndSurviveSaveLoad) {
  const RegionMergeModel strict = ColourRuleModel(10.0f);
  const RegionMergeModel loose = ColourRuleModel(25.0f);
  const RegionMergeModel ensemble = RegionMergeModel::Ensemble({strict, loose});
  EXPECT_EQ(ensemble.members(), 2);
  cv::Mat probe(3, kMergeFeatures, CV_32F, cv::Scalar(20.0f));
  probe.at<float>(0, 0) = 2.0f;   // both merge
  probe.at<float>(1, 0) = 18.0f;  // only the loose one merges
  probe.at<float>(2, 0) = 35.0f;  // neither
  const cv::Mat a = strict.Scores(probe);
  const cv::Mat b = loose.Scores(probe);
  const cv::Mat mean = ensemble.Scores(probe);
  for (int r = 0; r < probe.rows; ++r) {
    EXPECT_NEAR(mean.at<float>(r), 0.5f * (a.at<float>(r) + b.at<float>(r)), 1e-5) << r;
  }
  EXPECT_LT(a.at<float>(1), 0.0f);
  EXPECT_GT(b.at<float>(1), 0.0f);
  const std::string dir = ::testing::TempDir() + "/grouping_ensemble";
  std::filesystem::create_directories(dir);
  ASSERT_TRUE(ensemble.Save(dir).ok());
  const StatusOr<RegionMergeModel> loaded = RegionMergeModel::Load(dir);
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  EXPECT_EQ(loaded->members(), 2);
  const cv::Mat again = loaded->Scores(probe);
  for (int r = 0; r < probe.rows; ++r) EXPECT_FLOAT_EQ(again.at<float>(r), mean.at<float>(r));
}

TEST(RegionMergeModelTest, MissingFileIsNotFoundAndForeignFileIsRejected) {
  const StatusOr<RegionMergeModel> missing = RegionMergeModel::Load("/nonexistent/placerec");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), StatusCode::kNotFound);
  const std::string dir = ::testing::TempDir() + "/grouping_foreign";
  std::filesystem::create_directories(dir);
  {
    cv::FileStorage fs(dir + "/" + RegionMergeModel::kFileName, cv::FileStorage::WRITE);
    fs << "format_version" << 99 << "features" << 3;
  }
  const StatusOr<RegionMergeModel> foreign = RegionMergeModel::Load(dir);
  ASSERT_FALSE(foreign.ok());
  EXPECT_NE(foreign.status().message().find("placerec-train grouping"), std::string::npos);
  // Version 2 put the appearance-space features where version 3 has the semantic ones: such a
  // model cannot be read with the new layout.
  {
    cv::FileStorage fs(dir + "/" + RegionMergeModel::kFileName, cv::FileStorage::WRITE);
    fs << "format_version" << 2 << "features" << kMergeRelationFeatures + 40 << "members" << 1;
  }
  const StatusOr<RegionMergeModel> old_layout = RegionMergeModel::Load(dir);
  ASSERT_FALSE(old_layout.ok());
  EXPECT_NE(old_layout.status().message().find("retrain"), std::string::npos);
  // Version 3 put them where version 4 has the boundary features.
  {
    cv::FileStorage fs(dir + "/" + RegionMergeModel::kFileName, cv::FileStorage::WRITE);
    fs << "format_version" << 3 << "features" << kMergeBoundaryOffset + 1 << "members" << 1;
  }
  const StatusOr<RegionMergeModel> version3 = RegionMergeModel::Load(dir);
  ASSERT_FALSE(version3.ok());
  EXPECT_NE(version3.status().message().find("retrain"), std::string::npos);
}

// A version-3 model on the relational and semantic features (the layout models shipped in
// until the boundary features came) still loads and scores as it did.
TEST(RegionMergeModelTest, Version3ModelsOnTheLeadingFeaturesStillLoad) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> value(0.0f, 1.0f);
  cv::Mat features(300, kMergeBoundaryOffset, CV_32F);
  std::vector<int> labels;
  for (int r = 0; r < features.rows; ++r) {
    for (int f = 0; f < features.cols; ++f) features.at<float>(r, f) = value(rng);
    labels.push_back(features.at<float>(r, 0) < 0.5f ? 1 : 0);
  }
  RegionMergeModel::TrainingOptions options;
  options.weak_count = 10;
  const RegionMergeModel model = RegionMergeModel::Train(features, labels, {}, options);
  const std::string dir = ::testing::TempDir() + "/grouping_version3";
  std::filesystem::create_directories(dir);
  ASSERT_TRUE(model.Save(dir).ok());
  // Rewrite the saved file's version to 3, as such a model was written.
  const std::string path = dir + "/" + RegionMergeModel::kFileName;
  {
    cv::FileStorage in(path, cv::FileStorage::READ);
    cv::Ptr<cv::ml::Boost> boost = cv::ml::Boost::create();
    boost->read(in["member_0"]);
    in.release();
    cv::FileStorage out(path, cv::FileStorage::WRITE);
    out << "format_version" << 3 << "features" << kMergeBoundaryOffset << "members" << 1;
    out << "member_0"
        << "{";
    boost->write(out);
    out << "}";
  }
  const StatusOr<RegionMergeModel> loaded = RegionMergeModel::Load(dir);
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  cv::Mat probe(features.rowRange(0, 20).clone());
  cv::Mat wide(probe.rows, kMergeFeatures, CV_32F, cv::Scalar(0.0f));
  probe.copyTo(wide.colRange(0, kMergeBoundaryOffset));
  const cv::Mat expected = model.Scores(wide);
  const cv::Mat again = loaded->Scores(wide);
  for (int r = 0; r < probe.rows; ++r) EXPECT_FLOAT_EQ(again.at<float>(r), expected.at<float>(r));
}

// The semantic features are the pair's structured scores, margins and argmax agreement as
// the classifiers give them for each region (zeros for structured classes the models lack).
TEST(MergeStateTest, SemanticFeaturesFollowTheStructuredClassifiers) {
  const std::shared_ptr<const BackgroundModel> model = ShippedModel();
  ASSERT_NE(model, nullptr);
  const Scene scene = MakeScene();
  const MergeState state = StateOf(*model, scene.lab, scene.labels, scene.regions);
  const cv::Mat appearance = AppearanceOf(*model, scene.lab, scene.labels, scene.regions, 2);
  const cv::Mat background = model->classifier.Scores(appearance);
  const cv::Mat structured = model->classifier.StructuredScores(appearance);
  const int m = structured.cols;
  // Per region: best background minus best structured score, and the argmax over all classes.
  std::vector<float> margin(scene.regions, 0.0f);
  std::vector<int> best(scene.regions, 0);
  for (int r = 0; r < scene.regions; ++r) {
    double low = 0;
    double high = 0;
    cv::Point at;
    cv::minMaxLoc(background.row(r), &low, &high, nullptr, &at);
    best[r] = at.x;
    if (m == 0) continue;
    double structured_high = 0;
    cv::Point structured_at;
    cv::minMaxLoc(structured.row(r), &low, &structured_high, nullptr, &structured_at);
    margin[r] = static_cast<float>(high - structured_high);
    if (structured_high > high) best[r] = kBackgroundClasses + structured_at.x;
  }
  for (const auto& [a, b] : state.Pairs()) {
    float f[kMergeFeatures];
    state.PairFeatures(a, b, f);
    const float* semantic = f + kMergeRelationFeatures;
    for (int j = 0; j < kMergeStructuredScores; ++j) {
      const float sa = j < m ? structured.at<float>(a, j) : 0.0f;
      const float sb = j < m ? structured.at<float>(b, j) : 0.0f;
      EXPECT_FLOAT_EQ(semantic[2 * j], std::min(sa, sb)) << a << "," << b << " class " << j;
      EXPECT_FLOAT_EQ(semantic[2 * j + 1], std::max(sa, sb)) << a << "," << b << " class " << j;
    }
    EXPECT_FLOAT_EQ(semantic[2 * kMergeStructuredScores], std::min(margin[a], margin[b]));
    EXPECT_FLOAT_EQ(semantic[2 * kMergeStructuredScores + 1], std::max(margin[a], margin[b]));
    EXPECT_EQ(semantic[kMergeSemanticFeatures - 1], m > 0 && best[a] == best[b] ? 1.0f : 0.0f);
  }
}

TEST(MergeRegionsTest, ThresholdDecidesHowFarMergingGoes) {
  const std::shared_ptr<const BackgroundModel> model = ShippedModel();
  ASSERT_NE(model, nullptr);
  const Scene scene = MakeScene();
  const RegionMergeModel colour = ColourRuleModel();
  RegionMergeOptions options;
  // The colour rule joins the two halves of each block (same colour) but no two blocks.
  MergeState state = StateOf(*model, scene.lab, scene.labels, scene.regions);
  EXPECT_EQ(MergeRegions(colour, options, &state), 4);
  const SceneSegmentation blocks = state.Result();
  EXPECT_EQ(blocks.size(), 4);
  // Nothing scores above +infinity.
  options.threshold = std::numeric_limits<double>::max();
  MergeState untouched = StateOf(*model, scene.lab, scene.labels, scene.regions);
  EXPECT_EQ(MergeRegions(colour, options, &untouched), 0);
  EXPECT_EQ(untouched.Result().size(), scene.regions);
  // Everything scores above -infinity: one region.
  options.threshold = std::numeric_limits<double>::lowest();
  MergeState all = StateOf(*model, scene.lab, scene.labels, scene.regions);
  EXPECT_EQ(MergeRegions(colour, options, &all), scene.regions - 1);
  EXPECT_EQ(all.Result().size(), 1);
}

// The shipped grouping model at the default threshold on the synthetic blocks, as
// SceneOrganizer merges: the greedy merging joins the halves of each block and keeps the four
// blocks of very different colour apart; every pair of halves scores above the threshold and
// above every pair of halves from two different blocks.
TEST(ShippedGroupingModelTest, JoinsHalvesOfOneSurfaceAndKeepsDifferentSurfacesApart) {
  const std::shared_ptr<const BackgroundModel> model = ShippedModel();
  ASSERT_NE(model, nullptr);
  ASSERT_FALSE(model->grouping.empty())
      << "the shipped grouping model " << PLACEREC_MODELS_DIR << "/" << RegionMergeModel::kFileName
      << " is missing (models/ is part of the repository)";
  const Scene scene = MakeScene();
  // The learned boundary scores the model reads, as SceneOrganizer computes them.
  const cv::Mat boundary =
      model->GroupingReadsBoundary()
          ? model->boundary.ScoreMap(ComputeFilterBank(scene.lab), CrackPixels(scene.labels))
          : cv::Mat();
  MergeState state = StateOf(*model, scene.lab, scene.labels, scene.regions, boundary);
  cv::Mat halves(4, kMergeFeatures, CV_32F);
  for (int block = 0; block < 4; ++block) {
    state.PairFeatures(2 * block, 2 * block + 1, halves.ptr<float>(block));
  }
  cv::Mat blocks(2, kMergeFeatures, CV_32F);
  state.PairFeatures(1, 2, blocks.ptr<float>(0));  // orange | green, side by side
  state.PairFeatures(0, 4, blocks.ptr<float>(1));  // orange above blue
  const cv::Mat same = model->grouping.Scores(halves);
  const cv::Mat different = model->grouping.Scores(blocks);
  const double threshold = SceneOrganizerOptions::ForSegmentation().merge.threshold;
  double lowest_same = std::numeric_limits<double>::infinity();
  for (int r = 0; r < same.rows; ++r) {
    EXPECT_GT(same.at<float>(r), threshold) << "block " << r;
    lowest_same = std::min<double>(lowest_same, same.at<float>(r));
  }
  for (int r = 0; r < different.rows; ++r) {
    EXPECT_LT(different.at<float>(r), lowest_same) << "pair " << r;
  }
  // The merging itself: four merges, one per block, and the blocks stay apart.
  EXPECT_EQ(MergeRegions(model->grouping, SceneOrganizerOptions::ForSegmentation().merge, &state),
            4);
  const SceneSegmentation result = state.Result();
  ASSERT_EQ(result.size(), 4);
  for (int block = 0; block < 4; ++block) {
    EXPECT_EQ(state.Find(2 * block), state.Find(2 * block + 1)) << "block " << block;
    for (int other = block + 1; other < 4; ++other) {
      EXPECT_NE(state.Find(2 * block), state.Find(2 * other)) << block << " and " << other;
    }
  }
}

}  // namespace
}  // namespace placerec
